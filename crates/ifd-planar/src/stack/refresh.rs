//! Refreshing part of a [`ScaleStack`] after the image changed in a rectangle
//! (the brush app's strokes): every stored sample of every level whose value
//! depends on a changed pixel is recomputed by direct separable correlation
//! of the current, border-extended image with the level's sampled Gaussian.

use ifd_image::Image;
use rayon::prelude::*;

use super::plan::CUBIC_TAPS;
use super::separable::{Source, reach, window};
use super::{Interpolation, LevelLayout, ScaleStack, check_finite};
use crate::border::Border;
use crate::error::FilterError;

/// A rectangle of pixels: columns `x0..x0 + width`, rows `y0..y0 + height`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelRect {
    /// First column.
    pub x0: usize,
    /// First row.
    pub y0: usize,
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
}

impl PixelRect {
    /// The whole `width x height` image.
    #[must_use]
    pub fn full(width: usize, height: usize) -> Self {
        Self {
            x0: 0,
            y0: 0,
            width,
            height,
        }
    }

    /// The smallest rectangle containing both.
    #[must_use]
    pub fn union(self, other: Self) -> Self {
        let x0 = self.x0.min(other.x0);
        let y0 = self.y0.min(other.y0);
        let x1 = (self.x0 + self.width).max(other.x0 + other.width);
        let y1 = (self.y0 + self.height).max(other.y0 + other.height);
        Self {
            x0,
            y0,
            width: x1 - x0,
            height: y1 - y0,
        }
    }

    /// Number of pixels.
    #[must_use]
    pub fn area(self) -> usize {
        self.width * self.height
    }

    /// The intersection of two rectangles, if not empty.
    #[must_use]
    pub fn intersect(self, other: Self) -> Option<Self> {
        let x0 = self.x0.max(other.x0);
        let y0 = self.y0.max(other.y0);
        let x1 = (self.x0 + self.width).min(other.x0 + other.width);
        let y1 = (self.y0 + self.height).min(other.y0 + other.height);
        (x1 > x0 && y1 > y0).then(|| Self {
            x0,
            y0,
            width: x1 - x0,
            height: y1 - y0,
        })
    }

    /// The tiles of at most `side` pixels a side (at least 1) covering a
    /// `width x height` image, row by row.
    ///
    /// ```
    /// use ifd_planar::PixelRect;
    /// let t = PixelRect::tiles(5, 3, 2);
    /// assert_eq!(t.len(), 6);
    /// assert_eq!(t[5], PixelRect { x0: 4, y0: 2, width: 1, height: 1 });
    /// ```
    #[must_use]
    pub fn tiles(width: usize, height: usize, side: usize) -> Vec<Self> {
        let side = side.max(1);
        let mut out = Vec::new();
        for y0 in (0..height).step_by(side) {
            for x0 in (0..width).step_by(side) {
                out.push(Self {
                    x0,
                    y0,
                    width: side.min(width - x0),
                    height: side.min(height - y0),
                });
            }
        }
        out
    }
}

/// One lookup of a fixed (already rotated and scaled) filter: `weight *
/// fhat_sigma(x + dx, y + dy)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FixedTap {
    /// Column offset, pixels.
    pub dx: f32,
    /// Row offset, pixels.
    pub dy: f32,
    /// Gaussian sigma of the stack level, pixels.
    pub sigma: f64,
    /// Weight.
    pub weight: f32,
}

/// What [`ScaleStack::refresh_region`] recomputed.
///
/// Refreshing part of a [`ScaleStack`] after the image changed in a rectangle
/// (the brush app's strokes): every stored sample of every level whose value
/// depends on a changed pixel is recomputed by direct separable correlation
/// of the current, border-extended image with the level's sampled Gaussian.
///
/// The FFT build and this refresh compute the same quantity (see the
/// [`ScaleStack`] docs: the sampled normalised Gaussian
/// `exp(-d^2 / (2 sigma^2)) / (sqrt(2 pi) sigma)` per axis, not renormalised),
/// here truncated at `ceil(5 sigma) + 1` samples, where the neglected tail
/// mass is below `6e-7` per axis; the tests check agreement with a full
/// rebuild to `1e-5` relative to the image range.
///
/// Levels of cubic B-spline coefficients ([`Interpolation::Cubic`]) are
/// refreshed the same way, then prefiltered: a coefficient is
/// `sum_k sqrt 3 z^|k| s(i + k)` (`z = sqrt 3 - 2`, the inverse of the
/// sampled B-spline `(1, 4, 1) / 6`), kept for `|k| <= 12` (`CUBIC_TAPS`),
/// so a change rewrites 12 more samples on each side of the affected ones.
///
/// Cost per level: `(rows + 2R) * cols / step * (2R + 1)` plus
/// `rows / step * cols / step * (2R + 1)` multiply-adds per channel, with
/// `R = 5 sigma` and `rows x cols` the changed rectangle dilated by `R`
/// (clipped to the stored level).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RefreshReport {
    /// Stored samples recomputed (per channel), over all levels.
    pub samples: usize,
    /// Stored samples in the whole stack (per channel).
    pub total_samples: usize,
}

