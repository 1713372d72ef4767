//! The worker thread: owns the [`Engine`], runs every slow step (fitting,
//! decoding, prefiltering, dabs, stack refreshes, saving) and reports to the
//! UI through events, so the UI thread never waits on any of them.
//!
//! Commands are handled in order. While the smoother is being built (after
//! an image opens, or when the footprint scale or anisotropy changes),
//! stroke commands wait in the channel and are applied as soon as it is
//! ready ("queue dabs until ready"): the image is shown and can be painted
//! on at once; the result appears when prefiltering is done.

use std::path::PathBuf;
use std::sync::mpsc::{Receiver, Sender, TryRecvError, channel};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use egui::ColorImage;
use ifd_image::{Image, MemoryBudget};
use ifd_planar::PixelRect;

use crate::display::{self, TilePatch};
use crate::engine::{BankInfo, Banks, Engine, SharedDevice, SharedSmoother};
use crate::history::extract;
use crate::settings::BrushSettings;
use crate::strokes::StrokesFile;
use ifd_gpu::DeviceChoice;

/// What the UI asks the worker to do.
#[derive(Clone, Debug)]
pub enum Command {
    /// Read an image file and make it the document.
    Open(PathBuf, BrushSettings),
    /// Make this image the document (e.g. the generated fallback).
    SetImage(Image, Option<PathBuf>, BrushSettings),
    /// Build the smoother for these settings now (not at the next stroke).
    Prepare(BrushSettings),
    /// Start a stroke.
    BeginStroke(BrushSettings),
    /// Pointer position during a stroke, image pixels.
    StrokeTo(f32, f32),
    /// End the stroke.
    EndStroke,
    /// Undo the latest stroke.
    Undo,
    /// Redo.
    Redo,
    /// Save the image.
    Save(PathBuf),
    /// Replay strokes.
    Replay(StrokesFile),
    /// Start recording strokes.
    StartRecording,
    /// Write the recording.
    SaveRecording(PathBuf),
    /// Apply (`true`) or discard the journal an interrupted session left
    /// ([`Event::Recoverable`]), and start this session's journal.
    Recover(bool),
    /// The app closes normally: delete the journal (nothing to recover).
    CloseJournal,
}

/// What the worker reports.
#[derive(Debug)]
pub enum Event {
    /// A slow step started or progressed (`fraction` when known).
    Progress {
        /// What is being done.
        stage: String,
        /// Done fraction, when known.
        fraction: Option<f32>,
    },
    /// The decompositions are ready.
    BanksReady(BankInfo),
    /// The evaluation path in use ("CPU" or "GPU: adapter"), and why the GPU
    /// is not used when it is not.
    Compute {
        /// Shown in the status bar.
        label: String,
        /// Why not the GPU.
        note: Option<String>,
    },
    /// A new document: its pixels and display tiles (current and original).
    Loaded {
        /// The samples.
        image: Image,
        /// The file.
        path: Option<PathBuf>,
        /// From a float file (display through sRGB).
        float_source: bool,
        /// Display tiles, [`display::tile_rects`] order (empty when the
        /// document is shown from the device: `device_tiles`).
        tiles: Vec<ColorImage>,
        /// The document's display textures on the renderer's device, kept
        /// up to date there by the dabs ([`Engine::display_tiles`]).
        device_tiles: Option<Vec<(PixelRect, eframe::wgpu::Texture)>>,
        /// The same, kept for the before/after toggle.
        original: Vec<ColorImage>,
        /// The smoother (for the cursor's filter ellipse).
        smoother: SharedSmoother,
    },
    /// The smoother is ready.
    Ready {
        /// Time spent prefiltering.
        took: Duration,
    },
    /// Dabs were painted and shown on the device (the display path of
    /// [`Engine::displays_on_device`]); the pixels follow in a
    /// [`Event::Patch`] when the stroke ends.
    Painted {
        /// Time of each dab applied.
        dab_times: Vec<Duration>,
    },
    /// Pixels changed.
    Patch {
        /// Where.
        rect: PixelRect,
        /// The new samples of `rect`.
        pixels: Vec<f32>,
        /// Display updates (none when the display is on the device).
        tiles: Vec<TilePatch>,
        /// Time of each dab applied (empty for undo/redo).
        dab_times: Vec<Duration>,
    },
    /// Undo state after an edit, undo or redo.
    History {
        /// Edits that can be undone.
        undo: usize,
        /// Edits that can be redone.
        redo: usize,
        /// Id of the current state ([`crate::history::History::current_id`]).
        state: u64,
    },
    /// A stroke ended and the stack was refreshed.
    Refreshed {
        /// How long the refresh took.
        took: Duration,
    },
    /// The image was saved in this state.
    Saved {
        /// Where.
        path: PathBuf,
        /// State id saved.
        state: u64,
    },
    /// A replay finished.
    ReplayDone {
        /// Dabs applied.
        dabs: usize,
    },
    /// The recording was written.
    RecordingSaved(PathBuf),
    /// The opened image has a journal of an interrupted session: ask whether
    /// to recover it (answer with [`Command::Recover`]; nothing is journaled
    /// until then).
    Recoverable {
        /// Strokes, undos and redos in the journal.
        entries: usize,
        /// The journal file.
        journal: PathBuf,
    },
    /// The journal was recovered or discarded.
    Recovered {
        /// Entries applied (0 when discarded).
        entries: usize,
    },
    /// The journal was closed ([`Command::CloseJournal`]).
    JournalClosed,
    /// Something failed; the document is unchanged.
    Error(String),
}

