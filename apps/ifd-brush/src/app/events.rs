//! The worker's events (progress, results, errors) turned into app state.

use crate::display;
use crate::worker::{Command, Event};

use super::{BrushApp, Doc, Stage, TILE_OPTIONS};

impl BrushApp {
    pub(super) fn handle_events(&mut self, ctx: &egui::Context) {
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
                        self.begin_finish();
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
                            self.begin_finish();
                        }
                        if let Some(p) = self.automation.record.clone() {
                            self.send(Command::SaveRecording(p));
                        }
                    }
                }
                Event::RecordingSaved(p) => {
                    self.status = format!("strokes written to {}", p.display());
                }
                Event::Recoverable { entries, journal } => {
                    self.recovery = Some((entries, journal));
                }
                Event::Recovered { entries } => {
                    self.status = if entries > 0 {
                        format!("recovered {entries} edits from the journal")
                    } else {
                        "the interrupted session's edits were discarded".into()
                    };
                }
                Event::JournalClosed => {}
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
}