/// Index range `[lo, hi]` of stored samples (origin `origin`, spacing `step`,
/// `n` samples) whose full-resolution coordinate lies within `reach` of the
/// changed pixels `[a, b]` on an axis of `len` pixels; `None` when none.
#[expect(
    clippy::too_many_arguments,
    reason = "one axis of a level, spelled out"
)]
fn affected_range(
    a: i64,
    b: i64,
    reach: i64,
    origin: i64,
    step: i64,
    n: usize,
    len: usize,
    border: Border,
) -> Option<(usize, usize)> {
    let last = n as i64 - 1;
    // The stored overhang beyond the image: a changed pixel is also seen,
    // through the border extension, by stored samples in the margins, and
    // only when its reach extended by the overhang crosses the image edge.
    let overhang = -origin + step;
    let crosses_lo = a - reach - overhang <= 0;
    let crosses_hi = b + reach + overhang >= len as i64 - 1;
    if matches!(border, Border::Wrap) && (crosses_lo || crosses_hi) {
        return Some((0, last as usize));
    }
    let lo = if crosses_lo {
        0
    } else {
        (a - reach - origin).div_euclid(step).max(0)
    };
    let hi = if crosses_hi {
        last
    } else {
        ((b + reach - origin).div_euclid(step) + 1).min(last)
    };
    (lo <= hi).then_some((lo as usize, hi as usize))
}

/// Stored sample ranges `((i0, i1), (j0, j1))` (columns, rows) of level `l`
/// that depend on the pixels of the non-empty `rect`; `None` when none.
fn affected_window(
    l: &LevelLayout,
    rect: PixelRect,
    w: usize,
    h: usize,
    border: Border,
) -> Option<((usize, usize), (usize, usize))> {
    let r = reach(l.sigma);
    let step = l.step as i64;
    let (a_x, b_x) = (rect.x0 as i64, (rect.x0 + rect.width - 1) as i64);
    let (a_y, b_y) = (rect.y0 as i64, (rect.y0 + rect.height - 1) as i64);
    let cols = affected_range(a_x, b_x, r, l.origin, step, l.nx, w, border)?;
    let rows = affected_range(a_y, b_y, r, l.origin, step, l.ny, h, border)?;
    Some((cols, rows))
}

/// Stored samples `((i0, i1), (j0, j1))` of level `l` that
/// [`ScaleStack::refresh_region`] rewrites for a change in `rect`: those
/// depending on it ([`affected_window`]), and for B-spline coefficients
/// ([`CUBIC_TAPS`]) `K` more on each side.
fn written_window(
    l: &LevelLayout,
    cubic: bool,
    rect: PixelRect,
    w: usize,
    h: usize,
    border: Border,
) -> Option<((usize, usize), (usize, usize))> {
    let ((i0, i1), (j0, j1)) = affected_window(l, rect, w, h, border)?;
    if !cubic {
        return Some(((i0, i1), (j0, j1)));
    }
    let k = CUBIC_TAPS;
    Some((
        (i0.saturating_sub(k), (i1 + k).min(l.nx - 1)),
        (j0.saturating_sub(k), (j1 + k).min(l.ny - 1)),
    ))
}