/// The UI's handle on the worker.
pub struct Worker {
    /// Commands.
    pub tx: Sender<Command>,
    /// Events.
    pub rx: Receiver<Event>,
    /// The thread (joined on drop of the app, never waited on by the UI).
    pub handle: Option<JoinHandle<()>>,
}

/// Starts the worker: fits or loads the decompositions, then serves commands.
/// `wake` is called after every event (the UI's repaint request).
#[must_use]
///
/// `shared` is the window's device: on the GPU path the document is then
/// painted and shown there ([`Engine::enable_gpu_on`]).
pub fn spawn(
    bank_cache: Option<PathBuf>,
    journal_dir: Option<PathBuf>,
    budget: MemoryBudget,
    gpu: DeviceChoice,
    shared: Option<SharedDevice>,
    wake: impl Fn() + Send + 'static,
) -> Worker {
    let (tx, crx) = channel::<Command>();
    let (etx, rx) = channel::<Event>();
    let handle = std::thread::Builder::new()
        .name("ifd-brush worker".into())
        .spawn(move || {
            let send = |e: Event| {
                // The UI may be gone (closing): nothing left to tell.
                if etx.send(e).is_ok() {
                    wake();
                }
            };
            send(Event::Progress {
                stage: "fitting decompositions".into(),
                fraction: Some(0.0),
            });
            let banks = match Banks::load_or_build(bank_cache.as_deref(), |d, n| {
                send(Event::Progress {
                    stage: format!("fitting decompositions {d}/{n}"),
                    fraction: Some(d as f32 / n as f32),
                });
            }) {
                Ok(b) => b,
                Err(e) => {
                    send(Event::Error(format!("{e:#}")));
                    return;
                }
            };
            send(Event::BanksReady(banks.info.clone()));
            let mut engine = Engine::new(banks, budget);
            engine.set_journal_dir(journal_dir, false);
            let announce = |(label, note): (String, Option<String>)| {
                send(Event::Compute { label, note });
            };
            let mut compute = engine.enable_gpu_on(gpu, shared);
            announce(compute.clone());
            let mut pending: Option<Command> = None;
            loop {
                let cmd = match pending.take() {
                    Some(c) => c,
                    None => match crx.recv() {
                        Ok(c) => c,
                        // The UI is gone without closing the journal (it
                        // crashed): keep it for recovery.
                        Err(_) => return,
                    },
                };
                pending = serve(&mut engine, cmd, &crx, &send);
                // The GPU path can give way to the CPU (a smoother beyond
                // the device's limits) and come back.
                if engine.compute() != compute {
                    compute = engine.compute();
                    announce(compute.clone());
                }
            }
        })
        .ok();
    Worker { tx, rx, handle }
}

