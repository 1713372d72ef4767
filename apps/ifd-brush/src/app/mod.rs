//! The egui application: its state, start-up and frame; the canvas, panels,
//! dialogs, worker events and automated runs are its submodules. Holds no image
//! processing: everything slow is a [`Command`] to the worker.

mod automation;
mod canvas;
mod dialogs;
mod events;
mod panels;

pub use canvas::ellipse_points;

use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use egui::{Color32, Pos2, TextureHandle, TextureOptions};
use ifd_image::{Image, MemoryBudget};
use ifd_planar::PixelRect;
use ifd_smooth::Orientation;
use serde::{Deserialize, Serialize};

use crate::browser::{FileBrowser, Purpose};
use crate::engine::{BankInfo, SharedSmoother};
use crate::settings::BrushSettings;
use crate::strokes::StrokesFile;
use crate::view::View;
use crate::worker::{self, Command, Event, Worker};
use ifd_app::Finish;
use ifd_gpu::DeviceChoice;

/// Storage key of the persisted settings.
pub const STORAGE_KEY: &str = "ifd-brush-settings";

/// Settings kept between runs (eframe storage).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Persisted {
    /// The brush.
    pub brush: BrushSettings,
    /// Folder the file browser opens in.
    pub last_dir: Option<PathBuf>,
    /// Draw the Hessian filter's ellipse at the cursor.
    pub show_ellipse: bool,
}

impl Default for Persisted {
    fn default() -> Self {
        Self {
            brush: BrushSettings::default(),
            last_dir: None,
            show_ellipse: true,
        }
    }
}

/// What to do without a person: replay, save, screenshot, exit.
#[derive(Clone, Debug, Default)]
pub struct Automation {
    /// Strokes to replay once the smoother is ready.
    pub replay: Option<StrokesFile>,
    /// Save the image here after the replay.
    pub save: Option<PathBuf>,
    /// Write the recorded strokes here on exit (and after the replay).
    pub record: Option<PathBuf>,
    /// Take a screenshot of the window (PNG) once everything is shown.
    pub screenshot: Option<PathBuf>,
    /// Close when done.
    pub exit: bool,
    /// Where an automated run that must stop (an error under `exit`, a
    /// screenshot that cannot be written) leaves its message before closing
    /// the window: `main` reads it once the event loop has returned and
    /// exits with status 2. The app never exits the process itself.
    pub failure: Arc<Mutex<Option<String>>>,
}

/// How the app starts.
#[derive(Clone, Debug)]
pub struct StartOptions {
    /// The image to open (`None`: the bundled one).
    pub image: Option<PathBuf>,
    /// The aspect-bank cache.
    pub bank_cache: Option<PathBuf>,
    /// The memory budget for images.
    pub budget: MemoryBudget,
    /// Unattended steps.
    pub automation: Automation,
    /// Whether dabs may run on the GPU.
    pub gpu: DeviceChoice,
    /// The window's wgpu renderer (eframe's), when it has one: on the GPU
    /// path the document is painted on its device and shown from there.
    pub render_state: Option<WindowGpu>,
    /// Where edits are journaled as they are painted ([`crate::journal`]);
    /// `None`: not journaled.
    pub journal_dir: Option<PathBuf>,
}

/// The window's wgpu renderer (eframe's `RenderState`).
#[derive(Clone)]
pub struct WindowGpu(pub eframe::egui_wgpu::RenderState);

impl std::fmt::Debug for WindowGpu {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let info = self.0.adapter.get_info();
        write!(f, "WindowGpu({}, {:?})", info.name, info.backend)
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Stage {
    WaitReady,
    Replaying,
    Saving,
    /// The shared end of the run ([`ifd_app::Finish`]).
    Finishing,
    Done,
}

/// An answer to the "unsaved edits" question (its three buttons).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Answer {
    /// Save first (opens the save browser), then go on.
    Save,
    /// Go on and lose the edits.
    Discard,
    /// Do nothing.
    Cancel,
}

/// A question waiting for an answer before something that would lose edits.
#[derive(Clone, Debug)]
enum Pending {
    Quit,
    Open(PathBuf),
}

struct Doc {
    image: Image,
    path: Option<PathBuf>,
    rects: Vec<PixelRect>,
    tiles: Vec<TextureHandle>,
    /// The document's textures on the renderer's device (registered with
    /// egui's renderer) and the pixels each shows, drawn instead of `tiles`
    /// when present.
    device_tiles: Vec<(PixelRect, egui::TextureId)>,
    original: Vec<TextureHandle>,
    smoother: SharedSmoother,
}

