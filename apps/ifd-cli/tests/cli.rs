//! End-to-end tests of the `ifd` binary: exit codes and messages for bad input.

use std::path::{Path, PathBuf};

mod common;
#[path = "../../../tests/support/skip.rs"]
mod skip;
use common::{ifd, testdata};

fn write_file(dir: &Path, name: &str, bytes: &[u8]) -> String {
    let p: PathBuf = dir.join(name);
    std::fs::write(&p, bytes).expect("write test file");
    p.to_string_lossy().into_owned()
}

#[test]
fn compare_identical_images() {
    let cam = testdata("camera.png");
    let (code, out, _) = ifd(&["compare", &cam, &cam, "--json"]);
    assert_eq!(code, 0);
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["identical"], true);
    assert_eq!(v["ssim"], 1.0);
    assert_eq!(v["max_abs"], 0.0);
}

#[test]
fn bad_inputs_exit_2_with_named_problem() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cam = testdata("camera.png");
    let png = std::fs::read(&cam).unwrap();
    let cases: Vec<(String, &str)> = vec![
        (
            d.join("missing.png").to_string_lossy().into_owned(),
            "no such file",
        ),
        (
            write_file(d, "trunc.png", &png[..png.len() / 3]),
            "cannot decode PNG",
        ),
        (
            write_file(d, "corrupt.exr", b"garbage bytes"),
            "cannot decode OpenEXR",
        ),
        (
            write_file(d, "corrupt.hdr", b"#?RADIANCE\nnonsense"),
            "cannot decode Radiance HDR",
        ),
        (
            write_file(d, "x.gif", b"GIF89a"),
            "unsupported file extension",
        ),
        (
            write_file(d, "bad.npy", b"\x93NUMPY\x01\x00\x10\x00{'descr': '<c8'"),
            "cannot decode NumPy",
        ),
    ];
    for (path, needle) in cases {
        let (code, _, err) = ifd(&["compare", &path, &cam]);
        assert_eq!(code, 2, "{path}: {err}");
        assert!(
            err.contains(needle),
            "{path}: expected {needle:?} in {err:?}"
        );
        let name = Path::new(&path)
            .file_name()
            .unwrap()
            .to_string_lossy()
            .into_owned();
        assert!(err.contains(&name), "{err:?} does not name {name}");
    }
}

#[test]
fn memory_budget_is_enforced() {
    let cam = testdata("camera.png");
    let (code, _, err) = ifd(&["compare", &cam, &cam, "--memory-budget", "1"]);
    assert_eq!(code, 2);
    assert!(
        err.contains(&format!("{cam}: image would need 1.2 MiB"))
            && err.contains("budget of 1.0 MiB"),
        "{err}"
    );
    // A .npy is refused from its header: 20000x20000 float32 would need
    // 20000^2 x (4 read + 4 kept) bytes = 3.0 GiB; the data is never read
    // (the file is sparse: its length says it holds the data, and the
    // length is checked before the budget).
    let dir = tempfile::tempdir().unwrap();
    let mut header =
        "{'descr': '<f4', 'fortran_order': False, 'shape': (20000, 20000), }".to_string();
    while !(10 + header.len() + 1).is_multiple_of(64) {
        header.push(' ');
    }
    header.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend_from_slice(&(header.len() as u16).to_le_bytes());
    bytes.extend_from_slice(header.as_bytes());
    let p = write_file(dir.path(), "huge.npy", &bytes);
    std::fs::OpenOptions::new()
        .write(true)
        .open(&p)
        .and_then(|f| f.set_len(bytes.len() as u64 + 20000 * 20000 * 4))
        .unwrap();
    let (code, _, err) = ifd(&["info", &p, "--memory-budget", "1"]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains(&format!("{p}: image would need 3.0 GiB"))
            && err.contains("budget of 1.0 MiB"),
        "{err}"
    );
}

#[test]
fn nan_input_refused_or_replaced() {
    let dir = tempfile::tempdir().unwrap();
    // A 12x12 float32 .npy with one NaN.
    let mut header = "{'descr': '<f4', 'fortran_order': False, 'shape': (12, 12), }".to_string();
    while !(10 + header.len() + 1).is_multiple_of(64) {
        header.push(' ');
    }
    header.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend_from_slice(&(header.len() as u16).to_le_bytes());
    bytes.extend_from_slice(header.as_bytes());
    for i in 0..144 {
        let v = if i == 13 { f32::NAN } else { 0.5 };
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    let p = write_file(dir.path(), "nan.npy", &bytes);
    let (code, _, err) = ifd(&["compare", &p, &p]);
    assert_eq!(code, 2);
    assert!(
        err.contains(&format!("{p}: 1 non-finite")) && err.contains("x=1, y=1"),
        "{err}"
    );
    let (code, _, err) = ifd(&["compare", &p, &p, "--replace-nonfinite", "0"]);
    assert_eq!(code, 0, "{err}");
    assert!(
        err.contains(&format!("{p}: replaced 1 non-finite")),
        "{err}"
    );
}

#[test]
fn zero_sized_and_mismatched() {
    let dir = tempfile::tempdir().unwrap();
    let mut header = "{'descr': '<f4', 'fortran_order': False, 'shape': (0, 3), }".to_string();
    while !(10 + header.len() + 1).is_multiple_of(64) {
        header.push(' ');
    }
    header.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend_from_slice(&(header.len() as u16).to_le_bytes());
    bytes.extend_from_slice(header.as_bytes());
    let p = write_file(dir.path(), "empty.npy", &bytes);
    let (code, _, err) = ifd(&["compare", &p, &p]);
    assert_eq!(code, 2);
    assert!(
        err.contains(&format!("{p}: image is empty (3x0 with 1 channels)")),
        "{err}"
    );
    let (code, _, err) = ifd(&["compare", &testdata("camera.png"), &testdata("coffee.png")]);
    assert_eq!(code, 2);
    assert!(err.contains("512x512") && err.contains("600x400"), "{err}");
}

/// GPU tests need an adapter (lavapipe on machines without a GPU); with
/// `IFD_GPU_TESTS=skip` a missing adapter is accepted.
/// The test is then recorded as skipped (`tests/support/skip.rs`).
fn gpu_missing_ok(code: i32, err: &str) -> bool {
    let missing = code == 2 && err.contains("no GPU adapter") && skip::allowed("IFD_GPU_TESTS");
    if missing {
        skip::skip("no GPU adapter (IFD_GPU_TESTS=skip)");
    }
    missing
}

/// `max |a - b| / max |b|` over two images read back from files.
fn relative_difference(a: &str, b: &str) -> f32 {
    let a = ifd_image::read(a).expect("GPU output");
    let b = ifd_image::read(b).expect("CPU output");
    assert_eq!(
        (a.width(), a.height(), a.channels()),
        (b.width(), b.height(), b.channels())
    );
    let scale = b.data().iter().fold(0.0f32, |m, v| m.max(v.abs()));
    let diff = a
        .data()
        .iter()
        .zip(b.data())
        .fold(0.0f32, |m, (x, y)| m.max((x - y).abs()));
    diff / scale
}

#[test]
fn gpu_info_names_the_adapter() {
    let (code, out, err) = ifd(&["gpu-info", "--all"]);
    if gpu_missing_ok(code, &err) {
        return;
    }
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("adapters found:"), "{out}");
    assert!(out.contains("adapter: "), "{out}");
    // the limits are in the whole report (-v), not the summary
    assert!(!out.contains("max_storage_buffer_binding_size"), "{out}");
    let (code, out, err) = ifd(&["gpu-info", "--all", "-v"]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("adapters found:"), "{out}");
    assert!(out.contains("max_storage_buffer_binding_size"), "{out}");
}

