//! The UI's state logic driven through egui input events, without a window:
//! a stroke painted with the mouse, Ctrl+Z / Ctrl+Shift+Z, the question asked
//! before quitting or opening another image with unsaved edits, files
//! dropped on the window, the error dialog for files that cannot be
//! opened, and the recovery of a session that did not close.

mod common;

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use egui::{DroppedFile, Event, Key, Modifiers, PointerButton, RawInput, Rect, pos2, vec2};
use ifd_brush::app::{Answer, Automation, BrushApp, Persisted, StartOptions};
use ifd_image::{Image, MemoryBudget};

/// A file dropped on the window, as the windowing integration hands it over.
#[derive(Debug)]
struct Dropped(PathBuf);

impl DroppedFile for Dropped {
    fn path(&self) -> &Path {
        &self.0
    }

    fn bytes(&self) -> Result<Vec<u8>, String> {
        std::fs::read(&self.0).map_err(|e| e.to_string())
    }
}

fn frame(ctx: &egui::Context, app: &mut BrushApp, events: Vec<Event>, close: bool) {
    frame_with(ctx, app, events, close, Vec::new());
}

/// One frame with `path` dropped on the window.
fn drop_file(ctx: &egui::Context, app: &mut BrushApp, path: &Path) {
    let file: egui::DroppedFileHandle = Arc::new(Dropped(path.to_path_buf()));
    frame_with(ctx, app, Vec::new(), false, vec![file]);
}

