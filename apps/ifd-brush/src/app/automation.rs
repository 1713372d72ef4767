//! Runs without a person (`--replay`, `--save`, `--screenshot`, `--exit`):
//! the brush's own stages (wait until ready, replay, save), then the end
//! that both apps share ([`ifd_app::Finish`]: settle, screenshot, exit).

use ifd_app::FinishStep;

use crate::worker::Command;

use super::{BrushApp, Stage};

impl BrushApp {
    /// Stops an automated run: the message goes to `main` (through
    /// [`super::Automation::failure`]), which reports it and exits with
    /// status 2 once the window has closed.
    pub(super) fn fail(&mut self, ctx: &egui::Context, msg: String) {
        self.stage = Stage::Done;
        self.allow_close = true;
        self.finish.fail(ctx, msg);
    }

    /// The brush's stages are over: the shared end of the run begins.
    pub(super) fn begin_finish(&mut self) {
        self.stage = Stage::Finishing;
        self.finish.start();
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
                    self.begin_finish();
                }
            }
            Stage::Finishing => match self.finish.step(ctx) {
                FinishStep::Pending => {}
                FinishStep::Finished | FinishStep::Done => {
                    self.stage = Stage::Done;
                    if self.finish.exits() {
                        self.allow_close = true;
                    }
                }
                FinishStep::Failed => {
                    self.stage = Stage::Done;
                    self.allow_close = true;
                }
            },
            _ => {}
        }
    }
}