#[test]
fn filter_gpu_matches_cpu() {
    let dir = tempfile::tempdir().unwrap();
    // A hand-made anisotropic decomposition reaching 30 px outside the image.
    let terms: Vec<String> = (0..24)
        .map(|i| {
            let t = f64::from(i) / 23.0 * 2.0 - 1.0;
            format!(
                r#"{{"weight": {}, "x": {}, "y": {}, "sigma": {}}}"#,
                (1.0 - 0.5 * t * t) / 20.0,
                30.0 * t,
                4.0 * t * t,
                1.0 + 2.0 * t.abs()
            )
        })
        .collect();
    let decomp = write_file(
        dir.path(),
        "d.json",
        format!(
            r#"{{"format": "ifd-decomposition", "version": 1, "kernel": null, "dictionary": null, "report": null, "terms": [{}]}}"#,
            terms.join(", ")
        )
        .as_bytes(),
    );
    let img = testdata("coffee.png");
    let (w, h) = (600, 400);
    let angle: Vec<f32> = (0..w * h).map(|i| (i % w) as f32 * 0.6).collect();
    let scale: Vec<f32> = (0..w * h)
        .map(|i| 0.5 + (i / w) as f32 / h as f32)
        .collect();
    let amap = dir.path().join("angle.npy");
    let smap = dir.path().join("scale.npy");
    ifd_image::write(&amap, &ifd_image::Image::from_vec(w, h, 1, angle).unwrap()).unwrap();
    ifd_image::write(&smap, &ifd_image::Image::from_vec(w, h, 1, scale).unwrap()).unwrap();
    // At a constant scale both paths read levels at exactly the terms'
    // sigmas, one lookup per term (the GPU's levels located on the host);
    // these terms are too wide for the CPU's direct evaluation, so the CPU
    // side is the same command. With a scale map both read log-uniform levels.
    let (amap, smap) = (amap.to_string_lossy(), smap.to_string_lossy());
    for (name, extra) in [
        ("constant", vec!["--angle", "-35", "--scale", "1.5"]),
        (
            "angle map, constant scale",
            vec!["--angle-map", &*amap, "--scale", "1.5"],
        ),
        (
            "maps",
            vec![
                "--angle-map",
                &*amap,
                "--scale-map",
                &*smap,
                "--border",
                "constant:0.5",
            ],
        ),
    ] {
        let cpu = dir.path().join(format!("{name}-cpu.npy"));
        let gpu = dir.path().join(format!("{name}-gpu.npy"));
        let (cpu, gpu) = (cpu.to_string_lossy(), gpu.to_string_lossy());
        let mut args = vec!["filter", &*img, "--decomp", &*decomp, "-o", &*cpu];
        args.extend(&extra);
        let (code, _, err) = ifd(&args);
        assert_eq!(code, 0, "{err}");
        let mut args = vec!["filter", &*img, "--decomp", &*decomp, "-o", &*gpu];
        args.extend(&extra);
        args.extend(["--gpu", "--verbose"]);
        let (code, _, err) = ifd(&args);
        if gpu_missing_ok(code, &err) {
            return;
        }
        assert_eq!(code, 0, "{err}");
        assert!(err.contains("GPU: "), "{err}");
        let rel = relative_difference(&gpu, &cpu);
        assert!(rel <= 1e-4, "{name}: GPU and CPU differ by {rel:e}");
    }
    // Bad input on the GPU path is exit 2 with the CPU's message.
    let out = dir.path().join("bad.npy");
    let (code, _, err) = ifd(&[
        "filter",
        &img,
        "--decomp",
        &decomp,
        "--angle-map",
        &smap.replace("scale", "missing"),
        "--gpu",
        "-o",
        &out.to_string_lossy(),
    ]);
    assert_eq!(code, 2, "{err}");
}

#[test]
fn smooth_gpu_matches_cpu_in_both_modes() {
    let dir = tempfile::tempdir().unwrap();
    let cam = ifd_image::read(testdata("camera.png")).unwrap();
    let (w, h) = (96, 80);
    let mut data = Vec::with_capacity(w * h);
    for y in 0..h {
        data.extend_from_slice(&cam.data()[(y + 100) * 512 + 200..(y + 100) * 512 + 200 + w]);
    }
    let small = dir.path().join("small.npy");
    ifd_image::write(&small, &ifd_image::Image::from_vec(w, h, 1, data).unwrap()).unwrap();
    let small = small.to_string_lossy();
    let cpu = dir.path().join("cpu.npy").to_string_lossy().into_owned();
    let gpu = dir.path().join("gpu.npy").to_string_lossy().into_owned();
    let (code, _, err) = ifd(&["smooth", &small, "--sigma", "3", "-o", &cpu]);
    assert_eq!(code, 0, "{err}");
    let (code, _, err) = ifd(&["smooth", &small, "--sigma", "3", "--gpu", "-o", &gpu]);
    if gpu_missing_ok(code, &err) {
        return;
    }
    assert_eq!(code, 0, "{err}");
    let rel = relative_difference(&gpu, &cpu);
    assert!(rel <= 1e-4, "GPU and CPU smoothing differ by {rel:e}");
    // The paper's mode (a grid of blended dabs) on both paths.
    let (code, _, err) = ifd(&[
        "smooth", &small, "--sigma", "3", "--mode", "dab", "-o", &cpu,
    ]);
    assert_eq!(code, 0, "{err}");
    let (code, _, err) = ifd(&[
        "smooth", &small, "--sigma", "3", "--gpu", "--mode", "dab", "-o", &gpu,
    ]);
    assert_eq!(code, 0, "{err}");
    let rel = relative_difference(&gpu, &cpu);
    assert!(
        rel <= 1e-4,
        "GPU and CPU dab-mode smoothing differ by {rel:e}"
    );
}

/// `ifd sphere ...`: layouts, reconstruction clamping, limits, decomposition inputs.
mod sphere {
    use super::{ifd, testdata};
    use ifd_image::write_npy_f64;
    use ifd_sphere::ShCoeffs;
    use ifd_sphere::{Kernel, project_function};
    use ifd_sphere::{direction, gauss_legendre, sh_index};
    use std::f64::consts::PI;
    use std::path::Path;

    fn p(dir: &Path, name: &str) -> String {
        dir.join(name).to_string_lossy().into_owned()
    }

    fn json(out: &str) -> serde_json::Value {
        serde_json::from_str(out.trim()).unwrap_or_else(|e| panic!("{e}: {out}"))
    }

    /// Lobe weights (rows of `channels` values) of a decomposition JSON file.
    fn weights(path: &str) -> (usize, Vec<f64>) {
        let text = std::fs::read_to_string(path).expect("read the decomposition");
        let v: serde_json::Value = serde_json::from_str(&text).expect("decomposition JSON");
        let ch = v["weights"]["channels"].as_u64().expect("channels") as usize;
        let data = v["weights"]["data"]
            .as_array()
            .expect("weights")
            .iter()
            .map(|x| x.as_f64().expect("a number"))
            .collect();
        (ch, data)
    }

