//! Unit tests of `io.rs`.

use super::*;

/// New files get what `File::create` gives (umask applied, not the
/// temporary file's 0600); a replaced file keeps its permissions.
#[cfg(unix)]
#[test]
fn written_files_get_ordinary_permissions() {
    use std::os::unix::fs::PermissionsExt as _;
    let dir = tempfile::tempdir().unwrap();
    let plain = dir.path().join("plain");
    std::fs::File::create(&plain).unwrap();
    let want = std::fs::metadata(&plain).unwrap().permissions().mode() & 0o777;
    let out = dir.path().join("out.png");
    write(&out, &ramp(4, 3, 1)).unwrap();
    let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode(&out), want);
    std::fs::set_permissions(&out, std::fs::Permissions::from_mode(0o640)).unwrap();
    write(&out, &ramp(4, 3, 1)).unwrap();
    assert_eq!(mode(&out), 0o640);
}

fn ramp(w: usize, h: usize, c: usize) -> Image {
    let data = (0..w * h * c)
        .map(|i| i as f32 / (w * h * c - 1) as f32)
        .collect();
    Image::from_vec(w, h, c, data).unwrap()
}

#[test]
fn round_trips_every_format() {
    let dir = tempfile::tempdir().unwrap();
    for (name, c, tol) in [
        ("a.png", 1, 0.5 / 255.0),
        ("a.png", 3, 0.5 / 255.0),
        ("a.png", 4, 0.5 / 255.0),
        ("a.tiff", 3, 0.5 / 255.0),
        ("a.exr", 3, 0.0),
        ("a.exr", 4, 0.0),
        ("a.npy", 5, 0.0),
        ("a.hdr", 3, 1.0 / 64.0),
        ("a.jpg", 3, 0.1),
    ] {
        let img = ramp(17, 9, c);
        let p = dir.path().join(name);
        write(&p, &img).unwrap();
        let back = read(&p).unwrap();
        assert_eq!(
            (back.width(), back.height(), back.channels()),
            (17, 9, c),
            "{name}"
        );
        let err = img
            .data()
            .iter()
            .zip(back.data())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        assert!(err <= tol + 1e-6, "{name} c={c}: max error {err}");
    }
}

#[test]
fn sixteen_bit_keeps_precision() {
    let dir = tempfile::tempdir().unwrap();
    let img = ramp(300, 2, 1);
    for name in ["a.png", "a.tif"] {
        let p = dir.path().join(name);
        let opts = WriteOptions {
            bit_depth: BitDepth::Sixteen,
            ..WriteOptions::default()
        };
        write_image(&p, &img, &opts).unwrap();
        let loaded = read_image(&p, &ReadOptions::default()).unwrap();
        assert_eq!(loaded.integer_bits, Some(16));
        let err = img
            .data()
            .iter()
            .zip(loaded.image.data())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        assert!(err <= 0.51 / 65535.0, "{name}: {err}");
    }
}

#[test]
fn clipping_is_counted() {
    let dir = tempfile::tempdir().unwrap();
    let img = Image::from_vec(2, 2, 1, vec![-0.5, 0.2, 1.5, 1.0]).unwrap();
    let r = write(dir.path().join("c.png"), &img).unwrap();
    assert_eq!(r.clipped, 2);
    assert_eq!(r.samples, 4);
}

#[test]
fn srgb_round_trip() {
    for i in 0..=100 {
        let v = i as f32 / 100.0;
        assert!((linear_to_srgb(srgb_to_linear(v)) - v).abs() < 1e-5);
    }
}

#[test]
fn failed_write_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let img = Image::from_vec(1, 1, 1, vec![f32::NAN]).unwrap();
    let p = dir.path().join("n.png");
    let e = write(&p, &img).unwrap_err().to_string();
    assert!(e.contains("non-finite"), "{e}");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    // No format takes a NaN or an infinity, even those that could
    // store one; the message names the first.
    let img = Image::from_vec(2, 1, 3, vec![0.0, 1.0, 2.0, 3.0, f32::INFINITY, 5.0]).unwrap();
    for name in ["n.exr", "n.npy", "n.hdr", "n.tif"] {
        let e = write(dir.path().join(name), &img).unwrap_err().to_string();
        assert!(
            e.contains("1 non-finite") && e.contains("x=1, y=0, channel 1"),
            "{name}: {e}"
        );
    }
    // RGBE holds up to 1.7e38: a larger value is refused, not written as 0
    let big = Image::from_vec(1, 1, 3, vec![2e38, 1.0, 1.0]).unwrap();
    let e = write(dir.path().join("b.hdr"), &big)
        .unwrap_err()
        .to_string();
    assert!(e.contains("up to 1.69e38"), "{e}");
    let ok = Image::from_vec(1, 1, 3, vec![1.6e38, 1.0, 1.0]).unwrap();
    write(dir.path().join("ok.hdr"), &ok).unwrap();
    std::fs::remove_file(dir.path().join("ok.hdr")).unwrap();
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    // A failure inside the encoder callback also leaves no file behind.
    let e = atomic_write(&p, |_| Err("boom".into())).unwrap_err();
    assert!(e.to_string().contains("boom"));
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}

