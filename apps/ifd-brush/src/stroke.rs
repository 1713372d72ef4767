//! Stroke interpolation: pointer samples to evenly spaced dab centres, so
//! that fast mouse movement leaves no gaps.

/// Turns the pointer positions of one stroke into dab centres spaced
/// `spacing` pixels apart along the polyline through them (the first dab at
/// the first position; the distance left over at the end of a segment
/// carries into the next one, so the spacing does not depend on how the
/// pointer was sampled).
///
/// With bounds ([`StrokeInterpolator::with_bounds`]) only the centres inside
/// them are returned, the others skipped without being generated: a stroke
/// through a point far outside the image costs what its part near the image
/// costs. The centres returned are the same as without bounds.
#[derive(Clone, Debug)]
pub struct StrokeInterpolator {
    spacing: f64,
    last: Option<(f64, f64)>,
    /// Distance still to travel before the next dab.
    to_next: f64,
    /// `[x0, y0, x1, y1]`: centres outside are skipped.
    bounds: Option<[f64; 4]>,
}

impl StrokeInterpolator {
    /// A new stroke with dabs every `spacing` pixels (at least 0.25).
    #[must_use]
    pub fn new(spacing: f32) -> Self {
        Self {
            spacing: if spacing.is_finite() {
                f64::from(spacing.max(0.25))
            } else {
                1.0
            },
            last: None,
            to_next: 0.0,
            bounds: None,
        }
    }

    /// As [`StrokeInterpolator::new`], returning only the centres inside
    /// `[x0, x1] x [y0, y1]` (for a brush of radius `r` on a `w x h` image,
    /// `[-r - 1, w + r] x [-r - 1, h + r]` keeps every dab that can touch it).
    #[must_use]
    pub fn with_bounds(spacing: f32, bounds: [f32; 4]) -> Self {
        Self {
            bounds: Some(bounds.map(f64::from)),
            ..Self::new(spacing)
        }
    }

    fn inside(&self, x: f64, y: f64) -> bool {
        self.bounds
            .is_none_or(|[x0, y0, x1, y1]| x >= x0 && x <= x1 && y >= y0 && y <= y1)
    }

    /// The part `[a, b]` of `[0, len]` (distance along the segment from
    /// `(lx, ly)` in unit direction `(ux, uy)`) inside the bounds
    /// (Liang-Barsky); `None` when the segment misses them.
    fn clip(&self, (lx, ly): (f64, f64), (ux, uy): (f64, f64), len: f64) -> Option<(f64, f64)> {
        let Some([x0, y0, x1, y1]) = self.bounds else {
            return Some((0.0, len));
        };
        let (mut a, mut b) = (0.0f64, len);
        for (p, d, lo, hi) in [(lx, ux, x0, x1), (ly, uy, y0, y1)] {
            if d == 0.0 {
                if p < lo || p > hi {
                    return None;
                }
                continue;
            }
            let (t0, t1) = ((lo - p) / d, (hi - p) / d);
            a = a.max(t0.min(t1));
            b = b.min(t0.max(t1));
        }
        (a <= b).then_some((a, b))
    }

    /// The next pointer position; returns the dab centres it adds.
    /// Non-finite positions are ignored.
    pub fn push(&mut self, x: f32, y: f32) -> Vec<(f32, f32)> {
        if !(x.is_finite() && y.is_finite()) {
            return Vec::new();
        }
        let (x, y) = (f64::from(x), f64::from(y));
        let Some((lx, ly)) = self.last else {
            self.last = Some((x, y));
            self.to_next = self.spacing;
            return if self.inside(x, y) {
                vec![(x as f32, y as f32)]
            } else {
                Vec::new()
            };
        };
        let (dx, dy) = (x - lx, y - ly);
        let len = dx.hypot(dy);
        let mut out = Vec::new();
        let mut t = self.to_next;
        if len > 0.0 {
            let u = (dx / len, dy / len);
            if let Some((a, b)) = self.clip((lx, ly), u, len) {
                if t < a {
                    // Skip the centres before the bounds, on the same grid.
                    t += ((a - t) / self.spacing).ceil() * self.spacing;
                }
                while t <= len && t <= b {
                    let f = t / len;
                    let (cx, cy) = (lx + f * dx, ly + f * dy);
                    if self.inside(cx, cy) {
                        out.push((cx as f32, cy as f32));
                    }
                    t += self.spacing;
                }
            }
            if t <= len {
                // Past the bounds: the first centre beyond this segment.
                t += (((len - t) / self.spacing).floor() + 1.0) * self.spacing;
            }
        }
        self.to_next = t - len;
        self.last = Some((x, y));
        out
    }
}