    fn rel_diff(a: &[f64], b: &[f64]) -> f64 {
        assert_eq!(a.len(), b.len());
        let scale = b.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max)
            / scale
    }

    #[test]
    fn sh_reconstruct_to_hdr_clamps_ringing_and_counts_it() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let map = testdata("forest_dwab.exr");
        let (code, out, err) = ifd(&[
            "sphere",
            "sh",
            "--json",
            &map,
            "--lmax",
            "8",
            "-o",
            &p(d, "c.npy"),
            "--reconstruct",
            &p(d, "rec.exr"),
        ]);
        assert_eq!(code, 0, "{err}");
        assert_eq!(json(&out)["reconstruct_negatives_clamped"], 0);
        let (code, out, err) = ifd(&[
            "sphere",
            "sh",
            "--json",
            &map,
            "--lmax",
            "8",
            "-o",
            &p(d, "c.npy"),
            "--reconstruct",
            &p(d, "rec.hdr"),
        ]);
        assert_eq!(code, 0, "{err}");
        let v = json(&out);
        // independent count: the negatives of the EXR reconstruction (which keeps them)
        let exr = ifd_image::read(p(d, "rec.exr")).unwrap();
        let negatives = exr.data().iter().filter(|x| **x < 0.0).count();
        assert!(
            negatives > 0,
            "an L = 8 reconstruction of the forest map rings negative"
        );
        assert_eq!(v["reconstruct_negatives_clamped"], negatives);
        assert!(
            err.contains(&format!("{negatives} negative samples of the band-limited")),
            "{err}"
        );
        let hdr = ifd_image::read(p(d, "rec.hdr")).unwrap();
        assert_eq!((hdr.width(), hdr.height()), (exr.width(), exr.height()));
        assert_eq!((hdr.channels(), exr.channels()), (3, 3));
        for (h, e) in hdr.data().chunks(3).zip(exr.data().chunks(3)) {
            // RGBE: an 8-bit mantissa per channel with the exponent of the largest
            // channel, truncated: an error of up to 2^-7 of that channel
            let top = e.iter().fold(0.0f32, |m, x| m.max(*x));
            for (h, e) in h.iter().zip(e) {
                let want = e.max(0.0);
                assert!((h - want).abs() <= top / 64.0 + 1e-30, "{h} vs {want}");
            }
        }
    }

    #[test]
    fn sh_refuses_bad_shapes_and_degrees_with_the_limit() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let bad = p(d, "bad.npy");
        write_npy_f64(Path::new(&bad), &[20, 30], &vec![1.0; 600]).unwrap();
        let (code, _, err) = ifd(&["sphere", "sh", &bad, "--lmax", "4", "-o", &p(d, "c.npy")]);
        assert_eq!(code, 2);
        assert!(
            err.contains("2:1") && err.contains("6:1") && err.contains("30x20"),
            "{err}"
        );
        let ok = p(d, "ok.npy");
        write_npy_f64(Path::new(&ok), &[8, 16], &vec![1.0; 128]).unwrap();
        let (code, _, err) = ifd(&["sphere", "sh", &ok, "--lmax", "5000", "-o", &p(d, "c.npy")]);
        assert_eq!(code, 2);
        assert!(
            err.contains("--lmax 5000: at most L = 1000 is supported"),
            "{err}"
        );
    }

    #[test]
    fn sh_of_cubemap_strip_faces_lands_on_the_right_axes() {
        // one face at a time set to 1: c_00 = Y_00 * (4 pi / 6) exactly (exact solid
        // angles), and the l = 1 part points along the face's axis:
        // y_1^-1 = -c1 y, y_1^0 = c1 z, y_1^1 = -c1 x
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let n = 8;
        let axes = [
            (1, -1.0),
            (1, 1.0),
            (-1, -1.0),
            (-1, 1.0),
            (0, 1.0),
            (0, -1.0),
        ];
        for (face, (m, sign)) in axes.into_iter().enumerate() {
            let mut img = vec![0.0; 6 * n * n];
            for j in 0..n {
                for i in 0..n {
                    img[j * 6 * n + face * n + i] = 1.0;
                }
            }
            let path = p(d, "cube.npy");
            write_npy_f64(Path::new(&path), &[n, 6 * n], &img).unwrap();
            let (code, out, err) = ifd(&[
                "sphere",
                "sh",
                "--json",
                &path,
                "--lmax",
                "2",
                "-o",
                &p(d, "c.npy"),
                "--reconstruct",
                &p(d, "rec.npy"),
            ]);
            assert_eq!(code, 0, "{err}");
            assert_eq!(json(&out)["layout"], "cubemap-strip");
            let c = ShCoeffs::read_npy(Path::new(&p(d, "c.npy"))).unwrap();
            let y00 = 0.5 / PI.sqrt();
            assert!((c.get(0, 0, 0) - y00 * 4.0 * PI / 6.0).abs() < 1e-12);
            for mm in -1..=1i64 {
                let v = c.get(1, mm, 0);
                if mm == m {
                    assert!(v * sign > 0.1, "face {face}: c_1^{mm} = {v}");
                } else {
                    assert!(v.abs() < 1e-12, "face {face}: c_1^{mm} = {v}");
                }
            }
            let rec = ifd_image::read(p(d, "rec.npy")).unwrap();
            assert_eq!((rec.width(), rec.height()), (4 * n, 2 * n));
        }
    }

    #[test]
    fn decompose_refuses_large_degrees_naming_the_limit() {
        let dir = tempfile::tempdir().unwrap();
        let out = p(dir.path(), "d.json");
        // Refused before any work (a dense L = 5000 fit would not finish).
        let (code, _, err) = ifd(&[
            "sphere",
            "decompose",
            "gauss:s=0.3",
            "--lmax",
            "5000",
            "-o",
            &out,
        ]);
        assert_eq!(code, 2);
        assert!(
            err.contains("L = 5000 is too large for a dense ISD decomposition")
                && err.contains("at most L = 40")
                && err.contains("--lmax 5000"),
            "{err}"
        );
    }

    /// A kernel image is projected at pixel centres by default: an image
    /// whose texels hold a smooth kernel's mean over each texel (64 x 64
    /// sub-samples, uniform in `cos theta` and `phi`, so area-weighted) gives
    /// the closed form's weights to 0.1% (the texel-exact rule, which
    /// projects the piecewise-constant map, to 1%: it keeps the box blur of
    /// the texels); `--projection` is refused for a closed-form spec.
    #[test]
    fn decompose_projects_kernel_images_at_pixel_centres() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let spec = "vmf:kappa=10";
        let (code, _, err) = ifd(&[
            "sphere",
            "decompose",
            spec,
            "--lmax",
            "6",
            "-o",
            &p(d, "spec.json"),
        ]);
        assert_eq!(code, 0, "{err}");
        let (_, want) = weights(&p(d, "spec.json"));
        let k = Kernel::parse(spec).unwrap();
        let (w, h, n) = (64usize, 32usize, 64usize);
        let mut data = Vec::with_capacity(w * h);
        for y in 0..h {
            let (z0, z1) = (
                (PI * y as f64 / h as f64).cos(),
                (PI * (y + 1) as f64 / h as f64).cos(),
            );
            for x in 0..w {
                let mut sum = 0.0;
                for j in 0..n {
                    let z = z0 + (z1 - z0) * (j as f64 + 0.5) / n as f64;
                    for i in 0..n {
                        let phi = 2.0 * PI * (x as f64 + (i as f64 + 0.5) / n as f64) / w as f64;
                        sum += k.eval(direction(z.clamp(-1.0, 1.0).acos(), phi));
                    }
                }
                data.push((sum / (n * n) as f64) as f32);
            }
        }
        let img = ifd_image::Image::from_vec(w, h, 1, data).unwrap();
        let path = p(d, "kernel.exr");
        ifd_image::write(&path, &img).unwrap();
        let mut errors = Vec::new();
        for proj in ["texel", "centre"] {
            let out = p(d, &format!("{proj}.json"));
            let (code, _, err) = ifd(&[
                "sphere",
                "decompose",
                &path,
                "--lmax",
                "6",
                "--projection",
                proj,
                "-o",
                &out,
            ]);
            assert_eq!(code, 0, "{err}");
            errors.push(rel_diff(&weights(&out).1, &want));
        }
        let (code, _, err) = ifd(&[
            "sphere",
            "decompose",
            &path,
            "--lmax",
            "6",
            "-o",
            &p(d, "default.json"),
        ]);
        assert_eq!(code, 0, "{err}");
        assert!(
            rel_diff(
                &weights(&p(d, "default.json")).1,
                &weights(&p(d, "centre.json")).1
            ) == 0.0
        );
        assert!(
            errors[1] < 2e-3 && errors[0] < 2e-2 && errors[1] < 0.5 * errors[0],
            "texel, centre: {errors:?}"
        );
        let (code, _, err) = ifd(&[
            "sphere",
            "decompose",
            spec,
            "--lmax",
            "6",
            "--projection",
            "texel",
            "-o",
            &p(d, "x.json"),
        ]);
        assert_eq!(code, 2, "{err}");
        assert!(err.contains("--projection"), "{err}");
    }

    #[test]
    fn decompose_from_samples_and_from_sh_coefficients() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let (l, spec) = (6usize, "vmf:kappa=10");
        let (code, out, err) = ifd(&[
            "sphere",
            "decompose",
            "--json",
            spec,
            "--lmax",
            "6",
            "-o",
            &p(d, "spec.json"),
        ]);
        assert_eq!(code, 0, "{err}");
        let v = json(&out);
        assert_eq!(
            (v["lobes"].as_u64(), v["channels"].as_u64()),
            (Some(49), Some(1))
        );
        let (_, want) = weights(&p(d, "spec.json"));
        let k = Kernel::parse(spec).unwrap();
        // (N, 5) samples on a Gauss-Legendre product grid with its weights
        let (x, wx) = gauss_legendre(40);
        let mut rows = Vec::new();
        for (&z, &wz) in x.iter().zip(&wx) {
            for j in 0..80 {
                let dd = direction(z.acos(), 2.0 * PI * j as f64 / 80.0);
                rows.extend_from_slice(&[dd[0], dd[1], dd[2], k.eval(dd), wz * 2.0 * PI / 80.0]);
            }
        }
        let samples = p(d, "samples.npy");
        write_npy_f64(Path::new(&samples), &[rows.len() / 5, 5], &rows).unwrap();
        let (code, _, err) = ifd(&[
            "sphere",
            "decompose",
            &samples,
            "--lmax",
            "6",
            "-o",
            &p(d, "s.json"),
        ]);
        assert_eq!(code, 0, "{err}");
        let e = rel_diff(&weights(&p(d, "s.json")).1, &want);
        assert!(e < 1e-9, "samples vs spec: {e}");
        // (N, 4) samples: equal weights 4 pi / N on a fine spherical Fibonacci set
        let fib = ifd_sphere::fibonacci(40_000);
        let rows: Vec<f64> = fib
            .iter()
            .flat_map(|q| [q[0], q[1], q[2], k.eval(*q)])
            .collect();
        write_npy_f64(Path::new(&samples), &[fib.len(), 4], &rows).unwrap();
        let (code, _, err) = ifd(&[
            "sphere",
            "decompose",
            &samples,
            "--lmax",
            "6",
            "-o",
            &p(d, "s4.json"),
        ]);
        assert_eq!(code, 0, "{err}");
        let e = rel_diff(&weights(&p(d, "s4.json")).1, &want);
        assert!(e < 1e-3, "equal-weight samples vs spec: {e}");
        // ((L+1)^2, 2) SH coefficients: the kernel and twice the kernel
        let kc = project_function(l, |w| k.eval(w), 64).unwrap();
        let two: Vec<f64> = kc.data().iter().flat_map(|c| [*c, 2.0 * c]).collect();
        let sh = p(d, "k.sh.npy");
        write_npy_f64(Path::new(&sh), &[(l + 1) * (l + 1), 2], &two).unwrap();
        let (code, out, err) = ifd(&[
            "sphere",
            "decompose",
            "--json",
            &sh,
            "--lmax",
            "6",
            "-o",
            &p(d, "sh.json"),
        ]);
        assert_eq!(code, 0, "{err}");
        let v = json(&out);
        assert_eq!(
            (v["lobes"].as_u64(), v["channels"].as_u64()),
            (Some(49), Some(2))
        );
        let (ch, w2) = weights(&p(d, "sh.json"));
        assert_eq!(ch, 2);
        let c0: Vec<f64> = w2.iter().step_by(2).copied().collect();
        let c1: Vec<f64> = w2.iter().skip(1).step_by(2).map(|x| x / 2.0).collect();
        assert!(rel_diff(&c0, &want) < 1e-9 && rel_diff(&c1, &want) < 1e-9);
        // shared directions: 49 lobes on 13 directions
        let (code, out, _) = ifd(&[
            "sphere",
            "decompose",
            "--json",
            &sh,
            "--lmax",
            "6",
            "--directions",
            "shared",
            "-o",
            &p(d, "x.json"),
        ]);
        assert_eq!(code, 0);
        let v = json(&out);
        assert_eq!(
            (v["lobes"].as_u64(), v["directions"].as_u64()),
            (Some(49), Some(13))
        );
    }

    #[test]
    fn non_finite_coefficients_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let mut c = vec![0.5; 9 * 2];
        c[sh_index(2, 1) * 2 + 1] = f64::NAN;
        c[3] = f64::INFINITY;
        let path = p(d, "bad.sh.npy");
        write_npy_f64(Path::new(&path), &[9, 2], &c).unwrap();
        let (r, j) = (p(d, "r.npy"), p(d, "d.json"));
        for args in [
            vec!["sphere", "rotate", &path, "--zyz", "0,1,0", "-o", &r],
            vec!["sphere", "decompose", &path, "--lmax", "2", "-o", &j],
        ] {
            let (code, _, err) = ifd(&args);
            assert_eq!(code, 2, "{err}");
            assert!(
                err.contains(&path)
                    && err.contains("2 non-finite SH coefficient(s)")
                    && err.contains("first at row 1, column 1"),
                "{err}"
            );
        }
        assert!(!d.join("r.npy").exists() && !d.join("d.json").exists());
    }

    #[test]
    fn rotate_keeps_the_input_shape() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let c: Vec<f64> = (0..9).map(|i| 0.1 * f64::from(i)).collect();
        for (name, shape) in [("one.npy", vec![9]), ("two.npy", vec![9, 1])] {
            let path = p(d, name);
            write_npy_f64(Path::new(&path), &shape, &c).unwrap();
            for method in ["zhf", "tailored", "reference"] {
                let r = p(d, "r.npy");
                let (code, _, err) = ifd(&[
                    "sphere",
                    "rotate",
                    &path,
                    "--zyz",
                    "0.1,0.2,0.3",
                    "--method",
                    method,
                    "-o",
                    &r,
                ]);
                assert_eq!(code, 0, "{err}");
                let a = ifd_image::read_npy_array(
                    Path::new(&r),
                    ifd_image::MemoryBudget::default_for_machine(),
                )
                .unwrap();
                assert_eq!(a.shape, shape, "{name} --method {method}");
            }
        }
    }

    #[test]
    fn optimized_directions_and_degenerate_sets_through_the_cli() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let run = |dirs: &str| {
            let (code, out, err) = ifd(&[
                "sphere",
                "decompose",
                "--json",
                "aniso-gauss:s1=0.4,s2=0.2",
                "--lmax",
                "6",
                "--directions",
                dirs,
                "-o",
                &p(d, "o.json"),
            ]);
            assert_eq!(code, 0, "{err}");
            json(&out)["condition_number"].as_f64().unwrap()
        };
        let (fib, opt) = (run("fibonacci"), run("optimized"));
        assert!(opt < fib, "optimized {opt} vs fibonacci {fib}");
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(p(d, "o.json")).unwrap()).unwrap();
        assert_eq!(v["directions"]["sharing"], "per-band");
        // a degenerate set: band 2's five directions all equal
        let l = 2;
        let mut dirs = Vec::new();
        for i in 0..(l + 1) * (l + 1) {
            let q = if i >= 4 {
                [0.0, 0.6, 0.8]
            } else {
                direction(0.3 + i as f64, 1.7 * i as f64)
            };
            dirs.extend_from_slice(&q);
        }
        let file = p(d, "dirs.npy");
        write_npy_f64(Path::new(&file), &[(l + 1) * (l + 1), 3], &dirs).unwrap();
        let (code, _, err) = ifd(&[
            "sphere",
            "decompose",
            "vmf:kappa=8",
            "--lmax",
            "2",
            "--dirs",
            &file,
            "-o",
            &p(d, "x.json"),
        ]);
        assert_eq!(code, 2);
        assert!(
            err.contains("condition number")
                && err.contains("is degenerate")
                && err.contains("l = 2, cond(M_l) = "),
            "{err}"
        );
        // the same file with a wrong degree names the expected shapes
        let (code, _, err) = ifd(&[
            "sphere",
            "decompose",
            "vmf:kappa=8",
            "--lmax",
            "3",
            "--dirs",
            &file,
            "-o",
            &p(d, "x.json"),
        ]);
        assert_eq!(code, 2);
        assert!(err.contains("(16, 3)") && err.contains("(7, 3)"), "{err}");
        // a good per-band set from a file decomposes
        let good: Vec<f64> = ifd_sphere::DirectionSet::new(
            2,
            ifd_sphere::Sharing::PerBand,
            ifd_sphere::Chooser::Fibonacci,
        )
        .unwrap()
        .all()
        .iter()
        .flatten()
        .copied()
        .collect();
        write_npy_f64(Path::new(&file), &[9, 3], &good).unwrap();
        let (code, _, err) = ifd(&[
            "sphere",
            "decompose",
            "vmf:kappa=8",
            "--lmax",
            "2",
            "--dirs",
            &file,
            "-o",
            &p(d, "x.json"),
        ]);
        assert_eq!(code, 0, "{err}");
    }
}

