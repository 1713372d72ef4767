//! Opening files (dialogs, drag and drop, the file browser) and the
//! questions the app asks (unsaved changes).

use std::path::PathBuf;

use crate::browser::{FileBrowser, Purpose};
use crate::worker::Command;

use super::{Answer, BrushApp, Pending, Stage};

impl BrushApp {
    pub(super) fn request_open(&mut self, path: PathBuf) {
        if self.is_dirty() {
            self.pending = Some(Pending::Open(path));
        } else {
            self.open_now(path);
        }
    }

    pub(super) fn open_now(&mut self, path: PathBuf) {
        if let Some(d) = path.parent() {
            self.settings.last_dir = Some(d.to_path_buf());
        }
        self.send(Command::EndStroke);
        self.stroking = false;
        self.send(Command::Open(path, self.settings.brush));
    }

    pub(super) fn browse(&mut self, purpose: Purpose) {
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

    pub(super) fn dialogs(&mut self, ctx: &egui::Context) {
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
        if let Some((entries, journal)) = self.recovery.clone() {
            let mut answer = None;
            egui::Modal::new(egui::Id::unique("recover-dialog")).show(ctx, |ui| {
                ui.heading("Recover edits?");
                ui.label(format!(
                    "An earlier session on this image ended without closing (a crash or a \
                     kill). Its journal holds {entries} edit{} (strokes, undos and redos), \
                     saved as they were painted.",
                    if entries == 1 { "" } else { "s" }
                ));
                ui.small(journal.display().to_string());
                ui.horizontal(|ui| {
                    if ui.button("Recover").clicked() {
                        answer = Some(true);
                    }
                    if ui.button("Discard").clicked() {
                        answer = Some(false);
                    }
                });
            });
            if let Some(a) = answer {
                self.answer_recovery(a);
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
}
