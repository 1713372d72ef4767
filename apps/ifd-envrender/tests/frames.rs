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

use egui::{RawInput, Rect, pos2, vec2};
use ifd_envrender::app::{Automation, EnvApp, StartOptions};
use ifd_envrender::settings::Settings;
use ifd_gpu::DeviceChoice;
use ifd_image::Image;

fn frame(ctx: &egui::Context, app: &mut EnvApp) -> f32 {
    let screen = Rect::from_min_size(pos2(0.0, 0.0), vec2(1180.0, 760.0));
    let input = RawInput {
        screen_rect: Some(screen),
        ..RawInput::default()
    };
    let f0 = Instant::now();
    let mut out = ctx.run_ui(input, |ui| app.frame(ui));
    out.textures_delta.clear();
    drop(ctx.tessellate(out.shapes, out.pixels_per_point));
    f0.elapsed().as_secs_f32() * 1e3
}

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

    let ctx = egui::Context::default();
    let settings = Settings {
        env: Some(path),
        size: [320, 240],
        ..Settings::default()
    };
    let mut app = EnvApp::new(
        &ctx,
        settings,
        StartOptions {
            render_state: None,
            gpu: DeviceChoice::Cpu,
            automation: Automation::default(),
        },
    );
    let t0 = Instant::now();
    let mut times = Vec::new();
    while !app.frame_complete() {
        assert!(app.errors().is_empty(), "{:?}", app.errors());
        assert!(
            t0.elapsed() < Duration::from_mins(5),
            "no frame after 300 s"
        );
        times.push(frame(&ctx, &mut app));
        std::thread::sleep(Duration::from_millis(16));
    }
    let shown = t0.elapsed();
    let mut sorted = times.clone();
    sorted.sort_by(f32::total_cmp);
    let max = *sorted.last().expect("frames");
    let p99 = sorted[(sorted.len() * 99 / 100).min(sorted.len() - 1)];
    let median = sorted[sorted.len() / 2];
    eprintln!(
        "4096x2048 HDR map: first frame after {:.2} s; {} UI frames, median {median:.2} ms, \
         p99 {p99:.2} ms, max {max:.2} ms",
        shown.as_secs_f64(),
        times.len()
    );
    if max >= 50.0 {
        eprintln!("note: a UI frame took {max:.1} ms, above the 50 ms goal (not asserted)");
    }
    assert_eq!(app.frames_seen(), 1);

    // A map that cannot be read: an error, and the frame shown stays.
    app.settings.env = Some(dir.path().join("missing.exr"));
    let t1 = Instant::now();
    while app.errors().is_empty() {
        assert!(
            t1.elapsed() < Duration::from_mins(1),
            "no error for a missing map"
        );
        frame(&ctx, &mut app);
        std::thread::sleep(Duration::from_millis(16));
    }
    assert!(
        app.errors()[0].contains("missing.exr"),
        "{:?}",
        app.errors()
    );
    assert!(app.frame_complete() && app.frames_seen() == 1);
}