/// One grammar: reports are a human summary by default and JSON with
/// `--json`; enum-like values are refused with the list.
mod grammar {
    use super::*;

    #[test]
    fn reports_are_human_by_default_and_json_with_the_flag() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("dfg.npy");
        let out = out.to_str().unwrap();
        let (code, human, err) = ifd(&["envmap", "dfg", "--table-size", "8", "-o", out]);
        assert_eq!(code, 0, "{err}");
        assert!(
            serde_json::from_str::<serde_json::Value>(&human).is_err(),
            "{human}"
        );
        assert!(human.lines().any(|l| l.starts_with("size ")), "{human}");
        let (code, json, err) = ifd(&["envmap", "dfg", "--table-size", "8", "-o", out, "--json"]);
        assert_eq!(code, 0, "{err}");
        let v: serde_json::Value = serde_json::from_str(&json).unwrap();
        assert_eq!(v["size"], 8);
    }

    #[test]
    fn a_wrong_choice_is_refused_with_the_list() {
        let (code, _, err) = ifd(&[
            "render", "--env", "x.hdr", "--brdf", "lambert", "--method", "exact", "-o", "o.png",
        ]);
        assert_eq!(code, 2);
        assert!(
            err.contains("possible values") && err.contains("quadrature"),
            "{err}"
        );
        let (code, _, err) = ifd(&["envmap", "prefilter", "x.hdr", "--format", "dds"]);
        assert_eq!(code, 2);
        assert!(err.contains("ktx2") && err.contains("exr"), "{err}");
    }

    /// `ifd --version` names the version, the commit and the vector path.
    #[test]
    fn version_names_the_commit_and_the_vector_path() {
        let (code, out, err) = ifd(&["--version"]);
        assert_eq!(code, 0, "{err}");
        let line = out.trim();
        assert!(
            line.starts_with(&format!("ifd {} (commit ", env!("CARGO_PKG_VERSION"))),
            "{line}"
        );
        let commit = line
            .split("(commit ")
            .nth(1)
            .and_then(|r| r.split(',').next())
            .unwrap_or_default();
        assert!(
            commit == "unknown"
                || (commit.len() == 12 && commit.chars().all(|c| c.is_ascii_hexdigit())),
            "{line}"
        );
        assert!(
            ["avx512)", "avx2)", "baseline)"]
                .iter()
                .any(|p| line.ends_with(&format!("vector path {p}"))),
            "{line}"
        );
        // IFD_SIMD caps the path
        let out = common::run(
            common::ifd_command()
                .env("IFD_SIMD", "baseline")
                .arg("--version"),
        );
        assert!(out.1.trim().ends_with("vector path baseline)"), "{}", out.1);
    }

    /// Nothing was released, so spellings from before the grammar settled
    /// (and the studies, now the `ifd-paper` binary) get clap's ordinary
    /// error, not a command of their own.
    #[test]
    fn unknown_spellings_get_the_ordinary_error() {
        for args in [
            vec!["paper", "list"],
            vec!["mirror"],
            vec!["sphere", "sparsity"],
            vec!["envmap", "shrm"],
        ] {
            let (code, _, err) = ifd(&args);
            assert_eq!(code, 2, "{args:?}: {err}");
            assert!(err.contains("unrecognized subcommand"), "{args:?}: {err}");
        }
        let (code, _, err) = ifd(&["smooth", "x.png", "--scale", "2", "-o", "o.png"]);
        assert_eq!(code, 2);
        assert!(err.contains("unexpected argument '--scale'"), "{err}");
    }
}