impl ScaleStack {
    /// Evaluates a fixed filter, `sum_t weight_t fhat_{sigma_t}(p + d_t)`, at
    /// every pixel `p` of `rect`; returns `rect.area() * channels` values,
    /// interleaved, row-major. The lookups are those of
    /// [`ScaleStack::sample`] (the same interpolation), located once per tap.
    ///
    /// # Errors
    /// [`FilterError::SigmaOutOfRange`] for a tap sigma the stack does not
    /// cover, [`FilterError::InvalidParameter`] for non-finite offsets or
    /// weights, [`FilterError::Shape`] for a rectangle leaving the image.
    pub fn correlate_region(
        &self,
        taps: &[FixedTap],
        rect: PixelRect,
    ) -> Result<Vec<f32>, FilterError> {
        self.check_whole("a correlation over a rectangle")?;
        if rect.x0 + rect.width > self.width() || rect.y0 + rect.height > self.height() {
            return Err(FilterError::Shape(format!(
                "rectangle {}x{} at ({}, {}) leaves the {}x{} image",
                rect.width,
                rect.height,
                rect.x0,
                rect.y0,
                self.width(),
                self.height()
            )));
        }
        let mut lookups: Vec<(usize, f32, f32, f32)> = Vec::with_capacity(2 * taps.len());
        for t in taps {
            if !(t.dx.is_finite() && t.dy.is_finite() && t.weight.is_finite()) {
                return Err(FilterError::InvalidParameter(format!(
                    "tap {t:?} is not finite"
                )));
            }
            if !t.sigma.is_finite() || !self.covers(t.sigma) {
                let (min, max) = self.sigma_range();
                return Err(FilterError::SigmaOutOfRange {
                    sigma: t.sigma,
                    min,
                    max,
                });
            }
            let (a, b, wa, wb) = self.locate_ln(t.sigma.ln());
            for (level, w) in [(a, wa), (b, wb)] {
                if w != 0.0 {
                    lookups.push((level, t.dx, t.dy, w * t.weight));
                }
            }
        }
        let c = self.channels();
        let mut out = vec![0.0f32; rect.area() * c];
        if rect.area() == 0 {
            return Ok(out);
        }
        // The taps are constant over the rectangle: each is applied to a
        // whole row with its interpolation weights computed once.
        let taps: Vec<super::lookup::Tap> = lookups
            .iter()
            .map(|&(level, ox, oy, weight)| super::lookup::Tap {
                level,
                ox,
                oy,
                weight,
            })
            .collect();
        let xs = rect.x0..rect.x0 + rect.width;
        out.par_chunks_mut(rect.width * c)
            .enumerate()
            .for_each(|(j, row)| {
                super::lookup::row_constant(self, &taps, rect.y0 + j, xs.clone(), row);
            });
        Ok(out)
    }

    /// The stored rows `(j0, j1)` (inclusive) of each level that
    /// [`ScaleStack::refresh_region`] recomputes for a change in `rect`
    /// (`None`: the level keeps all its samples), for copies of the stack
    /// that follow it row by row (the GPU's). Empty rectangles, and
    /// rectangles leaving the image, change nothing.
    ///
    /// ```
    /// use ifd_planar::{Border, PixelRect, ScaleStack, StackOptions};
    /// let img = ifd_image::Image::from_vec(64, 64, 1, vec![0.5; 64 * 64])?;
    /// let stack = ScaleStack::new(&img, 1.0, 8.0, Border::Reflect101, StackOptions::default())?;
    /// let rect = PixelRect { x0: 30, y0: 30, width: 4, height: 4 };
    /// let rows = stack.refreshed_rows(rect);
    /// assert_eq!(rows.len(), stack.level_layouts().count());
    /// // The finest level (sigma 1, reach 5 sigma + 1 = 6 px, one more sample
    /// // on the far side) recomputes coordinates 30 - 6 ..= 33 + 6 + 1; its
    /// // stored row 0 is coordinate -1.
    /// let first = stack.level_layouts().next().unwrap();
    /// assert_eq!(first.origin, -1);
    /// assert_eq!(rows[0], Some((25, 41)));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    #[must_use]
    pub fn refreshed_rows(&self, rect: PixelRect) -> Vec<Option<(usize, usize)>> {
        let (w, h) = (self.width(), self.height());
        let inside = rect.width > 0
            && rect.height > 0
            && rect.x0 + rect.width <= w
            && rect.y0 + rect.height <= h;
        self.levels
            .iter()
            .map(|level| {
                if !inside {
                    return None;
                }
                let cubic = self.interpolation() == Interpolation::Cubic;
                written_window(&level.layout, cubic, rect, w, h, self.border())
                    .map(|(_, rows)| rows)
            })
            .collect()
    }

