//! End-to-end tests of the `ifd` binary: exit codes and messages for bad input.

use std::path::{Path, PathBuf};
use std::process::Command;

fn ifd(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_ifd"))
        .args(args)
        .output()
        .expect("run ifd");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn testdata(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../testdata")
        .join(name)
        .to_string_lossy()
        .into_owned()
}

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
    // (the file holds none, so a later check would say "truncated").
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
fn gpu_missing_ok(code: i32, err: &str) -> bool {
    code == 2
        && err.contains("no GPU adapter")
        && std::env::var("IFD_GPU_TESTS").is_ok_and(|v| v == "skip")
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
    let (amap, smap) = (amap.to_string_lossy(), smap.to_string_lossy());
    for (name, extra) in [
        ("constant", vec!["--angle", "-35", "--scale", "1.5"]),
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
        args[5] = &*gpu;
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
fn smooth_gpu_matches_cpu_and_refuses_dab_mode() {
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
    let (code, _, err) = ifd(&["smooth", &small, "--scale", "3", "-o", &cpu]);
    assert_eq!(code, 0, "{err}");
    let (code, _, err) = ifd(&["smooth", &small, "--scale", "3", "--gpu", "-o", &gpu]);
    if gpu_missing_ok(code, &err) {
        return;
    }
    assert_eq!(code, 0, "{err}");
    let rel = relative_difference(&gpu, &cpu);
    assert!(rel <= 1e-4, "GPU and CPU smoothing differ by {rel:e}");
    let (code, _, err) = ifd(&[
        "smooth", &small, "--scale", "3", "--gpu", "--mode", "dab", "-o", &gpu,
    ]);
    assert_eq!(code, 2);
    assert!(err.contains("per-pixel"), "{err}");
}
