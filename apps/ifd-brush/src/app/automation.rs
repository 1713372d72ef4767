//! Runs without a person (`--replay`, `--save`, `--screenshot`, `--exit`):
//! the stages of an automated run, and how a failure reaches `main`.

use ifd_app::write_screenshot;
use std::sync::Arc;
use std::time::Duration;

use crate::worker::Command;

use super::{BrushApp, Stage};

impl BrushApp {
    /// Stops an automated run: the message goes to `main` (through
    /// [`Automation::failure`]), which reports it and exits with status 2
    /// once the window has closed.
    pub(super) fn fail(&mut self, ctx: &egui::Context, msg: String) {
        if let Ok(mut slot) = self.automation.failure.lock() {
            slot.get_or_insert(msg);
        }
        self.stage = Stage::Done;
        self.allow_close = true;
        ctx.send_viewport_cmd(egui::ViewportCommand::Close);
    }

    pub(super) fn automation_step(&mut self, ctx: &egui::Context) {
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
}