    /// Recomputes, in every level, the stored samples that depend on the
    /// pixels of `rect`, from `image` (the stack's image after a change
    /// confined to `rect`). Samples outside the affected region are kept.
    ///
    /// # Errors
    /// [`FilterError::Shape`] when `image` is not the stack's shape or `rect`
    /// leaves it, [`FilterError::NonFinite`] for NaN or infinite pixels in
    /// `rect`.
    pub fn refresh_region(
        &mut self,
        image: &Image,
        rect: PixelRect,
    ) -> Result<RefreshReport, FilterError> {
        let (w, h, c) = (self.width(), self.height(), self.channels());
        if (image.width(), image.height(), image.channels()) != (w, h, c) {
            return Err(FilterError::Shape(format!(
                "image is {}x{}x{}, the stack's {w}x{h}x{c}",
                image.width(),
                image.height(),
                image.channels()
            )));
        }
        if rect.width == 0 || rect.height == 0 {
            return Ok(RefreshReport {
                samples: 0,
                total_samples: self.levels.iter().map(|l| l.data.len() / c).sum(),
            });
        }
        if rect.x0 + rect.width > w || rect.y0 + rect.height > h {
            return Err(FilterError::Shape(format!(
                "rectangle {}x{} at ({}, {}) leaves the {w}x{h} image",
                rect.width, rect.height, rect.x0, rect.y0
            )));
        }
        let data = image.data();
        for y in rect.y0..rect.y0 + rect.height {
            let row = &data[(y * w + rect.x0) * c..(y * w + rect.x0 + rect.width) * c];
            if row.iter().any(|v| !v.is_finite()) {
                // Locate the first one with the library's message.
                check_finite(data, w, c)?;
            }
        }
        let border = self.border();
        let cubic = self.interpolation() == Interpolation::Cubic;
        let mut report = RefreshReport::default();
        for level in &mut self.levels {
            let l = level.layout;
            report.total_samples += l.nx * l.ny;
            let Some(((i0, i1), (j0, j1))) = written_window(&l, cubic, rect, w, h, border) else {
                continue;
            };
            let (ni, nj) = (i1 - i0 + 1, j1 - j0 + 1);
            report.samples += ni * nj;
            let src = Source {
                data: image.data(),
                width: w,
                height: h,
                channels: c,
                border,
            };
            let values = window(
                &src,
                &l,
                (i0 as i64, i1 as i64),
                (j0 as i64, j1 as i64),
                cubic,
            );
            let nx = l.nx;
            level
                .data
                .par_chunks_mut(nx * c)
                .skip(j0)
                .take(nj)
                .zip(values.par_chunks(ni * c))
                .for_each(|(row, src)| row[i0 * c..(i1 + 1) * c].copy_from_slice(src));
        }
        Ok(report)
    }
}

#[cfg(test)]
#[path = "../../../../tests/support/images.rs"]
pub(super) mod test_images;

#[cfg(test)]
mod tests {
    use super::test_images::lcg_noise as test_image;
    use super::*;
    use crate::stack::StackOptions;

    fn max_diff(a: &ScaleStack, b: &ScaleStack) -> f32 {
        a.levels
            .iter()
            .zip(&b.levels)
            .flat_map(|(la, lb)| la.data.iter().zip(&lb.data).map(|(x, y)| (x - y).abs()))
            .fold(0.0, f32::max)
    }

    /// Changes a rectangle, refreshes, and compares with a full rebuild, for
    /// every border mode, near the corner (margins through the border
    /// extension) and in the middle.
    #[test]
    fn refresh_matches_rebuild() {
        for interpolation in [Interpolation::Linear, Interpolation::Cubic] {
            refresh_matches_rebuild_with(interpolation);
        }
    }