fn history_event(engine: &Engine) -> Event {
    let h = engine.history();
    Event::History {
        undo: h.undo_len(),
        redo: h.redo_len(),
        state: h.current_id(),
    }
}

fn patch_event(engine: &Engine, rect: PixelRect, dab_times: Vec<Duration>) -> Option<Event> {
    let image = engine.image()?;
    Some(Event::Patch {
        rect,
        pixels: extract(image, rect),
        tiles: if engine.displays_on_device() {
            Vec::new()
        } else {
            display::tile_patches(image, rect, engine.float_source())
        },
        dab_times,
    })
}

/// After a replay or a recovery: the whole image, when the history moved
/// from `before`, and the undo state.
fn send_if_changed(engine: &Engine, before: u64, send: &impl Fn(Event)) {
    if before != engine.history().current_id()
        && let Some(img) = engine.image()
    {
        let all = PixelRect {
            x0: 0,
            y0: 0,
            width: img.width(),
            height: img.height(),
        };
        if let Some(ev) = patch_event(engine, all, Vec::new()) {
            send(ev);
        }
    }
    send(history_event(engine));
}

/// After a stroke ended on the GPU display path: its pixels, for the UI's
/// copy of the image (the screen shows them already; on the CPU path the
/// dabs' patches carried them).
fn send_stroke_pixels(engine: &Engine, rect: PixelRect, send: &impl Fn(Event)) {
    if engine.displays_on_device()
        && let Some(ev) = patch_event(engine, rect, Vec::new())
    {
        send(ev);
    }
}

fn prepare(engine: &mut Engine, brush: &BrushSettings, send: &impl Fn(Event)) {
    if engine.image().is_none() {
        return;
    }
    send(Event::Progress {
        stage: "prefiltering".into(),
        fraction: None,
    });
    let t0 = Instant::now();
    match engine.prepare(brush) {
        Ok(_) => send(Event::Ready { took: t0.elapsed() }),
        Err(e) => send(Event::Error(format!("{e:#}"))),
    }
}

fn loaded(engine: &mut Engine, image: Image, path: Option<PathBuf>, float: bool) -> Event {
    let rects = display::tile_rects(image.width(), image.height());
    let original: Vec<ColorImage> = rects
        .iter()
        .map(|&r| display::color_image(&image, r, float))
        .collect();
    let copy = image.clone();
    engine.set_image(image, path.clone(), float);
    let device_tiles = engine.display_tiles();
    Event::Loaded {
        image: copy,
        path,
        float_source: float,
        tiles: if device_tiles.is_some() {
            Vec::new()
        } else {
            original.clone()
        },
        device_tiles,
        original,
        smoother: engine.shared_smoother(),
    }
}

