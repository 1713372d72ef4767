//! Reading a stack: trilinear (or cubic B-spline) lookups of all channels at
//! any point and sigma, with the border resolved outside the stored region.

use super::{Interpolation, Level, ScaleStack, bspline_weights};
use crate::border::Border;
use crate::error::FilterError;

impl ScaleStack {
    /// All channels of the prefiltered image at `(x, y)` (full-resolution
    /// pixel coordinates, any value: outside the image it is resolved by the
    /// border mode) for Gaussian `sigma`.
    ///
    /// # Errors
    /// [`FilterError::SigmaOutOfRange`] when `sigma` is not covered,
    /// [`FilterError::InvalidParameter`] for non-finite coordinates or a
    /// stack built for one filter's reads ([`crate::FilterPlan::build_stack_for`]:
    /// its levels hold only the samples that filter reads).
    pub fn sample(&self, x: f32, y: f32, sigma: f64) -> Result<Vec<f32>, FilterError> {
        let mut out = vec![0.0; self.channels];
        self.sample_into(x, y, sigma, &mut out)?;
        Ok(out)
    }

    /// As [`ScaleStack::sample`], writing the channels into `out`
    /// (`out.len()` must equal the channel count).
    ///
    /// # Errors
    /// As [`ScaleStack::sample`], and [`FilterError::Shape`] for a wrong `out` length.
    pub fn sample_into(
        &self,
        x: f32,
        y: f32,
        sigma: f64,
        out: &mut [f32],
    ) -> Result<(), FilterError> {
        if out.len() != self.channels {
            return Err(FilterError::Shape(format!(
                "output has {} channels, the stack {}",
                out.len(),
                self.channels
            )));
        }
        if !(x.is_finite() && y.is_finite()) {
            return Err(FilterError::InvalidParameter(format!(
                "sample position ({x}, {y}) is not finite"
            )));
        }
        if !sigma.is_finite() || !self.covers(sigma) {
            let (min, max) = self.sigma_range();
            return Err(FilterError::SigmaOutOfRange { sigma, min, max });
        }
        self.check_whole("a lookup anywhere")?;
        out.fill(0.0);
        let (a, b, wa, wb) = self.locate_ln(sigma.ln());
        self.accumulate(a, x, y, wa, out);
        if wb != 0.0 {
            self.accumulate(b, x, y, wb, out);
        }
        Ok(())
    }

    /// Adds `weight *` the interpolated value of level `li` at
    /// full-resolution `(x, y)` to `acc` (one value per channel).
    #[expect(clippy::inline_always, reason = "the hot path of filtering; measured")]
    #[inline(always)]
    pub(crate) fn accumulate(&self, li: usize, x: f32, y: f32, weight: f32, acc: &mut [f32]) {
        if self.interpolation == Interpolation::Cubic {
            self.accumulate_cubic(li, x, y, weight, acc);
            return;
        }
        let level = &self.levels[li];
        let u = (x - level.origin) * level.inv_step;
        let v = (y - level.origin) * level.inv_step;
        // For non-negative values truncation is floor (and avoids a libm call
        // on baseline x86-64).
        if u >= 0.0 && v >= 0.0 {
            // (Huge values saturate and fail the range test below.)
            let (iu, iv) = (u as i32 as usize, v as i32 as usize);
            let (nx, ny) = (level.layout.nx, level.layout.ny);
            if iu + 1 < nx && iv + 1 < ny {
                let fu = u - iu as f32;
                let fv = v - iv as f32;
                let c = self.channels;
                let i00 = (iv * nx + iu) * c;
                let i10 = i00 + nx * c;
                let d = &level.data;
                if c == 1 {
                    let (a0, a1) = (d[i00], d[i00 + 1]);
                    let (b0, b1) = (d[i10], d[i10 + 1]);
                    let r0 = a0 + fu * (a1 - a0);
                    let r1 = b0 + fu * (b1 - b0);
                    acc[0] += weight * (r0 + fv * (r1 - r0));
                    return;
                }
                let top = &d[i00..i00 + 2 * c];
                let bottom = &d[i10..i10 + 2 * c];
                for (k, a) in acc.iter_mut().enumerate() {
                    let r0 = top[k] + fu * (top[c + k] - top[k]);
                    let r1 = bottom[k] + fu * (bottom[c + k] - bottom[k]);
                    *a += weight * (r0 + fv * (r1 - r0));
                }
                return;
            }
        }
        self.accumulate_outside(level, x, y, weight, acc);
    }

    /// As [`Self::accumulate`] for a compile-time channel count `C` (the
    /// accumulator stays in registers).
    #[expect(clippy::inline_always, reason = "the hot path of filtering; measured")]
    #[inline(always)]
    pub(crate) fn accumulate_fixed<const C: usize>(
        &self,
        li: usize,
        x: f32,
        y: f32,
        weight: f32,
        acc: &mut [f32; C],
    ) {
        if self.interpolation == Interpolation::Cubic {
            self.accumulate_cubic(li, x, y, weight, acc.as_mut_slice());
            return;
        }
        let level = &self.levels[li];
        let u = (x - level.origin) * level.inv_step;
        let v = (y - level.origin) * level.inv_step;
        if u >= 0.0 && v >= 0.0 {
            let (iu, iv) = (u as i32 as usize, v as i32 as usize);
            let (nx, ny) = (level.layout.nx, level.layout.ny);
            if iu + 1 < nx && iv + 1 < ny {
                let fu = u - iu as f32;
                let fv = v - iv as f32;
                let i00 = (iv * nx + iu) * C;
                let i10 = i00 + nx * C;
                let top = &level.data[i00..i00 + 2 * C];
                let bottom = &level.data[i10..i10 + 2 * C];
                for k in 0..C {
                    let r0 = top[k] + fu * (top[C + k] - top[k]);
                    let r1 = bottom[k] + fu * (bottom[C + k] - bottom[k]);
                    acc[k] += weight * (r0 + fv * (r1 - r0));
                }
                return;
            }
        }
        self.accumulate_outside(level, x, y, weight, acc.as_mut_slice());
    }