/// The application state.
#[expect(
    clippy::struct_excessive_bools,
    reason = "independent UI flags, not a state machine"
)]
pub struct BrushApp {
    /// Persisted settings.
    pub settings: Persisted,
    worker: Worker,
    doc: Option<Doc>,
    ready: bool,
    view: View,
    fit_pending: bool,
    busy: Option<(String, Option<f32>)>,
    bank: Option<BankInfo>,
    dab_times: VecDeque<f32>,
    last_refresh: Option<Duration>,
    last_prefilter: Option<Duration>,
    frame_ms: VecDeque<f32>,
    max_frame_ms: f32,
    undo_len: usize,
    redo_len: usize,
    state: u64,
    saved_state: u64,
    errors: Vec<String>,
    pending: Option<Pending>,
    /// An interrupted session's journal on the open image: (entries, file),
    /// asked about in a dialog.
    recovery: Option<(usize, PathBuf)>,
    browser: Option<FileBrowser>,
    show_original: bool,
    stroking: bool,
    last_stroke_pos: Option<Pos2>,
    orientation: Option<(Orientation, f64)>,
    cursor: Option<Pos2>,
    allow_close: bool,
    quit_after_save: bool,
    automation: Automation,
    render_state: Option<WindowGpu>,
    stage: Stage,
    finish: Finish,
    status: String,
    compute: String,
    compute_note: Option<String>,
}

/// The bundled image opened when none is given, `testdata/camera.png` (the
/// one the library tests use).
///
/// Looked for, in order: in the executable's folder and up to three folders
/// above it (an installed copy next to the binary, or a checkout's
/// `target/release/ifd-brush`), then in the current folder, and last at the
/// source checkout this binary was built from (a compile-time path, which a
/// moved or installed binary may no longer have). When none of them exists
/// that last path is returned, and opening it fails with a message naming it.
#[must_use]
pub fn bundled_image() -> PathBuf {
    let exe = std::env::current_exe().ok();
    let cwd = std::env::current_dir().ok();
    bundled_image_candidates(exe.as_deref(), cwd.as_deref())
        .into_iter()
        .find(|p| p.is_file())
        .unwrap_or_else(built_in_bundled_image)
}

/// `testdata/camera.png` of the checkout the binary was built from.
fn built_in_bundled_image() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../testdata/camera.png")
}

/// Where [`bundled_image`] looks, in order.
fn bundled_image_candidates(exe: Option<&Path>, cwd: Option<&Path>) -> Vec<PathBuf> {
    let rel = Path::new("testdata").join("camera.png");
    let mut out: Vec<PathBuf> = exe
        .and_then(Path::parent)
        .into_iter()
        .flat_map(|d| d.ancestors().take(4))
        .map(|d| d.join(&rel))
        .collect();
    out.extend(cwd.map(|d| d.join(&rel)));
    out.push(built_in_bundled_image());
    out
}

const CANVAS_BG: Color32 = Color32::from_gray(40);

/// Display tiles are magnified nearest (pixels stay visible when zoomed in)
/// and minified linear; the GPU path's textures use the same sampler.
const TILE_OPTIONS: TextureOptions = TextureOptions {
    magnification: egui::TextureFilter::Nearest,
    minification: egui::TextureFilter::Linear,
    wrap_mode: egui::TextureWrapMode::ClampToEdge,
    mipmap_mode: None,
};

impl BrushApp {
    /// Starts the worker and opens the start image. `settings` come from
    /// storage (or defaults).
    #[must_use]
    pub fn new(ctx: &egui::Context, settings: Persisted, start: StartOptions) -> Self {
        let wake_ctx = ctx.clone();
        let shared = start
            .render_state
            .as_ref()
            .map(|WindowGpu(rs)| crate::engine::SharedDevice {
                device: rs.device.clone(),
                queue: rs.queue.clone(),
                info: rs.adapter.get_info(),
            });
        let worker = worker::spawn(
            start.bank_cache.clone(),
            start.journal_dir.clone(),
            start.budget,
            start.gpu,
            shared,
            move || {
                wake_ctx.request_repaint();
            },
        );
        let brush = settings.brush.clamped();
        let path = start.image.clone().unwrap_or_else(bundled_image);
        let send = |c| {
            // The worker only stops when the app does.
            worker.tx.send(c).ok();
        };
        send(Command::Open(path, brush));
        if start.automation.record.is_some() {
            send(Command::StartRecording);
        }
        let stage = if start.automation.replay.is_some()
            || start.automation.save.is_some()
            || start.automation.screenshot.is_some()
            || start.automation.exit
        {
            Stage::WaitReady
        } else {
            Stage::Done
        };
        let finish = Finish::new(
            start.automation.screenshot.clone(),
            start.automation.exit,
            Arc::clone(&start.automation.failure),
        );
        Self {
            settings: Persisted { brush, ..settings },
            worker,
            doc: None,
            ready: false,
            view: View::default(),
            fit_pending: true,
            busy: Some(("starting".into(), None)),
            bank: None,
            dab_times: VecDeque::new(),
            last_refresh: None,
            last_prefilter: None,
            frame_ms: VecDeque::new(),
            max_frame_ms: 0.0,
            undo_len: 0,
            redo_len: 0,
            state: 0,
            saved_state: 0,
            errors: Vec::new(),
            pending: None,
            recovery: None,
            browser: None,
            show_original: false,
            stroking: false,
            last_stroke_pos: None,
            orientation: None,
            cursor: None,
            allow_close: false,
            quit_after_save: false,
            automation: start.automation,
            render_state: start.render_state,
            stage,
            finish,
            status: String::new(),
            compute: "CPU".into(),
            compute_note: None,
        }
    }