fn frame_with(
    ctx: &egui::Context,
    app: &mut BrushApp,
    events: Vec<Event>,
    close: bool,
    dropped_files: Vec<egui::DroppedFileHandle>,
) {
    let mut input = RawInput {
        screen_rect: Some(Rect::from_min_size(pos2(0.0, 0.0), vec2(1280.0, 800.0))),
        events,
        dropped_files,
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

/// The app on `image` (CPU path), once its smoother is ready.
fn start(ctx: &egui::Context, image: PathBuf, budget: MemoryBudget) -> BrushApp {
    let mut app = BrushApp::new(
        ctx,
        Persisted::default(),
        StartOptions {
            image: Some(image),
            bank_cache: Some(common::bank_cache()),
            budget,
            automation: Automation::default(),
            gpu: ifd_gpu::DeviceChoice::Cpu,
            render_state: None,
            journal_dir: None,
        },
    );
    until(ctx, &mut app, "the smoother", BrushApp::is_ready);
    frame(ctx, &mut app, Vec::new(), false);
    assert!(!app.is_dirty());
    app
}

/// Paints one stroke with the mouse and waits until it is recorded; returns
/// the painted image.
fn paint_stroke(ctx: &egui::Context, app: &mut BrushApp) -> Image {
    let before = app.image().expect("image").clone();
    let undo_before = app.undo_redo().0;
    // A drag across the middle of the canvas (right of the controls panel).
    let (x0, y) = (650.0, 400.0);
    let press = |pressed| Event::PointerButton {
        pos: pos2(x0, y),
        button: PointerButton::Primary,
        pressed,
        modifiers: Modifiers::NONE,
    };
    frame(ctx, app, vec![Event::PointerMoved(pos2(x0, y))], false);
    frame(ctx, app, vec![press(true)], false);
    for k in 1..=20 {
        let p = pos2(x0 + 12.0 * k as f32, y + 3.0 * k as f32);
        frame(ctx, app, vec![Event::PointerMoved(p)], false);
    }
    let release = Event::PointerButton {
        pos: pos2(x0 + 240.0, y + 60.0),
        button: PointerButton::Primary,
        pressed: false,
        modifiers: Modifiers::NONE,
    };
    frame(ctx, app, vec![release], false);
    until(ctx, app, "the stroke", |a| {
        a.undo_redo() == (undo_before + 1, 0)
    });
    let painted = app.image().expect("image").clone();
    let changed = common::max_diff(&before, &painted);
    assert!(changed > 0.02, "the stroke changed nothing ({changed})");
    assert!(app.is_dirty());
    painted
}

#[test]
fn mouse_stroke_undo_redo_and_quit_question() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("in.png");
    ifd_image::write(&path, &common::crop(150, 100, 240, 200)).expect("write");
    let ctx = egui::Context::default();
    let mut app = start(&ctx, path, MemoryBudget::default_for_machine());
    let original = app.image().expect("image").clone();
    let painted = paint_stroke(&ctx, &mut app);

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

/// Waits for the error dialog and returns its message.
fn wait_for_error(ctx: &egui::Context, app: &mut BrushApp, what: &str) -> String {
    let t0 = Instant::now();
    while app.errors().is_empty() {
        assert!(
            t0.elapsed() < Duration::from_mins(2),
            "timed out waiting for the error about {what}"
        );
        frame(ctx, app, Vec::new(), false);
        std::thread::sleep(Duration::from_millis(10));
    }
    assert_eq!(app.errors().len(), 1, "{:?}", app.errors());
    app.errors()[0].clone()
}

#[test]
fn dropping_a_file_asks_about_unsaved_edits() {
    let dir = tempfile::tempdir().expect("tempdir");
    let first = dir.path().join("first.png");
    ifd_image::write(&first, &common::crop(150, 100, 240, 200)).expect("write");
    let other = dir.path().join("other.png");
    ifd_image::write(&other, &common::crop(0, 0, 160, 120)).expect("write");
    let ctx = egui::Context::default();
    let mut app = start(&ctx, first.clone(), MemoryBudget::default_for_machine());
    let painted = paint_stroke(&ctx, &mut app);

    // With edits, a drop asks first and changes nothing until answered.
    drop_file(&ctx, &mut app, &other);
    assert_eq!(app.asks_before_open(), Some(other.as_path()));
    assert!(!app.asks_before_quit());
    for _ in 0..20 {
        frame(&ctx, &mut app, Vec::new(), false);
    }
    assert_eq!(app.image().expect("image").data(), painted.data());
    // Cancel keeps the edits and the question goes away.
    app.answer(&ctx, Answer::Cancel);
    assert_eq!(app.asks_before_open(), None);
    frame(&ctx, &mut app, Vec::new(), false);
    assert!(app.is_dirty());
    assert_eq!(app.image().expect("image").data(), painted.data());
    assert_eq!(app.undo_redo(), (1, 0));

    // Discard opens the dropped file: a new document, nothing to undo.
    drop_file(&ctx, &mut app, &other);
    assert_eq!(app.asks_before_open(), Some(other.as_path()));
    app.answer(&ctx, Answer::Discard);
    until(&ctx, &mut app, "the dropped image", |a| {
        a.image()
            .is_some_and(|i| (i.width(), i.height()) == (160, 120))
    });
    until(&ctx, &mut app, "its smoother", BrushApp::is_ready);
    until(&ctx, &mut app, "its history", |a| a.undo_redo() == (0, 0));
    assert!(!app.is_dirty());

    // Without edits a drop opens at once, without a question.
    drop_file(&ctx, &mut app, &first);
    assert_eq!(app.asks_before_open(), None);
    until(&ctx, &mut app, "the first image again", |a| {
        a.image()
            .is_some_and(|i| (i.width(), i.height()) == (240, 200))
    });
    assert!(app.errors().is_empty(), "{:?}", app.errors());
}

#[test]
fn bad_files_show_the_reason_and_lose_no_edits() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("in.png");
    ifd_image::write(&path, &common::crop(150, 100, 240, 200)).expect("write");
    let garbage = dir.path().join("garbage.png");
    std::fs::write(&garbage, b"this is not a PNG file").expect("write");
    let mut nan = common::crop(0, 0, 32, 32);
    nan.set(5, 7, 0, f32::NAN);
    let nan_path = dir.path().join("nan.exr");
    let fixture = ifd_image::WriteOptions {
        allow_non_finite: true,
        ..ifd_image::WriteOptions::default()
    };
    ifd_image::write_image(&nan_path, &nan, &fixture).expect("write exr");
    // 3000x3000 RGB needs far more than the 64 MiB budget of this app.
    let big = dir.path().join("big.png");
    ifd_image::write(&big, &Image::new(3000, 3000, 3).expect("image")).expect("write");

    let ctx = egui::Context::default();
    let mut app = start(&ctx, path, MemoryBudget::bytes(64 << 20));
    let original = app.image().expect("image").clone();
    let painted = paint_stroke(&ctx, &mut app);

    for (file, reason) in [
        (&garbage, "cannot decode PNG"),
        // Gray EXR is stored as RGB: the NaN is in all three channels.
        (
            &nan_path,
            "3 non-finite (NaN or infinite) values, first at x=5, y=7",
        ),
        (&big, "more than the budget of 64.0 MiB"),
    ] {
        let name = file.file_name().expect("name").to_string_lossy();
        drop_file(&ctx, &mut app, file);
        // The edits are not saved: the app asks; the user discards them.
        assert_eq!(app.asks_before_open(), Some(file.as_path()), "{name}");
        app.answer(&ctx, Answer::Discard);
        let msg = wait_for_error(&ctx, &mut app, &name);
        assert!(
            msg.contains(&*name) && msg.contains(reason),
            "{name}: expected {reason:?} in {msg:?}"
        );
        // The open failed: the edited image, its history and the unsaved
        // state are all still there.
        for _ in 0..10 {
            frame(&ctx, &mut app, Vec::new(), false);
        }
        assert_eq!(app.image().expect("image").data(), painted.data(), "{name}");
        assert_eq!(app.undo_redo(), (1, 0), "{name}");
        assert!(app.is_dirty(), "{name}");
        assert!(app.is_ready(), "{name}");
        app.dismiss_errors();
    }

    // Undo still works on the kept document.
    frame(&ctx, &mut app, vec![key(Key::Z, Modifiers::COMMAND)], false);
    until(&ctx, &mut app, "undo", |a| a.undo_redo() == (0, 1));
    assert_eq!(app.image().expect("image").data(), original.data());
    assert!(!app.is_dirty());
}

/// Strokes are journaled as they are painted: a session that ends without
/// closing (the app dropped without `finish`, as a crash leaves it) is
/// offered at the next start on the same image; recovering gives the painted
/// image back with its undo history, and a normal close deletes the journal.
#[test]
fn an_unclosed_session_is_offered_for_recovery() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("in.png");
    ifd_image::write(&path, &common::crop(150, 100, 240, 200)).expect("write");
    let journal = dir.path().join("journal");
    let ctx = egui::Context::default();
    let open = |ctx: &egui::Context| {
        BrushApp::new(
            ctx,
            Persisted::default(),
            StartOptions {
                image: Some(path.clone()),
                bank_cache: Some(common::bank_cache()),
                budget: MemoryBudget::default_for_machine(),
                automation: Automation::default(),
                gpu: ifd_gpu::DeviceChoice::Cpu,
                render_state: None,
                journal_dir: Some(journal.clone()),
            },
        )
    };
    let mut app = open(&ctx);
    until(&ctx, &mut app, "the smoother", BrushApp::is_ready);
    assert_eq!(app.asks_to_recover(), None, "nothing to recover yet");
    let painted = paint_stroke(&ctx, &mut app);
    drop(app); // no finish(): the journal stays

    let ctx = egui::Context::default();
    let mut app = open(&ctx);
    until(&ctx, &mut app, "the recovery question", |a| {
        a.asks_to_recover().is_some()
    });
    assert_eq!(app.asks_to_recover(), Some(1));
    app.answer_recovery(true);
    until(&ctx, &mut app, "the recovered stroke", |a| {
        a.undo_redo() == (1, 0)
    });
    let got = app.image().expect("image");
    let d = common::max_diff(got, &painted);
    assert!(
        d <= 1e-6,
        "the recovered image differs from the painted one by {d}"
    );
    assert!(app.is_dirty(), "recovered edits are not saved");
    app.finish();
    let left = std::fs::read_dir(&journal).expect("journal folder").count();
    assert_eq!(left, 0, "a normal close deletes the journal");
}