    fn refresh_matches_rebuild_with(interpolation: Interpolation) {
        for border in [
            Border::Reflect101,
            Border::Replicate,
            Border::Wrap,
            Border::Constant(0.25),
        ] {
            for (rect, c) in [
                (
                    PixelRect {
                        x0: 2,
                        y0: 1,
                        width: 9,
                        height: 6,
                    },
                    1,
                ),
                (
                    PixelRect {
                        x0: 40,
                        y0: 30,
                        width: 12,
                        height: 7,
                    },
                    3,
                ),
            ] {
                let opts = StackOptions {
                    margin: 3,
                    interpolation,
                    ..StackOptions::default()
                };
                let mut img = test_image(97, 71, c, 7);
                let mut stack = ScaleStack::new(&img, 0.7, 12.0, border, opts).expect("stack");
                let fresh = test_image(rect.width, rect.height, c, 99);
                for y in 0..rect.height {
                    for x in 0..rect.width {
                        for k in 0..c {
                            img.set(rect.x0 + x, rect.y0 + y, k, fresh.get(x, y, k));
                        }
                    }
                }
                let before = max_diff(
                    &stack,
                    &ScaleStack::new(&img, 0.7, 12.0, border, opts).expect("stack"),
                );
                let old = stack.clone();
                let rows = stack.refreshed_rows(rect);
                let report = stack.refresh_region(&img, rect).expect("refresh");
                let rebuilt = ScaleStack::new(&img, 0.7, 12.0, border, opts).expect("stack");
                let after = max_diff(&stack, &rebuilt);
                // Rows outside `refreshed_rows` needed no change: there the
                // stack before the refresh already equals the rebuilt one.
                for ((lo, lr), range) in old.levels.iter().zip(&rebuilt.levels).zip(&rows) {
                    let row_len = lo.layout.nx * c;
                    for (j, (a, b)) in lo
                        .data
                        .chunks_exact(row_len)
                        .zip(lr.data.chunks_exact(row_len))
                        .enumerate()
                    {
                        if range.is_some_and(|(j0, j1)| (j0..=j1).contains(&j)) {
                            continue;
                        }
                        let d = a
                            .iter()
                            .zip(b)
                            .map(|(x, y)| (x - y).abs())
                            .fold(0.0, f32::max);
                        assert!(
                            d < 1e-5,
                            "{border} {rect:?}: level sigma {} row {j} changed by {d} outside the refreshed rows {range:?}",
                            lo.layout.sigma
                        );
                    }
                }
                assert!(before > 1e-2, "{border}: the change must show ({before})");
                assert!(
                    after < 1e-5,
                    "{border} {rect:?} {interpolation:?}: refresh differs by {after}"
                );
                assert!(report.samples > 0 && report.samples <= report.total_samples);
            }
        }
    }

    #[test]
    fn refresh_is_local_for_small_sigmas() {
        let img = test_image(300, 200, 1, 3);
        let mut stack =
            ScaleStack::new(&img, 1.0, 4.0, Border::Reflect101, StackOptions::default())
                .expect("stack");
        let r = stack
            .refresh_region(
                &img,
                PixelRect {
                    x0: 140,
                    y0: 90,
                    width: 10,
                    height: 10,
                },
            )
            .expect("refresh");
        assert!(
            r.samples * 20 < r.total_samples,
            "refreshed {} of {}",
            r.samples,
            r.total_samples
        );
    }

    #[test]
    fn correlate_region_matches_sample() {
        let img = test_image(60, 40, 2, 5);
        let stack = ScaleStack::new(&img, 1.0, 8.0, Border::Reflect101, StackOptions::default())
            .expect("stack");
        let taps = [
            FixedTap {
                dx: 3.5,
                dy: -2.25,
                sigma: 2.7,
                weight: 0.7,
            },
            FixedTap {
                dx: -40.0,
                dy: 1.0,
                sigma: 6.0,
                weight: -1.3,
            },
        ];
        let rect = PixelRect {
            x0: 5,
            y0: 30,
            width: 50,
            height: 10,
        };
        let got = stack.correlate_region(&taps, rect).expect("region");
        for j in 0..rect.height {
            for i in 0..rect.width {
                let (x, y) = ((rect.x0 + i) as f32, (rect.y0 + j) as f32);
                let mut want = [0.0f32; 2];
                for t in &taps {
                    let v = stack.sample(x + t.dx, y + t.dy, t.sigma).expect("sample");
                    want[0] += t.weight * v[0];
                    want[1] += t.weight * v[1];
                }
                for k in 0..2 {
                    let g = got[(j * rect.width + i) * 2 + k];
                    assert!((g - want[k]).abs() < 1e-5, "{g} vs {}", want[k]);
                }
            }
        }
        let bad = [FixedTap {
            sigma: 20.0,
            ..taps[0]
        }];
        assert!(stack.correlate_region(&bad, rect).is_err());
    }

    #[test]
    fn refresh_rejects_bad_input() {
        let img = test_image(20, 10, 1, 3);
        let mut stack =
            ScaleStack::new(&img, 1.0, 2.0, Border::Reflect101, StackOptions::default())
                .expect("stack");
        let rect = PixelRect {
            x0: 15,
            y0: 0,
            width: 10,
            height: 2,
        };
        assert!(stack.refresh_region(&img, rect).is_err());
        let other = test_image(21, 10, 1, 3);
        let ok = PixelRect {
            x0: 0,
            y0: 0,
            width: 2,
            height: 2,
        };
        assert!(stack.refresh_region(&other, ok).is_err());
        let mut nan = img.clone();
        nan.set(1, 1, 0, f32::NAN);
        assert!(matches!(
            stack.refresh_region(&nan, ok),
            Err(FilterError::NonFinite { .. })
        ));
    }
}
