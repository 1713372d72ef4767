//! The side panels and the status bar: brush controls, the decomposition
//! and timing panels, keyboard shortcuts.

use egui::{Color32, Key, Modifiers, Pos2, Sense, Shape, Stroke, pos2, vec2};

use crate::browser::Purpose;
use crate::settings::{BrushMode, range};
use crate::worker::Command;

use super::BrushApp;

impl BrushApp {
    pub(super) fn shortcuts(&mut self, ctx: &egui::Context) {
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

    pub(super) fn set_scale(&mut self, s: f64) {
        self.settings.brush.scale = s.clamp(range::SCALE.0, range::SCALE.1);
        self.send(Command::Prepare(self.settings.brush));
    }

    pub(super) fn controls(&mut self, ui: &mut egui::Ui) {
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

    pub(super) fn decomposition_panel(&self, ui: &mut egui::Ui) {
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

    pub(super) fn timing_panel(&self, ui: &mut egui::Ui) {
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

    pub(super) fn status_bar(&self, ui: &mut egui::Ui) {
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
