//! Images shown whole in the window: [`fit_views`] places one or more
//! equally sized views (an image and what is compared with it) inside an
//! area, side by side or stacked, scaled down (keeping their aspect) until
//! they fit; [`PixelRect`] is a rectangle in physical pixels, as the
//! automated runs report it.

use egui::{Rect, pos2, vec2};

/// A rectangle in physical pixels (the window's, as a screenshot has them).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PixelRect {
    /// Left edge.
    pub x: i64,
    /// Top edge.
    pub y: i64,
    /// Width.
    pub width: i64,
    /// Height.
    pub height: i64,
}

impl PixelRect {
    /// `rect` (points) in physical pixels, at `pixels_per_point`.
    #[must_use]
    pub fn from_points(rect: Rect, pixels_per_point: f32) -> Self {
        let p = |v: f32| (v * pixels_per_point).round() as i64;
        Self {
            x: p(rect.min.x),
            y: p(rect.min.y),
            width: p(rect.max.x) - p(rect.min.x),
            height: p(rect.max.y) - p(rect.min.y),
        }
    }

    /// Whether `other` lies wholly inside this rectangle.
    ///
    /// ```
    /// use ifd_app::PixelRect;
    /// let window = PixelRect { x: 0, y: 0, width: 100, height: 80 };
    /// assert!(window.contains(&PixelRect { x: 10, y: 0, width: 90, height: 80 }));
    /// assert!(!window.contains(&PixelRect { x: 10, y: 0, width: 91, height: 80 }));
    /// ```
    #[must_use]
    pub fn contains(&self, other: &Self) -> bool {
        other.x >= self.x
            && other.y >= self.y
            && other.x + other.width <= self.x + self.width
            && other.y + other.height <= self.y + self.height
    }
}

/// The rectangles (points) of `count` views of a `size` (pixels) image
/// inside `area` (points), `gap` points apart, from `area`'s top left.
///
/// The views are side by side or stacked, whichever shows them larger, and
/// share one scale: one image pixel per physical pixel when they fit (never
/// enlarged, so a view that fits is shown pixel for pixel), else the largest
/// that fits, keeping the aspect. Sizes and corners fall on whole physical
/// pixels. (Views keep at least a pixel a side: only an area too small for
/// that leaves them outside it.)
///
/// ```
/// use egui::{Rect, pos2};
/// // two 640x480 views beside a panel: stacked, at 0.7 of their size
/// let area = Rect::from_min_max(pos2(294.0, 8.0), pos2(1172.0, 700.0));
/// let r = ifd_app::fit_views(area, [640, 480], 2, 8.0, 1.0);
/// assert_eq!(r.len(), 2);
/// assert!(r.iter().all(|v| area.contains_rect(*v)));
/// assert!(r[1].min.y > r[0].max.y);
/// assert!((r[0].width() / r[0].height() - 640.0 / 480.0).abs() < 0.01);
/// // one small view: pixel for pixel
/// let r = ifd_app::fit_views(area, [200, 150], 1, 8.0, 1.0);
/// assert_eq!((r[0].width(), r[0].height()), (200.0, 150.0));
/// ```
#[must_use]
pub fn fit_views(
    area: Rect,
    size: [usize; 2],
    count: usize,
    gap: f32,
    pixels_per_point: f32,
) -> Vec<Rect> {
    let ppp = if pixels_per_point > 0.0 {
        pixels_per_point
    } else {
        1.0
    };
    let n = count.max(1) as f32;
    // everything in physical pixels from here
    let (iw, ih) = (size[0].max(1) as f32, size[1].max(1) as f32);
    // the area's whole pixels (a hair of rounding error forgiven)
    let (x0, y0) = (
        (area.min.x * ppp - 1e-3).ceil(),
        (area.min.y * ppp - 1e-3).ceil(),
    );
    let (x1, y1) = (
        (area.max.x * ppp + 1e-3).floor(),
        (area.max.y * ppp + 1e-3).floor(),
    );
    let (aw, ah) = (x1 - x0, y1 - y0);
    let g = (gap * ppp).round();
    let spare = g * (n - 1.0);
    let beside = ((aw - spare) / (n * iw)).min(ah / ih);
    let stacked = (aw / iw).min((ah - spare) / (n * ih));
    let across = beside >= stacked;
    let scale = beside.max(stacked).min(1.0);
    let (w, h) = if scale >= 1.0 {
        (iw, ih)
    } else {
        ((iw * scale).floor().max(1.0), (ih * scale).floor().max(1.0))
    };
    (0..count.max(1))
        .map(|i| {
            let i = i as f32;
            let (x, y) = if across {
                (x0 + i * (w + g), y0)
            } else {
                (x0, y0 + i * (h + g))
            };
            Rect::from_min_size(pos2(x, y) / ppp, vec2(w, h) / ppp)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every view inside the area, no two overlapping, the aspect kept
    /// within a pixel, pixel for pixel whenever that fits; over window
    /// sizes from tiny to large, one and two views, at two scale factors.
    #[test]
    fn views_fit_any_area_and_keep_their_aspect() {
        for ppp in [1.0f32, 1.5, 2.0] {
            for count in [1, 2] {
                for (w, h) in [(640, 480), (400, 300), (200, 150), (1024, 256), (64, 512)] {
                    for aw in (40..1600).step_by(37) {
                        for ah in (30..1000).step_by(41) {
                            let area = Rect::from_min_size(
                                pos2(286.0, 8.0),
                                vec2(aw as f32, ah as f32) / ppp,
                            );
                            let r = fit_views(area, [w, h], count, 8.0, ppp);
                            assert_eq!(r.len(), count);
                            let a = PixelRect::from_points(area, ppp);
                            for v in &r {
                                let p = PixelRect::from_points(*v, ppp);
                                assert!(
                                    a.contains(&p),
                                    "{p:?} outside {a:?} ({w}x{h} x{count}, ppp {ppp})"
                                );
                                let aspect = w as f32 / h as f32;
                                assert!(
                                    (p.width as f32 - aspect * p.height as f32).abs()
                                        <= aspect.max(1.0) + 1.0,
                                    "{p:?} is not {w}x{h}'s aspect"
                                );
                                assert!(p.width <= w as i64 && p.height <= h as i64);
                            }
                            if count == 2 {
                                assert!(!r[0].intersects(r[1]), "{r:?} overlap");
                            }
                            // the gap in physical pixels
                            let g = (8.0 * ppp).round() as i64;
                            let (n, w, h) = (count as i64, w as i64, h as i64);
                            let fits = (n * (w + g) - g <= a.width && h <= a.height)
                                || (w <= a.width && n * (h + g) - g <= a.height);
                            if fits {
                                let p = PixelRect::from_points(r[0], ppp);
                                assert_eq!((p.width, p.height), (w, h));
                            }
                        }
                    }
                }
            }
        }
    }
}
