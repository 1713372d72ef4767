//! The app in a real window under Xvfb (software Vulkan through lavapipe):
//! replays strokes, saves, takes a screenshot, and checks it shows the
//! image and the controls. The screenshot is kept in `tests/artifacts/`.
//!
//! Without Xvfb (`xvfb-run`, `Xvfb`; Debian `xvfb xauth`, which
//! `scripts/test-all.sh` installs) the test fails, unless
//! `IFD_WINDOW_TESTS=skip` is set (as `IFD_GPU_TESTS=skip` for the GPU tests).

mod common;
#[path = "../../../tests/support/skip.rs"]
mod skip;

#[path = "../../../tests/support/xvfb.rs"]
mod xvfb;

use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

/// The shared window-test set-up ([`xvfb::WindowTest`]) for `ifd-brush`,
/// with the test's bank cache.
struct WindowTest(xvfb::WindowTest);

impl std::ops::Deref for WindowTest {
    type Target = xvfb::WindowTest;
    fn deref(&self) -> &xvfb::WindowTest {
        &self.0
    }
}

impl WindowTest {
    /// `None` when Xvfb is missing and the test may be skipped.
    fn new() -> Option<Self> {
        xvfb::WindowTest::new().map(Self)
    }

    /// `xvfb-run ... ifd-brush` with the state and runtime folders set and
    /// the test's bank cache; the caller adds the app's arguments.
    fn command(&self) -> Command {
        self.command_under(&[])
    }

    /// [`Self::command`] run by `wrapper` (e.g. `["timeout", "300"]`).
    fn command_under(&self, wrapper: &[&str]) -> Command {
        let mut c = self.0.command(
            wrapper,
            env!("CARGO_BIN_EXE_ifd-brush"),
            "IFD_BRUSH_STATE_DIR",
        );
        c.args(["--bank", common::bank_cache().to_str().expect("utf8")]);
        c
    }
}

