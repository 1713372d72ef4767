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
    std::fs::write(&p, bytes).unwrap();
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
        err.contains("would need 1.2 MiB") && err.contains("budget of 1.0 MiB"),
        "{err}"
    );
}

#[test]
fn nan_input_refused_or_replaced() {
    let dir = tempfile::tempdir().unwrap();
    // A 12x12 float32 .npy with one NaN.
    let mut header = "{'descr': '<f4', 'fortran_order': False, 'shape': (12, 12), }".to_string();
    while (10 + header.len() + 1) % 64 != 0 {
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
        err.contains("1 non-finite") && err.contains("x=1, y=1"),
        "{err}"
    );
    let (code, _, err) = ifd(&["compare", &p, &p, "--replace-nonfinite", "0"]);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("replaced 1 non-finite"), "{err}");
}

#[test]
fn zero_sized_and_mismatched() {
    let dir = tempfile::tempdir().unwrap();
    let mut header = "{'descr': '<f4', 'fortran_order': False, 'shape': (0, 3), }".to_string();
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend_from_slice(&(header.len() as u16).to_le_bytes());
    bytes.extend_from_slice(header.as_bytes());
    let p = write_file(dir.path(), "empty.npy", &bytes);
    let (code, _, err) = ifd(&["compare", &p, &p]);
    assert_eq!(code, 2);
    assert!(err.contains("empty"), "{err}");
    let (code, _, err) = ifd(&["compare", &testdata("camera.png"), &testdata("coffee.png")]);
    assert_eq!(code, 2);
    assert!(err.contains("512x512") && err.contains("600x400"), "{err}");
}
