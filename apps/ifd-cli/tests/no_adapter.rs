//! `ifd gpu-info` and `ifd filter --gpu` on a machine without any Vulkan
//! driver: a clear message and exit code 2, never a panic. The Vulkan loader
//! is pointed at a driver manifest that does not exist (`VK_DRIVER_FILES`,
//! and `VK_ICD_FILENAMES` for older loaders), and wgpu is restricted to
//! Vulkan (`WGPU_BACKEND=vulkan`): in a whole-workspace build, feature
//! unification with eframe compiles wgpu's GL backend in too, and Mesa's GL
//! llvmpipe would otherwise be found.

mod common;

const MISSING: &str = "/nonexistent/ifd-no-vulkan-driver.json";

fn ifd_without_vulkan(args: &[&str]) -> (i32, String, String) {
    common::run(
        common::ifd_command()
            .args(args)
            .env("VK_DRIVER_FILES", MISSING)
            .env("VK_ICD_FILENAMES", MISSING)
            .env_remove("VK_ADD_DRIVER_FILES")
            .env("WGPU_BACKEND", "vulkan"),
    )
}

fn assert_no_adapter_error(code: i32, err: &str) {
    assert_eq!(code, 2, "{err}");
    assert!(
        err.starts_with("error: ") && err.contains("no GPU adapter found"),
        "{err}"
    );
    assert!(err.contains("mesa-vulkan-drivers"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn gpu_info_without_vulkan_says_so() {
    let (code, _, err) = ifd_without_vulkan(&["gpu-info", "--all"]);
    assert_no_adapter_error(code, &err);
}

#[test]
fn filter_gpu_without_vulkan_exits_2_and_writes_nothing() {
    let dir = tempfile::tempdir().expect("tempdir");
    let decomp = dir.path().join("d.json");
    std::fs::write(
        &decomp,
        r#"{"format": "ifd-decomposition", "version": 1, "kernel": null, "dictionary": null, "report": null,
            "terms": [{"weight": 1.0, "x": 0.0, "y": 0.0, "sigma": 2.0}]}"#,
    )
    .expect("write decomposition");
    let img = common::testdata("camera.png");
    let out = dir.path().join("out.png");
    let (code, _, err) = ifd_without_vulkan(&[
        "filter",
        &img,
        "--decomp",
        decomp.to_str().expect("utf8"),
        "-o",
        out.to_str().expect("utf8"),
        "--gpu",
    ]);
    assert_no_adapter_error(code, &err);
    assert!(!out.exists(), "a failed run wrote {}", out.display());
    // The same command without --gpu works: the failure was the adapter.
    let (code, _, err) = ifd_without_vulkan(&[
        "filter",
        &img,
        "--decomp",
        decomp.to_str().expect("utf8"),
        "-o",
        out.to_str().expect("utf8"),
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(out.exists());
}
