//! The egui application: canvas, panels, dialogs. Holds no image
//! processing: everything slow is a [`Command`] to the worker.

use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use egui::{
    Color32, ColorImage, Event as UiEvent, Key, Modifiers, PointerButton, Pos2, Rect, Sense, Shape,
    Stroke, TextureHandle, TextureOptions, Vec2, pos2, vec2,
};
use ifd_image::{Image, MemoryBudget};
use ifd_planar::PixelRect;
use ifd_smooth::Orientation;
use serde::{Deserialize, Serialize};

use crate::browser::{FileBrowser, Purpose};
use crate::display;
use crate::engine::{BankInfo, GpuChoice, SharedSmoother};
use crate::settings::{BrushMode, BrushSettings, range};
use crate::strokes::StrokesFile;
use crate::view::View;
use crate::worker::{self, Command, Event, Worker};

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
    pub gpu: GpuChoice,
    /// The window's wgpu renderer (eframe's), when it has one: on the GPU
    /// path the document is painted on its device and shown from there.
    pub render_state: Option<WindowGpu>,
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
    Screenshot(u32),
    WaitShot,
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
    shot: Arc<Mutex<Option<Arc<ColorImage>>>>,
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
            shot: Arc::new(Mutex::new(None)),
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
    pub fn finish(&mut self) {
        let Some(p) = self.automation.record.clone() else {
            return;
        };
        self.send(Command::SaveRecording(p));
        let t0 = Instant::now();
        while t0.elapsed() < Duration::from_secs(5) {
            match self.worker.rx.recv_timeout(Duration::from_millis(100)) {
                Ok(Event::RecordingSaved(_))
                | Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => break,
                Ok(Event::Error(e)) => {
                    eprintln!("error: {e}");
                    break;
                }
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

    fn handle_events(&mut self, ctx: &egui::Context) {
        let mut budget = 64;
        while budget > 0 {
            budget -= 1;
            let Ok(ev) = self.worker.rx.try_recv() else {
                break;
            };
            match ev {
                Event::Progress { stage, fraction } => self.busy = Some((stage, fraction)),
                Event::Compute { label, note } => {
                    eprintln!(
                        "ifd-brush: compute: {label}{}",
                        note.as_deref()
                            .map(|n| format!(" ({n})"))
                            .unwrap_or_default()
                    );
                    self.compute = label;
                    self.compute_note = note;
                }
                Event::BanksReady(info) => {
                    self.bank = Some(info);
                }
                Event::Loaded {
                    image,
                    path,
                    float_source: _,
                    tiles,
                    device_tiles,
                    original,
                    smoother,
                } => {
                    self.free_device_tiles();
                    let device_tiles = self.register_device_tiles(device_tiles);
                    let rects = display::tile_rects(image.width(), image.height());
                    let opts = TILE_OPTIONS;
                    let tiles = tiles
                        .into_iter()
                        .enumerate()
                        .map(|(i, t)| ctx.load_texture(format!("tile-{i}"), t, opts))
                        .collect();
                    let original = original
                        .into_iter()
                        .enumerate()
                        .map(|(i, t)| ctx.load_texture(format!("orig-{i}"), t, opts))
                        .collect();
                    self.doc = Some(Doc {
                        image,
                        path,
                        rects,
                        tiles,
                        device_tiles,
                        original,
                        smoother,
                    });
                    self.ready = false;
                    self.fit_pending = true;
                    self.state = 0;
                    self.saved_state = 0;
                    self.max_frame_ms = 0.0;
                    self.show_original = false;
                }
                Event::Ready { took } => {
                    self.ready = true;
                    self.busy = None;
                    self.last_prefilter = Some(took);
                }
                Event::Painted { dab_times } => {
                    self.record_dab_times(&dab_times);
                }
                Event::Patch {
                    rect,
                    pixels,
                    tiles,
                    dab_times,
                } => {
                    if let Some(doc) = &mut self.doc {
                        crate::history::paste(&mut doc.image, rect, &pixels);
                        for p in tiles {
                            if let Some(t) = doc.tiles.get_mut(p.tile) {
                                // The same options, or egui switches the
                                // tile to linear magnification.
                                t.set_partial(p.pos, p.image, TILE_OPTIONS);
                            }
                        }
                    }
                    self.record_dab_times(&dab_times);
                }
                Event::History { undo, redo, state } => {
                    self.undo_len = undo;
                    self.redo_len = redo;
                    self.state = state;
                }
                Event::Refreshed { took } => self.last_refresh = Some(took),
                Event::Saved { path, state } => {
                    self.busy = None;
                    self.saved_state = state;
                    self.status = format!("saved {}", path.display());
                    if let Some(doc) = &mut self.doc {
                        doc.path = Some(path);
                    }
                    if self.stage == Stage::Saving {
                        self.stage = Stage::Screenshot(0);
                    }
                    if self.quit_after_save && !self.is_dirty() {
                        self.allow_close = true;
                        ctx.send_viewport_cmd(egui::ViewportCommand::Close);
                    }
                }
                Event::ReplayDone { dabs } => {
                    self.status = format!("replayed {dabs} dabs");
                    if self.stage == Stage::Replaying {
                        self.stage = Stage::Saving;
                        if let Some(p) = self.automation.save.clone() {
                            self.send(Command::Save(p));
                        } else {
                            self.stage = Stage::Screenshot(0);
                        }
                        if let Some(p) = self.automation.record.clone() {
                            self.send(Command::SaveRecording(p));
                        }
                    }
                }
                Event::RecordingSaved(p) => {
                    self.status = format!("strokes written to {}", p.display());
                }
                Event::Error(msg) => {
                    self.busy = None;
                    self.quit_after_save = false;
                    if self.stage != Stage::Done {
                        if self.automation.exit {
                            self.fail(ctx, msg.clone());
                        } else {
                            eprintln!("error: {msg}");
                        }
                    }
                    self.errors.push(msg);
                }
            }
        }
        if budget == 0 {
            ctx.request_repaint();
        }
    }

    /// Stops an automated run: the message goes to `main` (through
    /// [`Automation::failure`]), which reports it and exits with status 2
    /// once the window has closed.
    fn fail(&mut self, ctx: &egui::Context, msg: String) {
        if let Ok(mut slot) = self.automation.failure.lock() {
            slot.get_or_insert(msg);
        }
        self.stage = Stage::Done;
        self.allow_close = true;
        ctx.send_viewport_cmd(egui::ViewportCommand::Close);
    }

    fn automation_step(&mut self, ctx: &egui::Context) {
        match self.stage {
            Stage::WaitReady if self.ready => {
                if let Some(f) = self.automation.replay.take() {
                    self.stage = Stage::Replaying;
                    self.send(Command::Replay(f));
                } else if let Some(p) = self.automation.save.clone() {
                    self.stage = Stage::Saving;
                    self.send(Command::Save(p));
                } else {
                    self.stage = Stage::Screenshot(0);
                }
            }
            Stage::Screenshot(n) => {
                if self.automation.screenshot.is_none() {
                    self.stage = Stage::Done;
                    if self.automation.exit {
                        self.allow_close = true;
                        ctx.send_viewport_cmd(egui::ViewportCommand::Close);
                    }
                } else if n < 5 {
                    // Let a few frames settle (fit, textures uploaded).
                    self.stage = Stage::Screenshot(n + 1);
                    ctx.request_repaint();
                } else {
                    let slot = Arc::clone(&self.shot);
                    let c2 = ctx.clone();
                    ctx.request_screenshot(move |img| {
                        if let Ok(mut s) = slot.lock() {
                            *s = Some(img);
                        }
                        c2.request_repaint();
                    });
                    self.stage = Stage::WaitShot;
                }
            }
            Stage::WaitShot => {
                let img = self.shot.lock().ok().and_then(|mut s| s.take());
                if let Some(img) = img {
                    if let Some(p) = &self.automation.screenshot {
                        if let Err(e) = write_screenshot(p, &img) {
                            self.fail(ctx, format!("writing the screenshot: {e:#}"));
                            return;
                        }
                        eprintln!("screenshot written to {}", p.display());
                    }
                    self.stage = Stage::Done;
                    if self.automation.exit {
                        self.allow_close = true;
                        ctx.send_viewport_cmd(egui::ViewportCommand::Close);
                    }
                } else {
                    ctx.request_repaint_after(Duration::from_millis(20));
                }
            }
            _ => {}
        }
    }

    fn request_open(&mut self, path: PathBuf) {
        if self.is_dirty() {
            self.pending = Some(Pending::Open(path));
        } else {
            self.open_now(path);
        }
    }

    fn open_now(&mut self, path: PathBuf) {
        if let Some(d) = path.parent() {
            self.settings.last_dir = Some(d.to_path_buf());
        }
        self.send(Command::EndStroke);
        self.stroking = false;
        self.send(Command::Open(path, self.settings.brush));
    }

    fn browse(&mut self, purpose: Purpose) {
        let dir = self
            .settings
            .last_dir
            .clone()
            .filter(|d| d.is_dir())
            .or_else(|| std::env::current_dir().ok())
            .unwrap_or_else(|| PathBuf::from("/"));
        let name = match purpose {
            Purpose::Open => String::new(),
            Purpose::Save => self
                .doc
                .as_ref()
                .and_then(|d| d.path.as_ref())
                .and_then(|p| p.file_stem())
                .map_or_else(
                    || "smoothed".into(),
                    |s| format!("{}-smoothed", s.to_string_lossy()),
                ),
        };
        self.browser = Some(FileBrowser::new(purpose, dir, name));
    }

    fn shortcuts(&mut self, ctx: &egui::Context) {
        if ctx.egui_wants_keyboard_input() {
            return;
        }
        let cmd_shift = Modifiers::COMMAND | Modifiers::SHIFT;
        // `consume_key` ignores an extra Shift, so Ctrl+Shift+Z is taken first.
        let (redo, redo2, undo, open, save, fit, one, before, bigger, smaller) =
            ctx.input_mut(|i| {
                (
                    i.consume_key(cmd_shift, Key::Z),
                    i.consume_key(Modifiers::COMMAND, Key::Y),
                    i.consume_key(Modifiers::COMMAND, Key::Z),
                    i.consume_key(Modifiers::COMMAND, Key::O),
                    i.consume_key(Modifiers::COMMAND, Key::S),
                    i.consume_key(Modifiers::NONE, Key::F),
                    i.consume_key(Modifiers::NONE, Key::Num1),
                    i.consume_key(Modifiers::NONE, Key::B),
                    i.consume_key(Modifiers::NONE, Key::CloseBracket),
                    i.consume_key(Modifiers::NONE, Key::OpenBracket),
                )
            });
        if redo || redo2 {
            self.send(Command::Redo);
        } else if undo {
            self.send(Command::Undo);
        }
        if open {
            self.browse(Purpose::Open);
        }
        if save {
            self.browse(Purpose::Save);
        }
        if fit {
            self.fit_pending = true;
        }
        if one {
            self.view.zoom = 1.0;
        }
        if before {
            self.show_original = !self.show_original;
        }
        if bigger || smaller {
            let f = if bigger { 1.25 } else { 0.8 };
            self.set_scale(self.settings.brush.scale * f);
        }
    }

    fn set_scale(&mut self, s: f64) {
        self.settings.brush.scale = s.clamp(range::SCALE.0, range::SCALE.1);
        self.send(Command::Prepare(self.settings.brush));
    }

    fn controls(&mut self, ui: &mut egui::Ui) {
        ui.heading("ifd brush");
        ui.horizontal(|ui| {
            if ui.button("Open…").clicked() {
                self.browse(Purpose::Open);
            }
            if ui
                .add_enabled(self.doc.is_some(), egui::Button::new("Save as…"))
                .clicked()
            {
                self.browse(Purpose::Save);
            }
        });
        ui.horizontal(|ui| {
            if ui
                .add_enabled(self.undo_len > 0, egui::Button::new("Undo"))
                .clicked()
            {
                self.send(Command::Undo);
            }
            if ui
                .add_enabled(self.redo_len > 0, egui::Button::new("Redo"))
                .clicked()
            {
                self.send(Command::Redo);
            }
            ui.toggle_value(&mut self.show_original, "Before (B)");
        });
        ui.horizontal(|ui| {
            if ui.button("Fit (F)").clicked() {
                self.fit_pending = true;
            }
            if ui.button("1:1").clicked() {
                self.view.zoom = 1.0;
            }
        });
        ui.separator();
        ui.label("Brush");
        let b = &mut self.settings.brush;
        ui.add(
            egui::Slider::new(&mut b.radius, range::RADIUS.0..=range::RADIUS.1)
                .logarithmic(true)
                .text("radius px"),
        );
        ui.add(egui::Slider::new(&mut b.strength, 0.0..=1.0).text("strength"));
        ui.add(egui::Slider::new(&mut b.falloff, 0.0..=1.0).text("falloff"));
        ui.add(
            egui::Slider::new(&mut b.spacing, range::SPACING.0..=range::SPACING.1)
                .text("spacing × r"),
        );
        let old = (b.scale, b.max_aspect);
        let r1 = ui.add(
            egui::Slider::new(&mut b.scale, range::SCALE.0..=range::SCALE.1)
                .logarithmic(true)
                .text("footprint S px"),
        );
        let r2 = ui.add(
            egui::Slider::new(&mut b.max_aspect, range::MAX_ASPECT.0..=range::MAX_ASPECT.1)
                .text("max anisotropy"),
        );
        ui.horizontal(|ui| {
            ui.label("mode");
            ui.radio_value(&mut b.mode, BrushMode::Dab, "dab");
            ui.radio_value(&mut b.mode, BrushMode::PerPixel, "per pixel");
        });
        let brush = *b;
        // Rebuild the stack once the slider is let go.
        let released = !(r1.dragged() || r2.dragged());
        if released
            && (old != (brush.scale, brush.max_aspect) || r1.drag_stopped() || r2.drag_stopped())
        {
            self.send(Command::Prepare(brush));
        }
        ui.checkbox(&mut self.settings.show_ellipse, "show filter ellipse");
        ui.small("Shift+wheel: radius · [ ]: footprint S · wheel: zoom · right/middle drag: pan");
        ui.separator();
        self.decomposition_panel(ui);
        ui.separator();
        self.timing_panel(ui);
    }

    fn decomposition_panel(&self, ui: &mut egui::Ui) {
        ui.label("Decomposition");
        let Some(info) = &self.bank else {
            ui.label("fitting…");
            return;
        };
        let used = self.orientation.map(|(o, _)| o);
        let n = info.aspects.len();
        let (idx, t) = used.map_or((None, 0.0), |o| {
            let (i, t) = locate(&info.aspects, f64::from(o.aspect));
            (Some(i), t)
        });
        egui::Grid::new("bank").striped(true).show(ui, |ui| {
            ui.label("aspect");
            ui.label("terms");
            ui.label("error");
            ui.end_row();
            for i in 0..n {
                let w = match idx {
                    Some(j) if j == i => 1.0 - t,
                    Some(j) if j + 1 == i => t,
                    _ => 0.0,
                };
                let txt = |s: String| {
                    if w > 0.0 {
                        egui::RichText::new(s).strong().color(Color32::LIGHT_GREEN)
                    } else {
                        egui::RichText::new(s)
                    }
                };
                ui.label(txt(format!("{:.2}", info.aspects[i])));
                ui.label(txt(info.terms[i].to_string()));
                ui.label(txt(format!("{:.2}%", 100.0 * info.errors[i])));
                ui.end_row();
            }
        });
        if let (Some(o), Some(idx)) = (used, idx) {
            let terms = if t > 0.0 && idx + 1 < n {
                info.terms[idx] + info.terms[idx + 1]
            } else {
                info.terms[idx.min(n - 1)]
            };
            ui.label(format!(
                "at cursor: aspect {:.2}, θ {:.0}°, {terms} terms",
                o.aspect, o.theta
            ));
        }
        ui.label(format!(
            "Hessian: xx {} + xy {} terms; bank: {}",
            info.hessian_terms[0], info.hessian_terms[1], info.source
        ));
    }

    fn timing_panel(&self, ui: &mut egui::Ui) {
        ui.label("Dab times (ms)");
        let (rect, _) =
            ui.allocate_exact_size(vec2(ui.available_width().min(260.0), 80.0), Sense::hover());
        let p = ui.painter_at(rect);
        p.rect_filled(rect, 2.0, Color32::from_gray(25));
        let max = self.dab_times.iter().copied().fold(20.0f32, f32::max);
        let y_of = |ms: f32| rect.bottom() - rect.height() * (ms / max).min(1.0);
        p.line_segment(
            [
                pos2(rect.left(), y_of(16.0)),
                pos2(rect.right(), y_of(16.0)),
            ],
            Stroke::new(1.0, Color32::from_rgb(160, 60, 60)),
        );
        let n = self.dab_times.len();
        if n > 1 {
            let pts: Vec<Pos2> = self
                .dab_times
                .iter()
                .enumerate()
                .map(|(i, &ms)| {
                    pos2(
                        rect.left() + rect.width() * i as f32 / (n - 1) as f32,
                        y_of(ms),
                    )
                })
                .collect();
            p.add(Shape::line(pts, Stroke::new(1.0, Color32::LIGHT_BLUE)));
        }
        let last = self.dab_times.back().copied().unwrap_or(0.0);
        let mean = if n > 0 {
            self.dab_times.iter().sum::<f32>() / n as f32
        } else {
            0.0
        };
        ui.small(format!(
            "last {last:.1} · mean {mean:.1} · red line 16 ms · scale to {max:.0}"
        ));
        if let Some(r) = self.last_refresh {
            ui.small(format!(
                "stack refresh after stroke: {:.1} ms",
                r.as_secs_f32() * 1e3
            ));
        }
        if let Some(r) = self.last_prefilter {
            ui.small(format!("prefiltering: {:.2} s", r.as_secs_f32()));
        }
        ui.small(format!(
            "longest UI frame since load: {:.1} ms",
            self.max_frame_ms
        ));
    }

    fn status_bar(&self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            let r = ui.label(format!("{} ·", self.compute));
            if let Some(n) = &self.compute_note {
                r.on_hover_text(n);
            }
            if let Some(doc) = &self.doc {
                let im = &doc.image;
                ui.label(format!("{}×{}×{}", im.width(), im.height(), im.channels()));
                ui.label(format!("zoom {:.0}%", self.view.zoom * 100.0));
                if let Some(c) = self.cursor {
                    let (x, y) = (c.x.round(), c.y.round());
                    if x >= 0.0
                        && y >= 0.0
                        && (x as usize) < im.width()
                        && (y as usize) < im.height()
                    {
                        let (x, y) = (x as usize, y as usize);
                        let v: Vec<String> = (0..im.channels())
                            .map(|k| format!("{:.4}", im.get(x, y, k)))
                            .collect();
                        ui.label(format!("({x}, {y}) = [{}]", v.join(", ")));
                    }
                }
                if let Some(p) = &doc.path {
                    ui.label(p.display().to_string());
                }
                if self.is_dirty() {
                    ui.label("● unsaved");
                }
                if self.show_original {
                    ui.colored_label(Color32::YELLOW, "showing BEFORE");
                }
            }
            if let Some((stage, f)) = &self.busy {
                ui.spinner();
                match f {
                    Some(f) => ui.label(format!("{stage} ({:.0}%)", f * 100.0)),
                    None => ui.label(stage.as_str()),
                };
                if !self.ready && self.doc.is_some() {
                    ui.label("— strokes are queued until prefiltering ends");
                }
            }
            if !self.status.is_empty() {
                ui.label(&self.status);
            }
        });
    }

    fn canvas(&mut self, ui: &mut egui::Ui) {
        let (rect, resp) = ui.allocate_exact_size(ui.available_size(), Sense::click_and_drag());
        let painter = ui.painter_at(rect);
        painter.rect_filled(rect, 0.0, CANVAS_BG);
        let Some(doc) = self.doc.as_ref() else {
            painter.text(
                rect.center(),
                egui::Align2::CENTER_CENTER,
                "drop an image here or open one",
                egui::FontId::proportional(18.0),
                Color32::GRAY,
            );
            return;
        };
        let (w, h) = (doc.image.width(), doc.image.height());
        if self.fit_pending && rect.width() > 1.0 {
            self.view = View::fit(w, h, rect);
            self.fit_pending = false;
        }
        let cpu_tiles = |t: &[TextureHandle]| -> Vec<(PixelRect, egui::TextureId)> {
            doc.rects
                .iter()
                .copied()
                .zip(t.iter().map(TextureHandle::id))
                .collect()
        };
        let tiles = if self.show_original {
            cpu_tiles(&doc.original)
        } else if doc.device_tiles.is_empty() {
            cpu_tiles(&doc.tiles)
        } else {
            doc.device_tiles.clone()
        };
        let uv = Rect::from_min_max(Pos2::ZERO, pos2(1.0, 1.0));
        for (r, t) in &tiles {
            let sr = self.view.pixel_rect(rect, r.x0, r.y0, r.width, r.height);
            if sr.intersects(rect) {
                painter.image(*t, sr, uv, Color32::WHITE);
            }
        }
        let smoother = Arc::clone(&doc.smoother);
        // Input: wheel (zoom; Shift: radius; Ctrl: footprint scale), pan, paint.
        let hover = resp.hover_pos();
        let mut wheel = 0.0f32;
        let mut mods = Modifiers::NONE;
        if hover.is_some() {
            ui.input(|i| {
                for e in &i.events {
                    if let UiEvent::MouseWheel {
                        delta, modifiers, ..
                    } = e
                    {
                        let d = if delta.y == 0.0 { delta.x } else { delta.y };
                        wheel += d.signum();
                        mods = *modifiers;
                    }
                }
            });
        }
        if wheel != 0.0 {
            let f = 1.15f32.powf(wheel);
            if mods.shift {
                let b = &mut self.settings.brush;
                b.radius = (b.radius * f).clamp(range::RADIUS.0, range::RADIUS.1);
            } else if mods.command || mods.alt {
                self.set_scale(self.settings.brush.scale * f64::from(f));
            } else if let Some(p) = hover {
                self.view.zoom_at(rect, p, f);
            }
        }
        if resp.dragged_by(PointerButton::Secondary) || resp.dragged_by(PointerButton::Middle) {
            self.view.pan(resp.drag_delta());
        }
        self.cursor = hover.map(|p| self.view.to_image(rect, p));
        let painting_allowed = !self.show_original;
        if resp.drag_started_by(PointerButton::Primary) && painting_allowed {
            if let Some(p) = resp.interact_pointer_pos() {
                let q = self.view.to_image(rect, p);
                self.send(Command::BeginStroke(self.settings.brush));
                self.send(Command::StrokeTo(q.x, q.y));
                self.stroking = true;
                self.last_stroke_pos = Some(q);
            }
        } else if self.stroking
            && resp.dragged_by(PointerButton::Primary)
            && let Some(p) = resp.interact_pointer_pos()
        {
            let q = self.view.to_image(rect, p);
            if self.last_stroke_pos != Some(q) {
                self.send(Command::StrokeTo(q.x, q.y));
                self.last_stroke_pos = Some(q);
            }
        }
        if self.stroking && !resp.dragged_by(PointerButton::Primary) {
            self.send(Command::EndStroke);
            self.stroking = false;
        }
        if resp.clicked_by(PointerButton::Primary) && painting_allowed && !self.stroking {
            // A click is a one-dab stroke.
            if let Some(p) = resp.interact_pointer_pos() {
                let q = self.view.to_image(rect, p);
                self.send(Command::BeginStroke(self.settings.brush));
                self.send(Command::StrokeTo(q.x, q.y));
                self.send(Command::EndStroke);
            }
        }
        // Cursor: footprint and, live, the filter ellipse from the Hessian.
        self.orientation = None;
        if let (Some(p), Some(c)) = (hover, self.cursor) {
            let r = self.settings.brush.radius * self.view.zoom;
            painter.circle_stroke(p, r, Stroke::new(1.5, Color32::WHITE));
            painter.circle_stroke(p, r + 1.5, Stroke::new(1.0, Color32::BLACK));
            if let Ok(guard) = smoother.try_read()
                && let Some(sm) = guard.as_ref()
            {
                let o = sm.orientation_at(c.x, c.y);
                let s = sm.options().scale;
                self.orientation = Some((o, s));
            }
            if self.settings.show_ellipse
                && let Some((o, s)) = self.orientation
            {
                let pts = ellipse_points(p, o, s as f32 * self.view.zoom, 48);
                painter.add(Shape::closed_line(
                    pts,
                    Stroke::new(1.5, Color32::from_rgb(255, 170, 0)),
                ));
            }
        }
    }

    fn dialogs(&mut self, ctx: &egui::Context) {
        if let Some(msg) = self.errors.last().cloned()
            && self.stage == Stage::Done
        {
            let mut close = false;
            egui::Modal::new(egui::Id::unique("error-dialog")).show(ctx, |ui| {
                ui.heading("Cannot do that");
                ui.label(&msg);
                ui.label("Your image and its edits are unchanged.");
                if ui.button("OK").clicked() {
                    close = true;
                }
            });
            if close {
                self.dismiss_errors();
            }
        }
        if let Some(p) = self.pending.clone() {
            let mut answer = None;
            egui::Modal::new(egui::Id::unique("confirm-dialog")).show(ctx, |ui| {
                ui.heading("Unsaved edits");
                ui.label(match &p {
                    Pending::Quit => "The image has edits that are not saved. Quit anyway?",
                    Pending::Open(_) => {
                        "The image has edits that are not saved. Open another image anyway?"
                    }
                });
                ui.horizontal(|ui| {
                    if ui.button("Save…").clicked() {
                        answer = Some(Answer::Save);
                    }
                    if ui.button("Discard edits").clicked() {
                        answer = Some(Answer::Discard);
                    }
                    if ui.button("Cancel").clicked() {
                        answer = Some(Answer::Cancel);
                    }
                });
            });
            if let Some(a) = answer {
                self.answer(ctx, a);
            }
        }
        if let Some(b) = &mut self.browser {
            let title = match b.purpose {
                Purpose::Open => "Open image",
                Purpose::Save => "Save image",
            };
            let mut chosen = None;
            egui::Window::new(title)
                .collapsible(false)
                .default_width(460.0)
                .show(ctx, |ui| chosen = b.show(ui));
            if let Some(c) = chosen {
                let purpose = b.purpose;
                self.settings.last_dir = Some(b.dir.clone());
                self.browser = None;
                match (purpose, c) {
                    (Purpose::Open, Some(p)) => self.request_open(p),
                    (Purpose::Save, Some(p)) => self.send(Command::Save(p)),
                    (_, None) => self.quit_after_save = false,
                }
            }
        }
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

/// Index and blend weight of aspect ratio `a` in a log-spaced table (as
/// `AspectBank::locate`).
fn locate(aspects: &[f64], a: f64) -> (usize, f64) {
    let n = aspects.len();
    if n < 2 || !a.is_finite() || a <= 1.0 {
        return (0, 0.0);
    }
    let top = aspects[n - 1];
    let f = (a.min(top).ln() / (top.ln() / (n - 1) as f64)).clamp(0.0, (n - 1) as f64);
    let i = (f.floor() as usize).min(n - 2);
    (i, f - i as f64)
}

/// The 2-sigma contour of the anisotropic Gaussian `o` with footprint
/// `scale` (screen points), centred at `c`: semi-axes `2 S sqrt(a)` along
/// `theta` (counter-clockwise on screen) and `2 S / sqrt(a)` across.
#[must_use]
pub fn ellipse_points(c: Pos2, o: Orientation, scale: f32, n: usize) -> Vec<Pos2> {
    let a = o.aspect.max(1.0).sqrt();
    let (major, minor) = (2.0 * scale * a, 2.0 * scale / a);
    let th = o.theta.to_radians();
    let u = Vec2::new(th.cos(), -th.sin());
    let v = Vec2::new(th.sin(), th.cos());
    (0..n)
        .map(|k| {
            let t = std::f32::consts::TAU * k as f32 / n as f32;
            c + u * (major * t.cos()) + v * (minor * t.sin())
        })
        .collect()
}

/// Writes an egui screenshot as PNG.
///
/// # Errors
/// Write failures.
pub fn write_screenshot(path: &Path, img: &ColorImage) -> anyhow::Result<()> {
    let [w, h] = img.size;
    let data = img
        .pixels
        .iter()
        .flat_map(|c| [c.r(), c.g(), c.b()].map(|v| f32::from(v) / 255.0))
        .collect();
    let im = Image::from_vec(w, h, 3, data)?;
    ifd_image::write(path, &im)?;
    Ok(())
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