/// `ifd render` options for what the papers' studies measure: self-shadowing
/// on meshes and anti-aliased mirror reflections.
mod render_options {
    use super::{ifd, testdata};
    use std::fmt::Write as _;
    use std::path::Path;

    /// A torus (radii 1 and 0.4, z up) as an OBJ file of 32 x 16 quads.
    fn torus_obj(dir: &Path) -> String {
        let (nu, nv) = (32, 16);
        let mut s = String::new();
        for i in 0..nu {
            let a = std::f64::consts::TAU * f64::from(i) / f64::from(nu);
            for j in 0..nv {
                let b = std::f64::consts::TAU * f64::from(j) / f64::from(nv);
                let r = 1.0 + 0.4 * b.cos();
                let _ = writeln!(s, "v {} {} {}", r * a.cos(), r * a.sin(), 0.4 * b.sin());
            }
        }
        let id = |i: u32, j: u32| (i % nu) * nv + (j % nv) + 1;
        for i in 0..nu {
            for j in 0..nv {
                let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
                let _ = writeln!(s, "f {a} {b} {c}\nf {a} {c} {d}");
            }
        }
        let path = dir.join("torus.obj");
        std::fs::write(&path, s).expect("write the OBJ");
        path.to_string_lossy().into_owned()
    }

    fn mean(path: &Path) -> f64 {
        let img = ifd_image::read(path).expect("a rendered image");
        img.data().iter().map(|v| f64::from(*v)).sum::<f64>() / img.data().len() as f64
    }