#[test]
fn window_under_xvfb_shows_image_and_controls() {
    let Some(win) = WindowTest::new() else {
        return;
    };
    let dir = win.path();
    let input = dir.join("in.png");
    let img = common::crop(100, 50, 320, 256);
    ifd_image::write(&input, &img).expect("write");
    let strokes = dir.join("strokes.json");
    std::fs::write(
        &strokes,
        r#"{"format": "ifd-brush-strokes", "version": 1, "strokes": [
            {"brush": {"radius": 24, "strength": 1.0}, "points": [[60, 60], [250, 180]]}]}"#,
    )
    .expect("strokes");
    let artifacts = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/artifacts");
    std::fs::create_dir_all(&artifacts).expect("artifacts dir");
    let shot = artifacts.join("brush-screenshot.png");
    std::fs::remove_file(&shot).ok();
    let out = dir.join("out.exr");
    let state = &win.state;
    let run = |gpu: &str, shot: &Path, out: &Path| -> String {
        let log = dir.join(format!("stderr-{gpu}.txt"));
        let mut child = win
            .command()
            .arg(&input)
            .args(["--replay", strokes.to_str().expect("utf8")])
            .args(["--save", out.to_str().expect("utf8")])
            .args(["--screenshot", shot.to_str().expect("utf8")])
            .args(["--brush", r#"{"radius": 37.5}"#])
            .args(["--device", gpu])
            .arg("--exit")
            .stderr(std::fs::File::create(&log).expect("log file"))
            .spawn()
            .expect("start xvfb-run");
        let t0 = Instant::now();
        let status = loop {
            if let Some(s) = child.try_wait().expect("wait") {
                break s;
            }
            if t0.elapsed() > Duration::from_mins(5) {
                child.kill().ok();
                panic!("the app did not exit within 5 minutes");
            }
            std::thread::sleep(Duration::from_millis(200));
        };
        let stderr = std::fs::read_to_string(&log).unwrap_or_default();
        assert!(
            status.success(),
            "ifd-brush --device {gpu} in Xvfb failed: {status}\n{stderr}"
        );
        stderr
    };
    run("cpu", &shot, &out);

    // Settings were persisted (eframe storage) on exit.
    let persisted = std::fs::read_to_string(state.join("app.ron")).unwrap_or_default();
    assert!(
        persisted.contains("ifd-brush-settings") && persisted.contains("37.5"),
        "settings not persisted: {persisted:?}"
    );

    // The windowed replay saved the same result as the headless one would.
    let saved = ifd_image::read(&out).expect("saved result");
    let saved =
        ifd_image::Image::from_vec(saved.width(), saved.height(), 1, saved.plane(0)).expect("grey");
    assert!(common::max_diff(&saved, &ifd_image::read(&input).expect("input")) > 0.02);

    let s = ifd_image::read(&shot).expect("screenshot");
    let (w, h) = (s.width(), s.height());
    assert!(w >= 800 && h >= 600, "screenshot is {w}x{h}");
    let lum = |x: usize, y: usize| (s.get(x, y, 0) + s.get(x, y, 1) + s.get(x, y, 2)) / 3.0;
    let stats = |x0: usize, x1: usize, y0: usize, y1: usize| {
        let v: Vec<f32> = (y0..y1)
            .flat_map(|y| (x0..x1).map(move |x| (x, y)))
            .map(|(x, y)| lum(x, y))
            .collect();
        let m = v.iter().sum::<f32>() / v.len() as f32;
        let var = v.iter().map(|a| (a - m) * (a - m)).sum::<f32>() / v.len() as f32;
        (m, var)
    };
    // Whole window: not blank.
    let (_, var) = stats(0, w, 0, h);
    assert!(var > 1e-3, "screenshot is blank (variance {var})");
    // Controls on the left: text on the panel background.
    let (_, var_left) = stats(5, 280, 40, 400);
    assert!(var_left > 1e-3, "no controls visible (variance {var_left})");
    // The image in the canvas: grey photo pixels (r = g = b) of many levels,
    // unlike the flat canvas background.
    let mut levels = std::collections::BTreeSet::new();
    let mut grey = 0usize;
    let mut n = 0usize;
    for y in (h / 4..3 * h / 4).step_by(3) {
        for x in (w / 2..w - 60).step_by(3) {
            n += 1;
            let (r, g, b) = (s.get(x, y, 0), s.get(x, y, 1), s.get(x, y, 2));
            if (r - g).abs() < 0.01 && (g - b).abs() < 0.01 {
                grey += 1;
                levels.insert((r * 255.0).round() as u32);
            }
        }
    }
    assert!(
        grey * 2 > n,
        "canvas is not the grey photo ({grey} of {n} grey)"
    );
    assert!(
        levels.len() > 40,
        "canvas has only {} grey levels",
        levels.len()
    );
    eprintln!(
        "screenshot {w}x{h}: variance {var:.4}, controls variance {var_left:.4}, {} grey levels in the canvas; kept at {}",
        levels.len(),
        shot.display()
    );

    // The GPU path in the window: the document is painted on the window's
    // own device and shown from there (no readback per dab). The saved
    // result and the canvas on screen match the CPU run's.
    let gpu_shot = artifacts.join("brush-screenshot-gpu.png");
    std::fs::remove_file(&gpu_shot).ok();
    let gpu_out = dir.join("out-gpu.exr");
    let log = run("gpu", &gpu_shot, &gpu_out);
    if !log.contains("shown without readback") {
        assert!(
            skip::allowed("IFD_GPU_TESTS"),
            "the window's GPU path does not show the document from the device (no Vulkan \
             adapter under Xvfb? install mesa-vulkan-drivers or set IFD_GPU_TESTS=skip):\n{log}"
        );
        eprintln!("{log}");
        skip::skip("the GPU display check: no Vulkan adapter under Xvfb (IFD_GPU_TESTS=skip)");
        return;
    }
    let cpu_saved = ifd_image::read(&out).expect("saved");
    let gpu_saved = ifd_image::read(&gpu_out).expect("saved");
    let d = common::max_diff(&gpu_saved, &cpu_saved);
    assert!(
        d < 1e-3,
        "the GPU window saved a result {d} away from the CPU's"
    );
    let g = ifd_image::read(&gpu_shot).expect("GPU screenshot");
    assert_eq!((g.width(), g.height()), (w, h));
    // The canvas area (the status bar and the side panel show timings and
    // the adapter, which differ): every pixel within 2 levels of 255.
    let mut worst = 0.0f32;
    for y in h / 8..h - 40 {
        for x in 300..w {
            for k in 0..3 {
                worst = worst.max((g.get(x, y, k) - s.get(x, y, k)).abs());
            }
        }
    }
    eprintln!(
        "GPU display: canvas within {:.1} levels of the CPU display; kept at {}",
        worst * 255.0,
        gpu_shot.display()
    );
    assert!(
        worst <= 2.01 / 255.0,
        "the GPU-displayed canvas differs from the CPU display by {:.1} levels",
        worst * 255.0
    );
}

/// An automated run that cannot finish (here: a screenshot whose folder is a
/// regular file) closes its window and exits with status 2 from `main`,
/// with the message and no panic.
#[test]
fn automation_failure_exits_2_with_the_message() {
    let Some(win) = WindowTest::new() else {
        return;
    };
    let input = win.path().join("in.png");
    ifd_image::write(&input, &common::crop(100, 50, 128, 96)).expect("write");
    let not_a_folder = win.path().join("file");
    std::fs::write(&not_a_folder, b"a regular file").expect("file");
    let shot = not_a_folder.join("shot.png");
    let out = win
        .command_under(&["timeout", "300"])
        .arg(&input)
        .args(["--screenshot", shot.to_str().expect("utf8")])
        .args(["--device", "cpu"])
        .arg("--exit")
        .output()
        .expect("start xvfb-run");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("error: writing the screenshot") && stderr.contains("shot.png"),
        "{stderr}"
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(!shot.exists());
}
