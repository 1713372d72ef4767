//! The UI's state logic driven through egui input events, without a window:
//! a stroke painted with the mouse, Ctrl+Z / Ctrl+Shift+Z, and the question
//! asked before quitting with unsaved edits.

mod common;

use std::time::{Duration, Instant};

use egui::{Event, Key, Modifiers, PointerButton, RawInput, Rect, pos2, vec2};
use ifd_brush::app::{Automation, BrushApp, Persisted, StartOptions};
use ifd_image::MemoryBudget;

fn frame(ctx: &egui::Context, app: &mut BrushApp, events: Vec<Event>, close: bool) {
    let mut input = RawInput {
        screen_rect: Some(Rect::from_min_size(pos2(0.0, 0.0), vec2(1280.0, 800.0))),
        events,
        ..RawInput::default()
    };
    if close {
        input
            .viewports
            .entry(egui::ViewportId::ROOT)
            .or_default()
            .events
            .push(egui::ViewportEvent::Close);
    }
    let mut out = ctx.run_ui(input, |ui| app.frame(ui));
    out.textures_delta.clear();
}

fn until(ctx: &egui::Context, app: &mut BrushApp, what: &str, cond: impl Fn(&BrushApp) -> bool) {
    let t0 = Instant::now();
    while !cond(app) {
        assert!(app.errors().is_empty(), "{:?}", app.errors());
        assert!(
            t0.elapsed() < Duration::from_mins(2),
            "timed out waiting for {what}"
        );
        frame(ctx, app, Vec::new(), false);
        std::thread::sleep(Duration::from_millis(10));
    }
}

fn key(key: Key, modifiers: Modifiers) -> Event {
    Event::Key {
        key,
        physical_key: None,
        pressed: true,
        repeat: false,
        modifiers,
    }
}

#[test]
fn mouse_stroke_undo_redo_and_quit_question() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("in.png");
    ifd_image::write(&path, &common::crop(150, 100, 240, 200)).expect("write");
    let ctx = egui::Context::default();
    let mut app = BrushApp::new(
        &ctx,
        Persisted::default(),
        StartOptions {
            image: Some(path),
            bank_cache: Some(common::bank_cache()),
            budget: MemoryBudget::default_for_machine(),
            automation: Automation::default(),
            gpu: ifd_brush::engine::GpuChoice::Off,
        },
    );
    until(&ctx, &mut app, "the smoother", BrushApp::is_ready);
    frame(&ctx, &mut app, Vec::new(), false);
    let original = app.image().expect("image").clone();
    assert!(!app.is_dirty());

    // A drag across the middle of the canvas (right of the controls panel).
    let (x0, y) = (650.0, 400.0);
    let press = |pressed| Event::PointerButton {
        pos: pos2(x0, y),
        button: PointerButton::Primary,
        pressed,
        modifiers: Modifiers::NONE,
    };
    frame(
        &ctx,
        &mut app,
        vec![Event::PointerMoved(pos2(x0, y))],
        false,
    );
    frame(&ctx, &mut app, vec![press(true)], false);
    for k in 1..=20 {
        let p = pos2(x0 + 12.0 * k as f32, y + 3.0 * k as f32);
        frame(&ctx, &mut app, vec![Event::PointerMoved(p)], false);
    }
    let release = Event::PointerButton {
        pos: pos2(x0 + 240.0, y + 60.0),
        button: PointerButton::Primary,
        pressed: false,
        modifiers: Modifiers::NONE,
    };
    frame(&ctx, &mut app, vec![release], false);
    until(&ctx, &mut app, "the stroke", |a| a.undo_redo() == (1, 0));
    let painted = app.image().expect("image").clone();
    let changed = common::max_diff(&original, &painted);
    assert!(changed > 0.02, "the stroke changed nothing ({changed})");
    assert!(app.is_dirty());

    frame(&ctx, &mut app, vec![key(Key::Z, Modifiers::COMMAND)], false);
    until(&ctx, &mut app, "undo", |a| a.undo_redo() == (0, 1));
    assert_eq!(app.image().expect("image").data(), original.data());
    assert!(!app.is_dirty(), "back at the opened state");

    let redo = key(Key::Z, Modifiers::COMMAND | Modifiers::SHIFT);
    frame(&ctx, &mut app, vec![redo], false);
    until(&ctx, &mut app, "redo", |a| a.undo_redo() == (1, 0));
    assert_eq!(app.image().expect("image").data(), painted.data());

    // Closing with unsaved edits asks first.
    assert!(!app.asks_before_quit());
    frame(&ctx, &mut app, Vec::new(), true);
    assert!(app.asks_before_quit());
}