    fn send(&self, c: Command) {
        if self.worker.tx.send(c).is_err() {
            // The worker died (it reported why as its last event).
        }
    }

    /// Whether the image has edits that are not saved.
    #[must_use]
    pub fn is_dirty(&self) -> bool {
        self.state != self.saved_state
    }

    /// Whether the smoother is ready (prefiltering done).
    #[must_use]
    pub fn is_ready(&self) -> bool {
        self.ready
    }

    /// Whether an image is shown.
    #[must_use]
    pub fn has_image(&self) -> bool {
        self.doc.is_some()
    }

    /// Strokes that can be undone and redone, as the worker last reported.
    #[must_use]
    pub fn undo_redo(&self) -> (usize, usize) {
        (self.undo_len, self.redo_len)
    }

    /// The entries of an interrupted session's journal, while the "recover
    /// edits?" question is showing.
    #[must_use]
    pub fn asks_to_recover(&self) -> Option<usize> {
        self.recovery.as_ref().map(|(n, _)| *n)
    }

    /// Answers the "recover edits?" question (its Recover and Discard
    /// buttons).
    pub fn answer_recovery(&mut self, recover: bool) {
        if self.recovery.take().is_some() {
            self.send(Command::Recover(recover));
        }
    }

    /// Whether the "unsaved edits" question is showing for quitting.
    #[must_use]
    pub fn asks_before_quit(&self) -> bool {
        matches!(self.pending, Some(Pending::Quit))
    }

    /// The image whose opening waits for the "unsaved edits" question.
    #[must_use]
    pub fn asks_before_open(&self) -> Option<&Path> {
        match &self.pending {
            Some(Pending::Open(p)) => Some(p),
            _ => None,
        }
    }

    /// Answers the "unsaved edits" question as its buttons do; nothing
    /// happens when no question is showing.
    pub fn answer(&mut self, ctx: &egui::Context, answer: Answer) {
        let Some(p) = self.pending.take() else {
            return;
        };
        match answer {
            Answer::Save => {
                self.quit_after_save = matches!(p, Pending::Quit);
                self.browse(Purpose::Save);
            }
            Answer::Discard => match p {
                Pending::Quit => {
                    self.allow_close = true;
                    ctx.send_viewport_cmd(egui::ViewportCommand::Close);
                }
                Pending::Open(path) => self.open_now(path),
            },
            Answer::Cancel => {}
        }
    }

    /// Error messages shown so far (dialogs).
    #[must_use]
    pub fn errors(&self) -> &[String] {
        &self.errors
    }

    /// Closes the error dialog, as its OK button does.
    pub fn dismiss_errors(&mut self) {
        self.errors.clear();
    }

    /// The UI-thread durations of recent frames, milliseconds.
    #[must_use]
    pub fn frame_times_ms(&self) -> &VecDeque<f32> {
        &self.frame_ms
    }

    /// Registers the document's textures on the renderer's device with
    /// egui's renderer (magnified nearest, minified linear, as the CPU
    /// path's tiles); none without a renderer.
    fn register_device_tiles(
        &self,
        tiles: Option<Vec<(PixelRect, eframe::wgpu::Texture)>>,
    ) -> Vec<(PixelRect, egui::TextureId)> {
        let (Some(tiles), Some(WindowGpu(rs))) = (tiles, &self.render_state) else {
            return Vec::new();
        };
        let mut renderer = rs.renderer.write();
        tiles
            .iter()
            .map(|(r, t)| {
                let view = t.create_view(&eframe::wgpu::TextureViewDescriptor::default());
                let id = renderer.register_native_texture_with_sampler_options(
                    &rs.device,
                    &view,
                    eframe::wgpu::SamplerDescriptor {
                        label: Some("ifd-brush canvas"),
                        mag_filter: eframe::wgpu::FilterMode::Nearest,
                        min_filter: eframe::wgpu::FilterMode::Linear,
                        ..eframe::wgpu::SamplerDescriptor::default()
                    },
                );
                (*r, id)
            })
            .collect()
    }

