//! Reading the bundled and shared real data; bad inputs end in clear errors.

use std::path::{Path, PathBuf};

use ifd::image::{self, ImageError, NonFinitePolicy, ReadOptions};

fn testdata(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("testdata")
        .join(name)
}

#[test]
fn reads_bundled_png_gray_and_rgb() {
    let cam = image::read(testdata("camera.png")).unwrap();
    assert_eq!((cam.width(), cam.height(), cam.channels()), (512, 512, 1));
    let coffee = image::read(testdata("coffee.png")).unwrap();
    assert_eq!(
        (coffee.width(), coffee.height(), coffee.channels()),
        (600, 400, 3)
    );
    assert!(coffee.data().iter().all(|v| (0.0..=1.0).contains(v)));
}

#[test]
fn reads_dwab_compressed_exr() {
    let env = image::read(testdata("forest_dwab.exr")).unwrap();
    assert_eq!((env.width(), env.height()), (1024, 512));
    assert!(env.channels() >= 3);
    let max = env.data().iter().copied().fold(f32::MIN, f32::max);
    // An HDR environment map: values far above 1 (the sun).
    assert!(max > 10.0, "max {max}");
}

#[test]
fn reads_bundled_radiance_hdr() {
    let env = image::read(testdata("forest.hdr")).unwrap();
    assert_eq!((env.width(), env.height(), env.channels()), (1024, 512, 3));
    let max = env.data().iter().copied().fold(f32::MIN, f32::max);
    assert!(max > 10.0, "an HDR map: max {max}");
    assert!(env.data().iter().all(|v| v.is_finite() && *v >= 0.0));
}

#[test]
fn srgb_decoding_darkens_mid_grey() {
    let lin = image::read(testdata("camera.png")).unwrap();
    let opts = ReadOptions {
        srgb_decode: true,
        ..ReadOptions::default()
    };
    let srgb = image::read_image(&testdata("camera.png"), &opts)
        .unwrap()
        .image;
    let mean = |d: &[f32]| d.iter().sum::<f32>() / d.len() as f32;
    assert!(mean(srgb.data()) < mean(lin.data()));
}

#[test]
fn zero_sized_npy_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("z.npy");
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    let mut header = "{'descr': '<f4', 'fortran_order': False, 'shape': (0, 5), }".to_string();
    while !(10 + header.len() + 1).is_multiple_of(64) {
        header.push(' ');
    }
    header.push('\n');
    bytes.extend_from_slice(&(header.len() as u16).to_le_bytes());
    bytes.extend_from_slice(header.as_bytes());
    std::fs::write(&p, bytes).unwrap();
    let e = image::read(&p).unwrap_err();
    assert!(matches!(e, ImageError::Empty { .. }), "{e}");
    let msg = e.to_string();
    assert!(
        msg.starts_with(&format!("{}: image is empty (5x0", p.display())),
        "{msg}"
    );
}

#[test]
fn truncated_npy_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("t.npy");
    let img = image::Image::new(8, 8, 3).unwrap();
    image::write(&p, &img).unwrap();
    let bytes = std::fs::read(&p).unwrap();
    std::fs::write(&p, &bytes[..bytes.len() - 10]).unwrap();
    let e = image::read(&p).unwrap_err().to_string();
    assert!(e.contains("truncated") && e.contains("t.npy"), "{e}");
}

#[test]
fn nan_replacement_counts() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("n.exr");
    let mut img = image::Image::new(4, 4, 3).unwrap();
    img.set(1, 2, 0, f32::NAN);
    // (a test input: the writer refuses NaN unless told it is one)
    let fixture = image::WriteOptions {
        allow_non_finite: true,
        ..image::WriteOptions::default()
    };
    image::write_image(&p, &img, &fixture).unwrap();
    let e = image::read(&p).unwrap_err().to_string();
    assert!(e.contains("1 non-finite") && e.contains("x=1, y=2"), "{e}");
    let opts = ReadOptions {
        non_finite: NonFinitePolicy::Replace(0.25),
        ..ReadOptions::default()
    };
    let l = image::read_image(&p, &opts).unwrap();
    assert_eq!(l.replaced_non_finite, 1);
    assert_eq!(l.image.get(1, 2, 0), 0.25);
}
