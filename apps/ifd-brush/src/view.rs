//! Zoom and pan: the map between image pixels and screen points.
//!
//! Pixel `(x, y)` covers `[x - 0.5, x + 0.5] x [y - 0.5, y + 0.5]` in image
//! coordinates (centres at integers, as the smoothing library uses).

use egui::{Pos2, Rect, Vec2, pos2};

/// Smallest and largest zoom (screen points per image pixel).
pub const ZOOM_RANGE: (f32, f32) = (1.0 / 64.0, 64.0);

/// The view of the image in the canvas.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    /// Screen points per image pixel.
    pub zoom: f32,
    /// Image coordinate shown at the canvas centre.
    pub center: Pos2,
}

impl Default for View {
    fn default() -> Self {
        Self {
            zoom: 1.0,
            center: Pos2::ZERO,
        }
    }
}

impl View {
    /// The view that fits a `w x h` image in `canvas`.
    #[must_use]
    pub fn fit(w: usize, h: usize, canvas: Rect) -> Self {
        let z = (canvas.width() / w as f32).min(canvas.height() / h as f32);
        Self {
            zoom: z.clamp(ZOOM_RANGE.0, ZOOM_RANGE.1),
            center: pos2(w as f32 / 2.0 - 0.5, h as f32 / 2.0 - 0.5),
        }
    }

    /// Screen position of image coordinate `p`.
    #[must_use]
    pub fn to_screen(&self, canvas: Rect, p: Pos2) -> Pos2 {
        canvas.center() + (p - self.center) * self.zoom
    }

    /// Image coordinate under screen position `s`.
    #[must_use]
    pub fn to_image(&self, canvas: Rect, s: Pos2) -> Pos2 {
        self.center + (s - canvas.center()) / self.zoom
    }

    /// Screen rectangle of a `w x h` image region starting at pixel `(x0, y0)`.
    #[must_use]
    pub fn pixel_rect(&self, canvas: Rect, x0: usize, y0: usize, w: usize, h: usize) -> Rect {
        let a = self.to_screen(canvas, pos2(x0 as f32 - 0.5, y0 as f32 - 0.5));
        let b = self.to_screen(canvas, pos2((x0 + w) as f32 - 0.5, (y0 + h) as f32 - 0.5));
        Rect::from_min_max(a, b)
    }

    /// Zooms by `factor` keeping the image point under `anchor` (screen) fixed.
    pub fn zoom_at(&mut self, canvas: Rect, anchor: Pos2, factor: f32) {
        let p = self.to_image(canvas, anchor);
        self.zoom = (self.zoom * factor).clamp(ZOOM_RANGE.0, ZOOM_RANGE.1);
        self.center = p - (anchor - canvas.center()) / self.zoom;
    }

    /// Pans by a screen-space drag `delta`.
    pub fn pan(&mut self, delta: Vec2) {
        self.center -= delta / self.zoom;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_fit_and_anchor() {
        let canvas = Rect::from_min_size(pos2(10.0, 20.0), Vec2::new(400.0, 300.0));
        let mut v = View::fit(800, 300, canvas);
        assert!((v.zoom - 0.5).abs() < 1e-6);
        let r = v.pixel_rect(canvas, 0, 0, 800, 300);
        assert!((r.width() - 400.0).abs() < 1e-3 && r.center().distance(canvas.center()) < 1e-3);
        let s = pos2(123.0, 77.0);
        let p = v.to_image(canvas, s);
        assert!(v.to_screen(canvas, p).distance(s) < 1e-3);
        v.zoom_at(canvas, s, 3.0);
        assert!(v.to_image(canvas, s).distance(p) < 1e-3);
        v.pan(Vec2::new(30.0, 0.0));
        assert!((v.to_image(canvas, s).x - (p.x - 30.0 / v.zoom)).abs() < 1e-3);
    }
}