    /// The cubic B-spline lookup: 4x4 coefficients around `(x, y)`.
    #[expect(clippy::inline_always, reason = "the hot path of filtering; measured")]
    #[inline(always)]
    pub(super) fn accumulate_cubic(&self, li: usize, x: f32, y: f32, weight: f32, acc: &mut [f32]) {
        let level = &self.levels[li];
        let u = (x - level.origin) * level.inv_step;
        let v = (y - level.origin) * level.inv_step;
        if u >= 1.0 && v >= 1.0 {
            let (iu, iv) = (u as i32 as usize, v as i32 as usize);
            let (nx, ny) = (level.layout.nx, level.layout.ny);
            if iu + 2 < nx && iv + 2 < ny {
                let wx = bspline_weights(u - iu as f32);
                let wy = bspline_weights(v - iv as f32);
                let c = self.channels;
                let d = &level.data;
                let row = nx * c;
                let base = ((iv - 1) * nx + iu - 1) * c;
                if c == 1 {
                    let mut sum = 0.0;
                    for (j, wyj) in wy.iter().enumerate() {
                        let r = &d[base + j * row..base + j * row + 4];
                        sum += wyj * (wx[0] * r[0] + wx[1] * r[1] + wx[2] * r[2] + wx[3] * r[3]);
                    }
                    acc[0] += weight * sum;
                    return;
                }
                for (j, wyj) in wy.iter().enumerate() {
                    let r = &d[base + j * row..base + j * row + 4 * c];
                    let wj = weight * wyj;
                    for (k, a) in acc.iter_mut().enumerate() {
                        *a += wj
                            * (wx[0] * r[k]
                                + wx[1] * r[c + k]
                                + wx[2] * r[2 * c + k]
                                + wx[3] * r[3 * c + k]);
                    }
                }
                return;
            }
        }
        self.accumulate_outside(level, x, y, weight, acc);
    }

    /// Slow path of [`Self::accumulate`]: the footprint leaves the stored
    /// region. The position is resolved by the border mode (exact for
    /// reflect-101 and wrap, whose blurred extension, and that of its
    /// B-spline coefficients, is the same extension of the blurred image),
    /// then every sample of the footprint is read, clamped to the stored
    /// region (replicate) or replaced by the constant.
    #[cold]
    #[inline(never)]
    pub(super) fn accumulate_outside(
        &self,
        level: &Level,
        x: f32,
        y: f32,
        weight: f32,
        acc: &mut [f32],
    ) {
        let step = level.layout.step as f32;
        let lo = level.origin;
        // Positions whose whole footprint is stored: [lo + before step,
        // last - (after - 1) step].
        let (before, after) = self.interpolation.reach();
        let first = lo + before as f32 * step;
        let hi_x = lo + (level.layout.nx - after) as f32 * step;
        let hi_y = lo + (level.layout.ny - after) as f32 * step;
        let map = |p: f32, n: usize, hi: f32| -> f32 {
            if p >= first && p <= hi {
                return p;
            }
            match self.border {
                Border::Constant(_) => p,
                Border::Replicate => p.clamp(first, hi),
                Border::Reflect101 | Border::Wrap => self.border.map_continuous(p, n),
            }
        };
        let x = map(x, self.width, hi_x);
        let y = map(y, self.height, hi_y);
        let u = (x - lo) * level.inv_step;
        let v = (y - lo) * level.inv_step;
        let iu = u.floor();
        let iv = v.floor();
        let axis = |f: f32| -> ([f32; 4], i64, usize) {
            match self.interpolation {
                Interpolation::Linear => ([1.0 - f, f, 0.0, 0.0], 0, 2),
                Interpolation::Cubic => (bspline_weights(f), -1, 4),
            }
        };
        let (wx, ox, n) = axis(u - iu);
        let (wy, oy, _) = axis(v - iv);
        let constant = self.border.constant();
        let c = self.channels;
        let nx = level.layout.nx as i64;
        let ny = level.layout.ny as i64;
        let is_constant = matches!(self.border, Border::Constant(_));
        for (j, &wyj) in wy[..n].iter().enumerate() {
            for (i, &wxi) in wx[..n].iter().enumerate() {
                let w = wxi * wyj;
                if w == 0.0 {
                    continue;
                }
                let mut ix = iu as i64 + ox + i as i64;
                let mut iy = iv as i64 + oy + j as i64;
                let inside = (0..nx).contains(&ix) && (0..ny).contains(&iy);
                if !inside && is_constant {
                    for a in acc.iter_mut() {
                        *a += weight * w * constant;
                    }
                    continue;
                }
                ix = ix.clamp(0, nx - 1);
                iy = iy.clamp(0, ny - 1);
                let k0 = ((iy as usize) * level.layout.nx + ix as usize) * c;
                for (k, a) in acc.iter_mut().enumerate() {
                    *a += weight * w * level.data[k0 + k];
                }
            }
        }
    }
}