/// All dab centres of a stroke through `points` with the given spacing.
#[must_use]
pub fn dab_centres(points: &[[f32; 2]], spacing: f32) -> Vec<(f32, f32)> {
    let mut s = StrokeInterpolator::new(spacing);
    points.iter().flat_map(|p| s.push(p[0], p[1])).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn evenly_spaced_without_gaps() {
        // One fast movement of 100 px, sampled twice: dabs every 4 px.
        let d = dab_centres(&[[0.0, 0.0], [100.0, 0.0]], 4.0);
        assert_eq!(d.len(), 26);
        for w in d.windows(2) {
            let gap = (w[1].0 - w[0].0).hypot(w[1].1 - w[0].1);
            assert!((gap - 4.0).abs() < 1e-3, "gap {gap}");
        }
    }

    #[test]
    fn spacing_is_independent_of_sampling() {
        let coarse = dab_centres(&[[0.0, 0.0], [30.0, 40.0], [30.0, 1.0]], 3.0);
        let fine: Vec<[f32; 2]> = (0..=50)
            .map(|i| [0.6 * i as f32, 0.8 * i as f32])
            .chain((1..=39).map(|i| [30.0, 40.0 - i as f32]))
            .collect();
        let fine = dab_centres(&fine, 3.0);
        assert_eq!(coarse.len(), fine.len());
        for (a, b) in coarse.iter().zip(&fine) {
            assert!(
                (a.0 - b.0).abs() < 1e-3 && (a.1 - b.1).abs() < 1e-3,
                "{a:?} {b:?}"
            );
        }
    }

    /// Bounds drop the centres outside them and keep the others exactly,
    /// and a point absurdly far away costs nothing.
    #[test]
    fn bounds_skip_far_centres_without_generating_them() {
        let points = [[10.0, 10.0], [300.0, 40.0], [-50.0, 120.0], [80.0, 90.0]];
        let bounds = [0.0, 0.0, 100.0, 100.0];
        let all = dab_centres(&points, 3.0);
        let mut s = StrokeInterpolator::with_bounds(3.0, bounds);
        let kept: Vec<_> = points.iter().flat_map(|p| s.push(p[0], p[1])).collect();
        let expected: Vec<_> = all
            .iter()
            .copied()
            .filter(|&(x, y)| (0.0..=100.0).contains(&x) && (0.0..=100.0).contains(&y))
            .collect();
        assert!(expected.len() > 20 && expected.len() < all.len());
        assert_eq!(kept.len(), expected.len());
        for (a, b) in kept.iter().zip(&expected) {
            assert!(
                (a.0 - b.0).abs() < 1e-3 && (a.1 - b.1).abs() < 1e-3,
                "{a:?} {b:?}"
            );
        }
        // Out to 1e9 px and back: the same few dabs near the image.
        let mut s = StrokeInterpolator::with_bounds(7.5, [-31.0, -31.0, 542.0, 542.0]);
        let mut n = s.push(10.0, 10.0).len();
        n += s.push(1e9, 1e9).len();
        n += s.push(20.0, 10.0).len();
        assert!(n < 300, "{n} dabs");
    }

    #[test]
    fn still_pointer_gives_one_dab_and_nan_is_ignored() {
        let mut s = StrokeInterpolator::new(2.0);
        assert_eq!(s.push(5.0, 5.0).len(), 1);
        assert!(s.push(5.0, 5.0).is_empty());
        assert!(s.push(f32::NAN, 1.0).is_empty());
        assert_eq!(s.push(5.0, 7.0), vec![(5.0, 7.0)]);
    }
}
