//! The views fit the window (issue 54): in the headless harness (no window,
//! no GPU), the app's views stay whole inside the central area beside the
//! panel, and the area inside the window, while the window is resized from
//! large to small and back, with one view and with a second beside it (the
//! Monte Carlo reference, as the split sum takes the same place); a view
//! that fits is shown pixel for pixel, one that does not is scaled down
//! with its aspect kept. The window test (`window.rs`) checks the same in a
//! real window for the README's command.

use ifd_app::{Headless, PixelRect};
use ifd_envrender::app::{Automation, EnvApp, StartOptions};
use ifd_envrender::settings::Settings;
use ifd_gpu::DeviceChoice;
use ifd_image::Image;

#[test]
fn views_stay_inside_the_window_as_it_is_resized() {
    let dir = tempfile::tempdir().expect("tempdir");
    // a small map and a cheap BRDF: the worker's frames are not the point
    let path = dir.path().join("sky.hdr");
    let sky = Image::from_vec(
        16,
        8,
        3,
        (0..16 * 8 * 3)
            .map(|i| 0.2 + (i % 7) as f32 * 0.1)
            .collect(),
    )
    .expect("image");
    ifd_image::write(&path, &sky).expect("write");
    let sizes = [
        [1180.0, 760.0], // the default window
        [1600.0, 1000.0],
        [900.0, 600.0],
        [640.0, 400.0],
        [520.0, 900.0],
        [2200.0, 1300.0],
        [1180.0, 760.0],
    ];
    for beside in [false, true] {
        let mut h = Headless::new(sizes[0]);
        let settings = Settings {
            env: Some(path.clone()),
            brdf: "lambert".into(),
            l_max: 2,
            size: [640, 480],
            reference: beside,
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
        for size in sizes {
            h.resize(size);
            for _ in 0..3 {
                h.frame(Vec::new(), |ui| app.frame(ui));
            }
            let layout = app.layout().expect("a layout after a frame");
            let window = PixelRect {
                x: 0,
                y: 0,
                width: size[0] as i64,
                height: size[1] as i64,
            };
            let area = PixelRect::from_points(layout.area, 1.0);
            assert!(window.contains(&area), "{size:?}: area {area:?}");
            assert!(
                area.x > 200,
                "{size:?}: the area {area:?} is not beside the panel"
            );
            assert_eq!(layout.views.len(), 1 + usize::from(beside), "{size:?}");
            let views: Vec<PixelRect> = (layout.views.iter())
                .map(|(_, r)| PixelRect::from_points(*r, 1.0))
                .collect();
            for v in &views {
                assert!(
                    area.contains(v),
                    "{size:?}: view {v:?} leaves the area {area:?} (window {window:?})"
                );
                assert!(
                    (v.width * 480 - v.height * 640).abs() <= 640,
                    "{size:?}: view {v:?} is not 4:3"
                );
            }
            if let [a, b] = &views[..] {
                let apart = a.x + a.width <= b.x || a.y + a.height <= b.y;
                assert!(apart, "{size:?}: the views {a:?} and {b:?} overlap");
                assert_eq!((a.width, a.height), (b.width, b.height));
            }
            // pixel for pixel where it fits, never larger
            let fits = if beside {
                (2 * 640 + 8 <= area.width && 480 <= area.height)
                    || (640 <= area.width && 2 * 480 + 8 <= area.height)
            } else {
                640 <= area.width && 480 <= area.height
            };
            let v = views[0];
            if fits {
                assert_eq!(
                    (v.width, v.height),
                    (640, 480),
                    "{size:?}: {v:?} in {area:?}"
                );
            } else {
                assert!(
                    v.width < 640 && v.width > 100,
                    "{size:?}: {v:?} in {area:?}"
                );
            }
            eprintln!(
                "window {}x{}, area {}x{}: {}",
                size[0],
                size[1],
                area.width,
                area.height,
                views
                    .iter()
                    .map(|v| format!("{}x{} at {},{}", v.width, v.height, v.x, v.y))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
        app.finish();
    }
}