    #[test]
    fn shadows_darken_a_mesh_and_are_refused_where_they_do_not_apply() {
        let dir = tempfile::tempdir().unwrap();
        let obj = torus_obj(dir.path());
        let forest = testdata("forest.hdr");
        let out = |name: &str| dir.path().join(name);
        let base = [
            "render",
            "--env",
            &forest,
            "--env-size",
            "32x16",
            "--brdf",
            "lambert",
            "--scene",
            &obj,
            "--obj-up",
            "z",
            "--eye",
            "0,-2.4,1.7",
            "--size",
            "24x24",
            "--no-background",
        ];
        let run = |extra: &[&str], name: &str| {
            let mut args = base.to_vec();
            args.extend_from_slice(extra);
            let o = out(name);
            let o = o.to_str().unwrap().to_owned();
            args.extend_from_slice(&["-o", &o]);
            ifd(&args)
        };
        let (code, _, err) = run(
            &["--lmax", "6", "--shadows", "--shadow-rays", "512"],
            "s.exr",
        );
        assert_eq!(code, 0, "{err}");
        let (code, _, err) = run(&["--lmax", "6"], "u.exr");
        assert_eq!(code, 0, "{err}");
        let (code, _, err) = run(&["--method", "quadrature", "--shadows"], "r.exr");
        assert_eq!(code, 0, "{err}");
        let (s, u, r) = (
            mean(&out("s.exr")),
            mean(&out("u.exr")),
            mean(&out("r.exr")),
        );
        assert!(
            s < 0.99 * u && r < 0.99 * u,
            "shadowed {s}, unshadowed {u}, reference {r}"
        );
        assert!(
            (s - r).abs() < (u - r).abs(),
            "isd {s}, reference {r}, open {u}"
        );
        // refusals, each naming the problem
        for (extra, needle) in [
            (
                vec!["--lmax", "6", "--shadows", "--method", "sh"],
                "--method isd",
            ),
            (
                vec!["--lmax", "6", "--shadows", "--shadow-rays", "10"],
                "(L+1)^2",
            ),
            (vec!["--lmax", "6", "--shadow-rays", "100"], "--shadows"),
        ] {
            let (code, _, err) = run(&extra, "x.exr");
            assert_eq!(code, 2, "{extra:?}: {err}");
            assert!(err.contains(needle), "{extra:?}: {err}");
        }
        let (code, _, err) = ifd(&[
            "render",
            "--env",
            &forest,
            "--brdf",
            "lambert",
            "--lmax",
            "4",
            "--shadows",
            "-o",
            out("y.exr").to_str().unwrap(),
        ]);
        assert_eq!(code, 2, "{err}");
        assert!(err.contains("triangle mesh"), "{err}");
        assert!(!out("x.exr").exists() && !out("y.exr").exists());
    }

    /// A tangent-space normal map (RGB, `(n + 1) / 2`) of `w x h`: slopes
    /// `s(u, v)` tilt the normal to `(-sx, -sy, 1)`, normalised.
    fn normal_map(
        dir: &Path,
        name: &str,
        w: usize,
        h: usize,
        s: impl Fn(f64, f64) -> (f64, f64),
    ) -> String {
        let mut data = Vec::with_capacity(w * h * 3);
        for y in 0..h {
            for x in 0..w {
                let (u, v) = ((x as f64 + 0.5) / w as f64, (y as f64 + 0.5) / h as f64);
                let (sx, sy) = s(u, v);
                let l = (sx * sx + sy * sy + 1.0).sqrt();
                data.extend([-sx / l, -sy / l, 1.0 / l].map(|c| f64::midpoint(c, 1.0) as f32));
            }
        }
        let img = ifd_image::Image::from_vec(w, h, 3, data).expect("a map");
        let path = dir.join(name);
        ifd_image::write(&path, &img).expect("write the map");
        path.to_string_lossy().into_owned()
    }

    /// Mean absolute difference over the pixels where `mask` is 1.
    fn masked_error(a: &Path, b: &Path, mask: &Path) -> f64 {
        let (a, b, m) = (
            ifd_image::read(a).expect("a"),
            ifd_image::read(b).expect("b"),
            ifd_image::read(mask).expect("mask"),
        );
        let ch = a.channels();
        let (mut sum, mut n) = (0.0, 0.0);
        for (i, mv) in m.data().iter().step_by(m.channels()).enumerate() {
            if *mv > 0.5 {
                for c in 0..ch {
                    sum += f64::from((a.data()[i * ch + c] - b.data()[i * ch + c]).abs());
                    n += 1.0;
                }
            }
        }
        sum / n
    }

    #[test]
    fn a_normal_mapped_mirror_is_anti_aliased_by_isd() {
        let dir = tempfile::tempdir().unwrap();
        let forest = testdata("forest.hdr");
        let out = |name: &str| dir.path().join(name).to_string_lossy().into_owned();
        let flat = normal_map(dir.path(), "flat.exr", 16, 8, |_, _| (0.0, 0.0));
        let bumps = normal_map(dir.path(), "bumps.exr", 256, 128, |u, v| {
            let a = 0.35 * f64::from(u8::from(v < 0.5));
            (
                a * (std::f64::consts::TAU * 24.0 * u).cos(),
                a * (std::f64::consts::TAU * 12.0 * v).cos(),
            )
        });
        let run = |extra: &[&str], name: &str| {
            let o = out(name);
            let mut args = vec![
                "render",
                "--env",
                &forest,
                "--brdf",
                "mirror",
                "--size",
                "64x64",
                "--eye",
                "0,-3.2,1.1",
                "-o",
                &o,
            ];
            args.extend_from_slice(extra);
            let (code, _, err) = ifd(&args);
            assert_eq!(code, 0, "{extra:?}: {err}");
        };
        // a flat normal map changes nothing
        run(
            &[
                "--method",
                "quadrature",
                "--spp",
                "1",
                "--mask",
                &out("mask.exr"),
            ],
            "plain.exr",
        );
        run(
            &[
                "--method",
                "quadrature",
                "--spp",
                "1",
                "--normal-map",
                &flat,
            ],
            "flat.exr",
        );
        let mask = dir.path().join("mask.exr");
        let p = |n: &str| dir.path().join(n);
        assert!(masked_error(&p("plain.exr"), &p("flat.exr"), &mask) < 1e-6);
        // bumps: ISD's filter is closer to the jittered reference than the
        // centre sample, and than 2x2 supersampling
        let nm = ["--normal-map", bumps.as_str()];
        run(
            &[&nm[..], &["--method", "mc", "--spp", "1024"]].concat(),
            "ref.exr",
        );
        run(
            &[&nm[..], &["--method", "quadrature", "--spp", "1"]].concat(),
            "none.exr",
        );
        run(
            &[&nm[..], &["--method", "quadrature", "--spp", "4"]].concat(),
            "ss2.exr",
        );
        run(
            &[&nm[..], &["--method", "isd", "--lmax", "32"]].concat(),
            "isd.exr",
        );
        let e = |n: &str| masked_error(&p(n), &p("ref.exr"), &mask);
        let (none, ss2, isd) = (e("none.exr"), e("ss2.exr"), e("isd.exr"));
        assert!(
            isd < 0.6 * none && isd < ss2,
            "isd {isd}, 2x2 {ss2}, none {none}"
        );
        assert!(masked_error(&p("plain.exr"), &p("none.exr"), &mask) > 2.0 * none.min(isd));
        // refusals
        for (extra, needle) in [
            (
                vec!["--method", "sh", "--lmax", "4"],
                "isd, quadrature or mc",
            ),
            (vec!["--method", "mc", "--spp", "10"], "square number"),
            (vec!["--method", "isd"], "--lmax"),
            (
                vec!["--method", "isd", "--lmax", "8", "--light", "0,0,3,0.5,10"],
                "--light",
            ),
        ] {
            let o = out("x.exr");
            let mut args = vec!["render", "--env", &forest, "--brdf", "mirror", "-o", &o];
            args.extend_from_slice(&extra);
            let (code, _, err) = ifd(&args);
            assert_eq!(code, 2, "{extra:?}: {err}");
            assert!(err.contains(needle), "{extra:?}: {err}");
            assert!(!dir.path().join("x.exr").exists());
        }
    }
}

