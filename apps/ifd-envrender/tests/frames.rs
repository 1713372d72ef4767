//! Loading a large environment map never stalls the UI thread: the app runs
//! in a headless egui harness (no window, no GPU: the CPU renderer; the frame
//! time is the app's `frame` plus egui's layout and tessellation) at about 60
//! frames per second while the worker decodes a 4096x2048 HDR map, projects
//! it, builds the GGX lobe table and renders. The test checks that the frame
//! appears without errors and prints the frame times BENCHMARKS.md reports
//! (median, p99, max against the 50 ms goal); the times are reported, not
//! asserted (a timed assertion flakes on a loaded 2-core machine). It also
//! checks that a map that cannot be read leaves an error and the previous
//! frame.

use std::time::{Duration, Instant};

use ifd_app::Headless;
use ifd_envrender::app::{Automation, EnvApp, StartOptions};
use ifd_envrender::settings::Settings;
use ifd_gpu::DeviceChoice;
use ifd_image::Image;

#[test]
fn a_large_map_loads_without_stalling_the_ui_and_bad_maps_keep_the_frame() {
    let dir = tempfile::tempdir().expect("tempdir");
    // 4096 x 2048 RGB, a smooth sky with a bright sun
    let (w, h) = (4096, 2048);
    let data = (0..w * h * 3)
        .map(|i| {
            let p = i / 3;
            let (x, y) = ((p % w) as f32 / w as f32, (p / w) as f32 / h as f32);
            let sun = if (x - 0.3).hypot(y - 0.25) < 0.01 {
                50.0
            } else {
                0.0
            };
            [0.4 + 0.6 * (1.0 - y), 0.5 + 0.3 * x, 0.8 - 0.5 * y][i % 3] + sun
        })
        .collect();
    let path = dir.path().join("sky.hdr");
    ifd_image::write(&path, &Image::from_vec(w, h, 3, data).expect("image")).expect("write");

    let mut h = Headless::new([1180.0, 760.0]);
    let settings = Settings {
        env: Some(path),
        size: [320, 240],
        ..Settings::default()
    };
    let mut app = EnvApp::new(
        h.ctx(),
        settings,
        StartOptions {
            render_state: None,
            gpu: DeviceChoice::Cpu,
            automation: Automation::default(),
        },
    );
    let t0 = Instant::now();
    while !app.frame_complete() {
        assert!(app.errors().is_empty(), "{:?}", app.errors());
        assert!(
            t0.elapsed() < Duration::from_mins(5),
            "no frame after 300 s"
        );
        h.frame(Vec::new(), |ui| app.frame(ui));
        std::thread::sleep(Duration::from_millis(16));
    }
    let shown = t0.elapsed();
    let times = h.times();
    eprintln!(
        "4096x2048 HDR map: first frame after {:.2} s; {}",
        shown.as_secs_f64(),
        times.summary()
    );
    let plot = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("envrender-frame-times.png");
    times
        .report("ifd-envrender, 4096x2048 map", &plot)
        .expect("frame-time report");
    assert_eq!(app.frames_seen(), 1);

    // A map that cannot be read: an error, and the frame shown stays.
    app.settings.env = Some(dir.path().join("missing.exr"));
    let t1 = Instant::now();
    while app.errors().is_empty() {
        assert!(
            t1.elapsed() < Duration::from_mins(1),
            "no error for a missing map"
        );
        h.frame(Vec::new(), |ui| app.frame(ui));
        std::thread::sleep(Duration::from_millis(16));
    }
    assert!(
        app.errors()[0].contains("missing.exr"),
        "{:?}",
        app.errors()
    );
    assert!(app.frame_complete() && app.frames_seen() == 1);
}