/// Handles one command; returns a command it read ahead and did not handle.
fn serve(
    engine: &mut Engine,
    cmd: Command,
    crx: &Receiver<Command>,
    send: &impl Fn(Event),
) -> Option<Command> {
    let fail = |e: anyhow::Error| send(Event::Error(format!("{e:#}")));
    match cmd {
        Command::Open(path, brush) => {
            send(Event::Progress {
                stage: format!("reading {}", path.display()),
                fraction: None,
            });
            match engine.read(&path, &brush) {
                Ok(l) => {
                    let float = l.integer_bits.is_none();
                    send(loaded(engine, l.image, Some(path), float));
                    send(history_event(engine));
                    if let Some(r) = engine.recoverable() {
                        send(Event::Recoverable {
                            entries: r.strokes.strokes.len(),
                            journal: r.path.clone(),
                        });
                    }
                    prepare(engine, &brush, send);
                }
                Err(e) => fail(e),
            }
        }
        Command::SetImage(image, path, brush) => match engine.check_fits(&image, &brush) {
            Ok(()) => {
                send(loaded(engine, image, path, false));
                send(history_event(engine));
                prepare(engine, &brush, send);
            }
            Err(e) => fail(e),
        },
        Command::Prepare(brush) => {
            if engine.image().is_some() {
                prepare(engine, &brush, send);
            }
        }
        Command::BeginStroke(brush) => {
            if engine.image().is_some() {
                let needs_build = !engine.is_ready()
                    || engine
                        .shared_smoother()
                        .read()
                        .ok()
                        .and_then(|s| s.as_ref().map(|s| *s.options() != brush.smooth_options()))
                        .unwrap_or(true);
                if needs_build {
                    prepare(engine, &brush, send);
                }
                if let Err(e) = engine.begin_stroke(brush) {
                    fail(e);
                }
            }
        }
        Command::StrokeTo(x, y) => {
            // Coalesce the pointer positions already queued into one update.
            let mut rect: Option<PixelRect> = None;
            let mut times = Vec::new();
            let mut next = Some(Command::StrokeTo(x, y));
            let mut ahead = None;
            while let Some(c) = next.take() {
                if let Command::StrokeTo(x, y) = c {
                    // Without a stroke (no image, or starting it failed and
                    // was reported) the movement is ignored.
                    if let Ok(b) = engine.stroke_to(x, y) {
                        times.extend(b.times);
                        if let Some(r) = b.rect {
                            rect = Some(rect.map_or(r, |a| a.union(r)));
                        }
                    }
                    if times.len() < 64 {
                        match crx.try_recv() {
                            Ok(c) => next = Some(c),
                            Err(TryRecvError::Empty | TryRecvError::Disconnected) => {}
                        }
                    }
                } else {
                    ahead = Some(c);
                }
            }
            if engine.displays_on_device() {
                if rect.is_some() {
                    send(Event::Painted { dab_times: times });
                }
            } else if let Some(r) = rect
                && let Some(ev) = patch_event(engine, r, times)
            {
                send(ev);
            }
            return ahead;
        }
        Command::EndStroke => {
            let t0 = Instant::now();
            match engine.end_stroke() {
                Ok(Some(rect)) => {
                    send(Event::Refreshed { took: t0.elapsed() });
                    send_stroke_pixels(engine, rect, send);
                    send(history_event(engine));
                }
                Ok(None) => {}
                Err(e) => fail(e),
            }
        }
        Command::Undo | Command::Redo => {
            let r = if matches!(cmd, Command::Undo) {
                engine.undo()
            } else {
                engine.redo()
            };
            match r {
                Ok(Some(rect)) => {
                    if let Some(ev) = patch_event(engine, rect, Vec::new()) {
                        send(ev);
                    }
                    send(history_event(engine));
                }
                Ok(None) => {}
                Err(e) => fail(e),
            }
        }
        Command::Save(path) => {
            // A stroke in progress belongs to the saved image.
            match engine.end_stroke() {
                Ok(Some(rect)) => send_stroke_pixels(engine, rect, send),
                Ok(None) => {}
                Err(e) => fail(e),
            }
            send(history_event(engine));
            send(Event::Progress {
                stage: format!("saving {}", path.display()),
                fraction: None,
            });
            match engine.save(&path) {
                Ok(()) => send(Event::Saved {
                    path,
                    state: engine.history().current_id(),
                }),
                Err(e) => fail(e),
            }
        }
        Command::Replay(file) => {
            let before = engine.history().current_id();
            match engine.replay(&file) {
                Ok(dabs) => {
                    send_if_changed(engine, before, send);
                    send(Event::ReplayDone { dabs });
                }
                Err(e) => fail(e),
            }
        }
        Command::StartRecording => engine.start_recording(),
        Command::Recover(apply) => {
            let entries = engine.recoverable().map_or(0, |r| r.strokes.strokes.len());
            let before = engine.history().current_id();
            match engine.resolve_recovery(apply) {
                Ok(_) => {
                    send_if_changed(engine, before, send);
                    send(Event::Recovered {
                        entries: if apply { entries } else { 0 },
                    });
                }
                Err(e) => fail(e),
            }
        }
        Command::CloseJournal => {
            if let Err(e) = engine.end_stroke() {
                fail(e);
            }
            engine.close_journal();
            send(Event::JournalClosed);
        }
        Command::SaveRecording(path) => {
            if let Err(e) = engine.end_stroke() {
                fail(e);
            }
            match engine.recording().map(|r| r.save(&path)) {
                Some(Ok(())) => send(Event::RecordingSaved(path)),
                Some(Err(e)) => fail(e),
                None => fail(anyhow::anyhow!("not recording")),
            }
        }
    }
    None
}
