//! The canvas: the image, the brush cursor and its footprint ellipse,
//! painting strokes with the pointer.

use std::sync::Arc;

use egui::{
    Color32, Event as UiEvent, Modifiers, PointerButton, Pos2, Rect, Sense, Shape, Stroke,
    TextureHandle, Vec2, pos2,
};
use ifd_planar::PixelRect;
use ifd_smooth::Orientation;

use crate::settings::range;
use crate::view::View;
use crate::worker::Command;

use super::{BrushApp, CANVAS_BG};

impl BrushApp {
    pub(super) fn canvas(&mut self, ui: &mut egui::Ui) {
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
