//! The end of an automated run that both apps share (`--screenshot`,
//! `--exit`): let a few frames settle, take the window screenshot and write
//! it, then ask the window to close; or stop early with a failure that
//! `main` reports once the event loop has returned.
//!
//! An app runs its own stages first (the brush replays and saves, the
//! environment renderer waits for its frame and reference), then calls
//! [`Finish::start`] and [`Finish::step`] once per frame.

use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use egui::ColorImage;

use crate::write_screenshot;

/// Frames drawn before the screenshot is taken (fits laid out, textures
/// uploaded).
pub const SETTLE_FRAMES: u32 = 5;

/// Where the end of a run is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Stage {
    Idle,
    Settle(u32),
    WaitShot,
    Done,
}

/// What one [`Finish::step`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FinishStep {
    /// Not started, or still settling or waiting for the screenshot.
    Pending,
    /// Finished in this frame: the screenshot, when asked for, is written,
    /// and with `exit` the window was asked to close.
    Finished,
    /// The screenshot could not be written: the run failed (see
    /// [`Finish::fail`]) in this frame.
    Failed,
    /// Finished or failed in an earlier frame.
    Done,
}

/// The shared end of an automated run.
///
/// ```
/// use std::sync::{Arc, Mutex};
/// use ifd_app::{Finish, FinishStep};
/// let ctx = egui::Context::default();
/// let failure = Arc::new(Mutex::new(None));
/// // no screenshot, no exit: finishes as soon as it starts
/// let mut f = Finish::new(None, false, Arc::clone(&failure));
/// assert_eq!(f.step(&ctx), FinishStep::Pending);
/// f.start();
/// assert_eq!(f.step(&ctx), FinishStep::Finished);
/// assert_eq!(f.step(&ctx), FinishStep::Done);
/// assert!(f.is_done() && failure.lock().unwrap().is_none());
/// ```
#[derive(Debug)]
pub struct Finish {
    screenshot: Option<PathBuf>,
    exit: bool,
    failure: Arc<Mutex<Option<String>>>,
    shot: Arc<Mutex<Option<Arc<ColorImage>>>>,
    stage: Stage,
}

impl Finish {
    /// The end of a run that writes a screenshot to `screenshot` (if any),
    /// closes the window when `exit`, and leaves a failure's message in
    /// `failure` for `main`.
    #[must_use]
    pub fn new(
        screenshot: Option<PathBuf>,
        exit: bool,
        failure: Arc<Mutex<Option<String>>>,
    ) -> Self {
        Self {
            screenshot,
            exit,
            failure,
            shot: Arc::new(Mutex::new(None)),
            stage: Stage::Idle,
        }
    }

    /// Whether the run closes the window when done.
    #[must_use]
    pub fn exits(&self) -> bool {
        self.exit
    }

    /// Whether the run has finished or failed.
    #[must_use]
    pub fn is_done(&self) -> bool {
        self.stage == Stage::Done
    }

    /// Begins the end of the run (the app's own stages are over); a second
    /// call changes nothing.
    pub fn start(&mut self) {
        if self.stage == Stage::Idle {
            self.stage = Stage::Settle(0);
        }
    }

    /// Stops the run: the message goes to `main` (the first one is kept),
    /// which reports it and exits with status 2 once the window has closed.
    /// The app never exits the process itself.
    pub fn fail(&mut self, ctx: &egui::Context, msg: String) {
        if let Ok(mut slot) = self.failure.lock() {
            slot.get_or_insert(msg);
        }
        self.stage = Stage::Done;
        ctx.send_viewport_cmd(egui::ViewportCommand::Close);
    }

    /// Advances the end of the run by one frame.
    pub fn step(&mut self, ctx: &egui::Context) -> FinishStep {
        match self.stage {
            Stage::Idle => FinishStep::Pending,
            Stage::Done => FinishStep::Done,
            Stage::Settle(_) if self.screenshot.is_none() => self.finish(ctx),
            Stage::Settle(n) if n < SETTLE_FRAMES => {
                self.stage = Stage::Settle(n + 1);
                ctx.request_repaint();
                FinishStep::Pending
            }
            Stage::Settle(_) => {
                let slot = Arc::clone(&self.shot);
                let c2 = ctx.clone();
                ctx.request_screenshot(move |img| {
                    if let Ok(mut s) = slot.lock() {
                        *s = Some(img);
                    }
                    c2.request_repaint();
                });
                self.stage = Stage::WaitShot;
                FinishStep::Pending
            }
            Stage::WaitShot => {
                let img = self.shot.lock().ok().and_then(|mut s| s.take());
                let Some(img) = img else {
                    ctx.request_repaint_after(Duration::from_millis(20));
                    return FinishStep::Pending;
                };
                if let Some(p) = &self.screenshot {
                    if let Err(e) = write_screenshot(p, &img) {
                        self.fail(ctx, format!("writing the screenshot: {e:#}"));
                        return FinishStep::Failed;
                    }
                    eprintln!("screenshot written to {}", p.display());
                }
                self.finish(ctx)
            }
        }
    }

    fn finish(&mut self, ctx: &egui::Context) -> FinishStep {
        self.stage = Stage::Done;
        if self.exit {
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
        }
        FinishStep::Finished
    }
}