/// Issue 54: a command that reports prints a summary a person reads (at most
/// eight lines: what it wrote, sizes, the time, the accuracy) by default,
/// the whole report with `-v` and the JSON report with `--json`.
mod summaries {
    use super::*;

    /// `SUMMARY_LINES` in `src/options.rs`.
    const MOST_LINES: usize = 8;

    /// Runs `args` three ways: the default summary must hold at most
    /// [`MOST_LINES`] lines and not be JSON, `--json` must parse as one
    /// object, `-v` must print at least as much as the summary. Returns the
    /// summary.
    fn check(args: &[&str]) -> String {
        let (code, summary, err) = ifd(args);
        assert_eq!(code, 0, "{args:?}: {err}");
        let lines = summary.lines().count();
        assert!(
            (1..=MOST_LINES).contains(&lines),
            "{args:?}: the default summary has {lines} lines (at most {MOST_LINES}):\n{summary}"
        );
        assert!(
            serde_json::from_str::<serde_json::Value>(&summary).is_err(),
            "{args:?}: the default output is JSON:\n{summary}"
        );
        let json_args: Vec<&str> = args.iter().copied().chain(["--json"]).collect();
        let (code, json, err) = ifd(&json_args);
        assert_eq!(code, 0, "{json_args:?}: {err}");
        let v: serde_json::Value =
            serde_json::from_str(&json).unwrap_or_else(|e| panic!("{json_args:?}: {e}:\n{json}"));
        assert!(v.is_object(), "{json_args:?}: {json}");
        let verbose_args: Vec<&str> = args.iter().copied().chain(["-v"]).collect();
        let (code, detail, err) = ifd(&verbose_args);
        assert_eq!(code, 0, "{verbose_args:?}: {err}");
        assert!(
            detail.lines().count() >= lines,
            "{verbose_args:?}: -v prints less than the summary:\n{detail}\nvs\n{summary}"
        );
        summary
    }

    fn p(dir: &Path, name: &str) -> String {
        dir.join(name).to_string_lossy().into_owned()
    }

    #[test]
    fn every_reporting_command_prints_at_most_eight_lines_by_default() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let cam = testdata("camera.png");
        let coffee = testdata("coffee.png");
        let forest = testdata("forest.hdr");
        let exr = testdata("forest_dwab.exr");
        // an image of 9 channels: its per-channel tables are longer than 8 lines
        let (w, h, c) = (16usize, 12usize, 9usize);
        let data: Vec<f64> = (0..w * h * c).map(|i| (i % 17) as f64 / 16.0).collect();
        let wide = p(d, "wide.npy");
        ifd_image::write_npy_f64(Path::new(&wide), &[h, w, c], &data).unwrap();
        let other: Vec<f64> = data.iter().map(|x| 0.9 * x).collect();
        let wide2 = p(d, "wide2.npy");
        ifd_image::write_npy_f64(Path::new(&wide2), &[h, w, c], &other).unwrap();

        check(&["info", &cam]);
        check(&["info", &coffee]);
        let info = check(&["info", &wide]);
        assert!(info.contains("all channels"), "{info}");
        check(&["compare", &cam, &cam]);
        check(&["compare", &coffee, &coffee]);
        let cmp = check(&["compare", &wide, &wide2]);
        assert!(cmp.contains("overall"), "{cmp}");
        let (_, all, _) = ifd(&["compare", &wide, &wide2, "-v"]);
        assert_eq!(all.lines().count(), 3 + c, "{all}");
        let dec = p(d, "d.json");
        let s = check(&[
            "decompose",
            "gauss:sx=6,sy=2",
            "-o",
            &dec,
            "--plot",
            &p(d, "plot.png"),
        ]);
        assert!(s.contains(&dec) && s.contains("terms"), "{s}");
        check(&["sphere", "sh", &exr, "--lmax", "4", "-o", &p(d, "c.npy")]);
        check(&[
            "sphere",
            "sh",
            &exr,
            "--lmax",
            "4",
            "-o",
            &p(d, "c.npy"),
            "--reconstruct",
            &p(d, "rec.exr"),
        ]);
        let sd = p(d, "s.json");
        check(&[
            "sphere",
            "decompose",
            "vmf:kappa=10",
            "--lmax",
            "4",
            "-o",
            &sd,
        ]);
        check(&[
            "sphere",
            "filter",
            &exr,
            "--decomp",
            &sd,
            "--size",
            "32x16",
            "-o",
            &p(d, "f.npy"),
        ]);
        check(&[
            "sphere",
            "brdf",
            "lambert",
            "--lmax",
            "4",
            "-o",
            &p(d, "l.lobes"),
        ]);
        check(&[
            "sphere",
            "radial",
            "--brdf",
            "lambert",
            "--lmax",
            "2",
            "--light-profile",
            "overcast",
            "--cells",
            "2x2x2",
            "-o",
            &p(d, "rad.npy"),
            "--coeffs",
            &p(d, "rc.npy"),
            "--preview",
            &p(d, "rad.png"),
            "--check",
            "4",
        ]);
        check(&[
            "sphere",
            "brdf-filter",
            "--brdf",
            "ggx:alpha=0.5",
            "--lmax",
            "2",
            "--kappa",
            "10",
            "--clean",
            "ggx:alpha=0.5",
            "-o",
            &p(d, "bf.npy"),
        ]);
        let render = |extra: &[&str]| {
            let out = p(d, "r.png");
            let mut args = vec![
                "render", "--env", &forest, "--size", "16x16", "--lmax", "4", "-o", &out,
            ];
            args.extend_from_slice(extra);
            let s = check(&args);
            assert!(s.starts_with(&format!("wrote {out} (16x16")), "{s}");
            s
        };
        render(&["--brdf", "ggx:alpha=0.3"]);
        render(&[
            "--brdf",
            "ggx:alpha=0.3",
            "--mask",
            &p(d, "m.npy"),
            "--gbuffer",
            &p(d, "g.npy"),
        ]);
        let s = render(&["--brdf", "ggx:alpha=0.5", "--error-map", &p(d, "e.npy")]);
        assert!(s.contains("relative RMS"), "{s}");
        render(&["--brdf", "ggx:alpha=0.5", "--method", "quadrature"]);
        render(&["--brdf", "mirror"]);
        let s = check(&[
            "envmap",
            "prefilter",
            &forest,
            "--face-size",
            "16",
            "--irradiance-size",
            "4",
            "--out-dir",
            &p(d, "ibl"),
        ]);
        assert!(s.contains("radiance.ktx2") && s.contains("sh.npy"), "{s}");
        check(&[
            "envmap",
            "prefilter",
            &forest,
            "--face-size",
            "16",
            "--irradiance-size",
            "4",
            "--format",
            "exr",
            "--out-dir",
            &p(d, "ibl-exr"),
        ]);
        check(&["envmap", "dfg", "--table-size", "8", "-o", &p(d, "dfg.npy")]);
    }

    /// `gpu-info`'s summary (it needs an adapter: lavapipe where there is no
    /// GPU; skipped without one under `IFD_GPU_TESTS=skip`).
    #[test]
    fn gpu_info_prints_a_short_summary() {
        let (code, _, err) = ifd(&["gpu-info"]);
        if gpu_missing_ok(code, &err) {
            return;
        }
        let s = check(&["gpu-info"]);
        assert!(s.starts_with("adapter: "), "{s}");
    }

    /// The check above can fail: a report of every figure is longer.
    #[test]
    fn the_whole_report_is_longer_than_a_summary() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("ibl");
        let (code, detail, err) = ifd(&[
            "envmap",
            "prefilter",
            &testdata("forest.hdr"),
            "--face-size",
            "16",
            "--out-dir",
            out.to_str().unwrap(),
            "-v",
        ]);
        assert_eq!(code, 0, "{err}");
        assert!(detail.lines().count() > MOST_LINES, "{detail}");
        assert!(detail.contains("levels:"), "{detail}");
    }
}