    /// Frees the current document's device textures in egui's renderer.
    fn free_device_tiles(&mut self) {
        let (Some(doc), Some(WindowGpu(rs))) = (&mut self.doc, &self.render_state) else {
            return;
        };
        let mut renderer = rs.renderer.write();
        for (_, id) in doc.device_tiles.drain(..) {
            renderer.free_texture(&id);
        }
    }

    /// Keeps the times of the latest 240 dabs, in ms, for the plot.
    fn record_dab_times(&mut self, times: &[Duration]) {
        self.dab_times
            .extend(times.iter().map(|t| t.as_secs_f32() * 1e3));
        while self.dab_times.len() > 240 {
            self.dab_times.pop_front();
        }
    }

    /// The image as the UI holds it.
    #[must_use]
    pub fn image(&self) -> Option<&Image> {
        self.doc.as_ref().map(|d| &d.image)
    }

    /// Call when the app closes: writes the `--record` file (waits up to 5 s
    /// for the worker, which may be finishing a stroke).
    ///
    /// A normal close also deletes the edit journal: there is nothing to
    /// recover (unsaved edits were confirmed away by the quit dialog).
    pub fn finish(&mut self) {
        if let Some(p) = self.automation.record.clone() {
            self.send(Command::SaveRecording(p));
        }
        self.send(Command::CloseJournal);
        let t0 = Instant::now();
        while t0.elapsed() < Duration::from_secs(5) {
            match self.worker.rx.recv_timeout(Duration::from_millis(100)) {
                Ok(Event::JournalClosed) | Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => {
                    break;
                }
                Ok(Event::Error(e)) => eprintln!("error: {e}"),
                _ => {}
            }
        }
    }

    /// The evaluation path in use, as the status bar shows it.
    #[must_use]
    pub fn compute_path(&self) -> &str {
        &self.compute
    }

    /// Whether unattended steps are done.
    #[must_use]
    pub fn automation_done(&self) -> bool {
        self.stage == Stage::Done
    }

    /// One frame of the whole UI (the eframe `ui` callback and the headless
    /// test harness both call it).
    pub fn frame(&mut self, ui: &mut egui::Ui) {
        let t0 = Instant::now();
        let ctx = &ui.ctx().clone();
        self.handle_events(ctx);
        let dropped: Vec<PathBuf> = ctx.input(|i| {
            i.raw
                .dropped_files
                .iter()
                .map(|f| f.path().to_path_buf())
                .collect()
        });
        if let Some(p) = dropped.into_iter().next() {
            self.request_open(p);
        }
        if ctx.input(|i| i.viewport().close_requested()) && self.is_dirty() && !self.allow_close {
            ctx.send_viewport_cmd(egui::ViewportCommand::CancelClose);
            self.pending = Some(Pending::Quit);
        }
        self.shortcuts(ctx);
        egui::Panel::bottom("status").show(ui, |ui| self.status_bar(ui));
        egui::Panel::left("controls")
            .default_size(290.0)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| self.controls(ui));
            });
        egui::CentralPanel::default()
            .frame(egui::Frame::NONE)
            .show(ui, |ui| self.canvas(ui));
        self.dialogs(ctx);
        self.automation_step(ctx);
        if self.busy.is_some() {
            ctx.request_repaint_after(Duration::from_millis(100));
        }
        let ms = t0.elapsed().as_secs_f32() * 1e3;
        self.max_frame_ms = self.max_frame_ms.max(ms);
        self.frame_ms.push_back(ms);
        while self.frame_ms.len() > 600 {
            self.frame_ms.pop_front();
        }
    }
}

impl ifd_app::AppFrame for BrushApp {
    type Settings = Persisted;

    fn frame(&mut self, ui: &mut egui::Ui) {
        BrushApp::frame(self, ui);
    }

    fn settings(&self) -> &Persisted {
        &self.settings
    }

    fn finish(&mut self) {
        BrushApp::finish(self);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bundled_image_is_looked_for_next_to_the_binary_first() {
        let c = bundled_image_candidates(
            Some(Path::new("/opt/ifd/bin/ifd-brush")),
            Some(Path::new("/home/u")),
        );
        let want: Vec<PathBuf> = [
            "/opt/ifd/bin/testdata/camera.png",
            "/opt/ifd/testdata/camera.png",
            "/opt/testdata/camera.png",
            "/testdata/camera.png",
            "/home/u/testdata/camera.png",
        ]
        .iter()
        .map(PathBuf::from)
        .chain([built_in_bundled_image()])
        .collect();
        assert_eq!(c, want);
        // Without an executable or current folder only the built-in path is left.
        assert_eq!(
            bundled_image_candidates(None, None),
            [built_in_bundled_image()]
        );
        // From a test binary in target/debug/deps, the checkout's copy is found.
        assert!(bundled_image().is_file(), "{}", bundled_image().display());
    }
}