#[test]
fn bad_inputs_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing.png");
    assert!(matches!(read(&missing), Err(ImageError::NotFound { .. })));
    let odd = dir.path().join("a.bmpx");
    std::fs::write(&odd, b"x").unwrap();
    let e = read(&odd).unwrap_err().to_string();
    assert!(e.contains("unsupported file extension"), "{e}");
    let trunc = dir.path().join("t.png");
    let good = dir.path().join("g.png");
    write(&good, &ramp(64, 64, 3)).unwrap();
    let bytes = std::fs::read(&good).unwrap();
    std::fs::write(&trunc, &bytes[..bytes.len() / 2]).unwrap();
    let e = read(&trunc).unwrap_err().to_string();
    assert!(e.contains("cannot decode PNG"), "{e}");
    let garbage = dir.path().join("g.exr");
    std::fs::write(&garbage, b"not an exr at all").unwrap();
    let e = read(&garbage).unwrap_err().to_string();
    assert!(e.contains("cannot decode OpenEXR"), "{e}");
}

#[test]
fn budget_refuses_large_images() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("big.png");
    write(&p, &ramp(100, 100, 3)).unwrap();
    let opts = ReadOptions {
        budget: MemoryBudget::bytes(1000),
        ..ReadOptions::default()
    };
    let e = read_image(&p, &opts).unwrap_err().to_string();
    assert!(
        e.starts_with(&format!("{}: ", p.display())) && e.contains("would need 146.5 KiB"),
        "{e}"
    );
    // NumPy files are checked from their header, before the data is read.
    let n = dir.path().join("big.npy");
    write(&n, &ramp(100, 100, 3)).unwrap();
    let e = read_image(&n, &opts).unwrap_err();
    assert!(matches!(e, ImageError::TooLarge { .. }), "{e}");
    let e = e.to_string();
    assert!(
        e.starts_with(&format!("{}: ", n.display())) && e.contains("budget of 1000 B"),
        "{e}"
    );
}

/// Images in memory decode as their files do, with the same checks,
/// each error naming the name given.
#[test]
fn bytes_read_as_files() {
    let dir = tempfile::tempdir().unwrap();
    let name = Path::new("model.glb: image 2 (image/png)");
    for (file, format) in [("a.png", FileFormat::Png), ("a.jpg", FileFormat::Jpeg)] {
        let p = dir.path().join(file);
        write(&p, &ramp(40, 30, 3)).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        for srgb in [false, true] {
            let opts = ReadOptions {
                srgb_decode: srgb,
                ..ReadOptions::default()
            };
            let a = read_image(&p, &opts).unwrap();
            let b = read_image_bytes(&bytes, name, format, &opts).unwrap();
            assert_eq!(a.image.data(), b.image.data(), "{file}");
            assert_eq!((a.format, a.integer_bits), (b.format, b.integer_bits));
        }
        let small = ReadOptions {
            budget: MemoryBudget::bytes(1000),
            ..ReadOptions::default()
        };
        let e = read_image_bytes(&bytes, name, format, &small)
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("model.glb: image 2 (image/png): image would need"),
            "{e}"
        );
        let e = read_image_bytes(
            &bytes[..bytes.len() - 40],
            name,
            format,
            &ReadOptions::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.starts_with(&format!(
                "model.glb: image 2 (image/png): cannot decode {}",
                format.name()
            )),
            "{e}"
        );
    }
    let e = read_image_bytes(b"\x93NUMPY", name, FileFormat::Npy, &ReadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("files only"), "{e}");
}

#[test]
fn empty_images_name_the_file() {
    let e = Image::new(0, 4, 1).unwrap_err().to_string();
    assert_eq!(e, "image is empty (0x4 with 1 channels)");
    let e = ImageError::Empty {
        path: None,
        width: 0,
        height: 4,
        channels: 1,
    }
    .in_file(Path::new("x.npy"))
    .to_string();
    assert_eq!(e, "x.npy: image is empty (0x4 with 1 channels)");
}

#[test]
fn non_finite_policy() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("n.npy");
    let img = Image::from_vec(3, 1, 1, vec![1.0, f32::NAN, f32::INFINITY]).unwrap();
    let fixture = WriteOptions {
        allow_non_finite: true,
        ..WriteOptions::default()
    };
    write_image(&p, &img, &fixture).unwrap();
    let e = read(&p).unwrap_err().to_string();
    assert!(e.contains("2 non-finite") && e.contains("x=1, y=0"), "{e}");
    let opts = ReadOptions {
        non_finite: NonFinitePolicy::Replace(0.0),
        ..ReadOptions::default()
    };
    let l = read_image(&p, &opts).unwrap();
    assert_eq!(l.replaced_non_finite, 2);
    assert_eq!(l.image.data(), &[1.0, 0.0, 0.0]);
}
