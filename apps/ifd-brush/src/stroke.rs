//! Stroke interpolation: pointer samples to evenly spaced dab centres, so
//! that fast mouse movement leaves no gaps.

/// Turns the pointer positions of one stroke into dab centres spaced
/// `spacing` pixels apart along the polyline through them (the first dab at
/// the first position; the distance left over at the end of a segment
/// carries into the next one, so the spacing does not depend on how the
/// pointer was sampled).
#[derive(Clone, Debug)]
pub struct StrokeInterpolator {
    spacing: f32,
    last: Option<(f32, f32)>,
    /// Distance still to travel before the next dab.
    to_next: f32,
}

impl StrokeInterpolator {
    /// A new stroke with dabs every `spacing` pixels (at least 0.25).
    #[must_use]
    pub fn new(spacing: f32) -> Self {
        Self {
            spacing: if spacing.is_finite() {
                spacing.max(0.25)
            } else {
                1.0
            },
            last: None,
            to_next: 0.0,
        }
    }

    /// The next pointer position; returns the dab centres it adds.
    /// Non-finite positions are ignored.
    pub fn push(&mut self, x: f32, y: f32) -> Vec<(f32, f32)> {
        if !(x.is_finite() && y.is_finite()) {
            return Vec::new();
        }
        let Some((lx, ly)) = self.last else {
            self.last = Some((x, y));
            self.to_next = self.spacing;
            return vec![(x, y)];
        };
        let (dx, dy) = (x - lx, y - ly);
        let len = dx.hypot(dy);
        let mut out = Vec::new();
        let mut t = self.to_next;
        while t <= len {
            let f = t / len;
            out.push((lx + f * dx, ly + f * dy));
            t += self.spacing;
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

    #[test]
    fn still_pointer_gives_one_dab_and_nan_is_ignored() {
        let mut s = StrokeInterpolator::new(2.0);
        assert_eq!(s.push(5.0, 5.0).len(), 1);
        assert!(s.push(5.0, 5.0).is_empty());
        assert!(s.push(f32::NAN, 1.0).is_empty());
        assert_eq!(s.push(5.0, 7.0), vec![(5.0, 7.0)]);
    }
}