/// `ifd render --tol E`: the degree chosen by the measured rule keeps the
/// image within E of the oracle, over the object and over its grazing
/// pixels; what the rule cannot reach is refused with the reachable value.
mod render_tol {
    use super::{ifd, testdata};
    use std::path::Path;

    /// The relative RMS error of `a` against `b` over the pixels where
    /// `keep(n.v)` holds on the object, and how many there are.
    fn rel_rms(a: &Path, b: &Path, gbuffer: &Path, keep: impl Fn(f32) -> bool) -> (f64, usize) {
        let (a, b, g) = (
            ifd_image::read(a).expect("render_tol"),
            ifd_image::read(b).expect("render_tol"),
            // NaN roughness and metalness where the BRDF has none
            ifd_image::read_image(
                gbuffer,
                &ifd_image::ReadOptions {
                    non_finite: ifd_image::NonFinitePolicy::Replace(0.0),
                    ..Default::default()
                },
            )
            .expect("render_tol")
            .image,
        );
        let (mut num, mut den, mut n) = (0.0, 0.0, 0);
        for i in 0..a.width() * a.height() {
            let nv = g.data()[i * 6 + 3];
            let on = g.data()[i * 6..i * 6 + 3].iter().any(|x| *x != 0.0);
            if !on || !keep(nv) {
                continue;
            }
            n += 1;
            for c in 0..3 {
                let (x, y) = (
                    f64::from(a.data()[i * 3 + c]),
                    f64::from(b.data()[i * 3 + c]),
                );
                num += (x - y) * (x - y);
                den += y * y;
            }
        }
        ((num / den).sqrt(), n)
    }

    /// Renders `brdf` on `map` at --tol `tol` and by the oracle, checks the
    /// errors over the object and over its grazing pixels, and returns the
    /// chosen L.
    fn within(map: &str, brdf: &str, tol: f64) -> usize {
        let dir = tempfile::tempdir().expect("render_tol");
        let p = |n: &str| dir.path().join(n);
        let env = testdata(map);
        let tol_s = tol.to_string();
        let common = [
            "render",
            "--env",
            &env,
            "--brdf",
            brdf,
            "--size",
            "96x96",
            "--no-background",
        ];
        let isd = p("isd.npy");
        let args: Vec<&str> = common
            .iter()
            .copied()
            .chain([
                "--tol",
                &tol_s,
                "--json",
                "-o",
                isd.to_str().expect("render_tol"),
            ])
            .collect();
        let (code, out, err) = ifd(&args);
        assert_eq!(code, 0, "{args:?}: {err}");
        let report: serde_json::Value = serde_json::from_str(&out).expect("render_tol");
        let l = report["lmax"].as_u64().expect("the chosen L") as usize;
        assert_eq!(report["tol"]["lmax"].as_u64(), Some(l as u64), "{report}");
        assert_eq!(report["tol"]["tolerance"].as_f64(), Some(tol), "{report}");
        let (oracle, gbuffer) = (p("oracle.npy"), p("g.npy"));
        let args: Vec<&str> = common
            .iter()
            .copied()
            .chain([
                "--method",
                "quadrature",
                "--gbuffer",
                gbuffer.to_str().expect("render_tol"),
            ])
            .chain(["-o", oracle.to_str().expect("render_tol")])
            .collect();
        let (code, _, err) = ifd(&args);
        assert_eq!(code, 0, "{args:?}: {err}");
        let (object, n_object) = rel_rms(&isd, &oracle, &gbuffer, |_| true);
        let (grazing, n_grazing) = rel_rms(&isd, &oracle, &gbuffer, |nv| nv < 0.2);
        assert!(
            n_grazing >= 20 && n_object > 10 * n_grazing,
            "{n_grazing} of {n_object}"
        );
        assert!(
            object <= tol && grazing <= tol,
            "{brdf} on {map} at --tol {tol} (L = {l}): relative RMS {object:.3e} over the \
             object, {grazing:.3e} over its {n_grazing} grazing pixels"
        );
        l
    }

    #[test]
    fn the_chosen_degree_keeps_object_and_grazing_pixels_within_the_tolerance() {
        // at 96x96, between the sizes the rule was measured at (64x64 and
        // 128x128): the issue's red dielectric, roughness 0.5, whose
        // grazing pixels err 6% at L = 24 on the sunrise map
        let l = within(
            "sunrise.hdr",
            "gltf:roughness=0.5,metallic=0,base=0.8:0.1:0.1",
            0.02,
        );
        assert!(l > 24, "L = {l}");
        within("forest.hdr", "gltf:roughness=0.7,metallic=1,base=0.9", 0.05);
        let coarse = within("sunrise.hdr", "lambert", 0.02);
        let fine = within("sunrise.hdr", "lambert", 0.005);
        assert!(fine > coarse, "{fine} <= {coarse}");
    }

    #[test]
    fn unreachable_tolerances_and_conflicting_flags_are_refused() {
        let env = testdata("forest.hdr");
        let dir = tempfile::tempdir().expect("render_tol");
        let out = dir.path().join("o.png");
        let out = out.to_str().expect("render_tol");
        let run = |extra: &[&str]| {
            let args: Vec<&str> = ["render", "--env", &env, "--size", "16x16", "-o", out]
                .into_iter()
                .chain(extra.iter().copied())
                .collect();
            let (code, _, err) = ifd(&args);
            assert_eq!(code, 2, "{args:?}: {err}");
            err
        };
        // below the table's floor at grazing views: the reachable value named
        let err = run(&["--brdf", "gltf:roughness=0.5,metallic=1", "--tol", "1e-5"]);
        assert!(err.contains("smallest reachable is"), "{err}");
        // a near-mirror needs L near 400
        let err = run(&["--brdf", "gltf:roughness=0.1,metallic=1", "--tol", "0.01"]);
        assert!(err.contains("400") && err.contains("--lmax"), "{err}");
        for bad in ["0", "1", "-0.1", "NaN", "inf"] {
            let err = run(&["--brdf", "lambert", "--tol", bad]);
            assert!(err.contains("--tol"), "{bad}: {err}");
        }
        let err = run(&["--brdf", "lambert", "--tol", "0.01", "--lmax", "8"]);
        assert!(err.contains("--lmax") && err.contains("--tol"), "{err}");
        let err = run(&[
            "--brdf",
            "lambert",
            "--tol",
            "0.01",
            "--method",
            "quadrature",
        ]);
        assert!(err.contains("no L to choose"), "{err}");
        let err = run(&["--brdf", "ward:ax=0.3,ay=0.3", "--tol", "0.01"]);
        assert!(err.contains("measured for"), "{err}");
        let err = run(&["--brdf", "mirror", "--tol", "0.01"]);
        assert!(err.contains("--tol"), "{err}");
    }
}
