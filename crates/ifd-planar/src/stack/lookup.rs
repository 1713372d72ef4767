//! Fixed lookups applied to whole rows: a tap's interpolation weights are
//! the same for every pixel of a row, so the stored interior is read as a
//! contiguous, vectorisable stencil (2x2 samples, or 4x4 B-spline
//! coefficients), and only the pixels whose stencil leaves the stored level
//! take the general, border-resolving lookup.

use rayon::prelude::*;

use super::{Interpolation, ScaleStack, bspline_weights};
use crate::error::FilterError;

/// One resolved lookup: level, displacement from the pixel and weight.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Tap {
    pub(crate) level: usize,
    pub(crate) ox: f32,
    pub(crate) oy: f32,
    pub(crate) weight: f32,
}

/// Adds constant taps into `out`, the pixels `xs` of row `y` (`out[(x -
/// xs.start) * c..]`): full-resolution levels are applied as a 2x2 stencil
/// over the stored interior (contiguous, vectorisable), everything else
/// through the general lookup with border handling.
pub(crate) fn row_constant(
    stack: &ScaleStack,
    taps: &[Tap],
    y: usize,
    xs: std::ops::Range<usize>,
    out: &mut [f32],
) {
    let c = stack.channels();
    let (xa, xb) = (xs.start, xs.end);
    let yf = y as f32;
    for tap in taps {
        let level = &stack.levels[tap.level];
        let lay = &level.layout;
        let general = |out: &mut [f32], xs: std::ops::Range<usize>| {
            for x in xs {
                let o = (x - xa) * c;
                stack.accumulate(
                    tap.level,
                    x as f32 + tap.ox,
                    yf + tap.oy,
                    tap.weight,
                    &mut out[o..o + c],
                );
            }
        };
        if lay.step != 1 {
            general(out, xa..xb);
            continue;
        }
        let fx = tap.ox.floor();
        let fy = tap.oy.floor();
        let ax = tap.ox - fx;
        let ay = tap.oy - fy;
        // Stored column of pixel x is x + di, stored row is y + dj.
        let di = fx as i64 - lay.origin;
        let iv = y as i64 + fy as i64 - lay.origin;
        // Samples the stencil reads before and after the one below the point.
        let (before, after) = stack.interpolation().reach();
        let (before, after) = (before as i64, after as i64);
        if iv < before || iv + after >= lay.ny as i64 {
            general(out, xa..xb);
            continue;
        }
        let x0 = (before - di).clamp(xa as i64, xb as i64) as usize;
        let x1 = (lay.nx as i64 - after - di).clamp(x0 as i64, xb as i64) as usize;
        general(out, xa..x0);
        general(out, x1..xb);
        if x1 > x0 && stack.interpolation() == Interpolation::Cubic {
            // 4x4 coefficients with weights fixed for the whole row.
            let wx = bspline_weights(ax);
            let wy = bspline_weights(ay);
            let nxc = lay.nx * c;
            let start = ((x0 as i64 + di - 1) as usize) * c;
            let len = (x1 - x0) * c;
            let dst = &mut out[(x0 - xa) * c..(x1 - xa) * c];
            for (j, wyj) in wy.iter().enumerate() {
                let r = (iv as usize + j - 1) * nxc;
                let row = &level.data[r + start..r + start + len + 3 * c];
                let w = wx.map(|v| v * wyj * tap.weight);
                for (i, o) in dst.iter_mut().enumerate() {
                    *o += w[0] * row[i]
                        + w[1] * row[i + c]
                        + w[2] * row[i + 2 * c]
                        + w[3] * row[i + 3 * c];
                }
            }
        } else if x1 > x0 {
            let nxc = lay.nx * c;
            let r0 = &level.data[iv as usize * nxc..(iv as usize + 1) * nxc];
            let r1 = &level.data[(iv as usize + 1) * nxc..(iv as usize + 2) * nxc];
            let start = ((x0 as i64 + di) as usize) * c;
            let len = (x1 - x0) * c;
            let a00 = tap.weight * (1.0 - ax) * (1.0 - ay);
            let a01 = tap.weight * ax * (1.0 - ay);
            let a10 = tap.weight * (1.0 - ax) * ay;
            let a11 = tap.weight * ax * ay;
            let dst = &mut out[(x0 - xa) * c..(x1 - xa) * c];
            let p00 = &r0[start..start + len];
            let p01 = &r0[start + c..start + c + len];
            let p10 = &r1[start..start + len];
            let p11 = &r1[start + c..start + c + len];
            for ((((o, &v00), &v01), &v10), &v11) in
                dst.iter_mut().zip(p00).zip(p01).zip(p10).zip(p11)
            {
                *o += a00 * v00 + a01 * v01 + a10 * v10 + a11 * v11;
            }
        }
    }
}

/// The lookups of one constant rotation and scale (possibly of several
/// weighted filters on the same stack, e.g. a blend of two
/// decompositions), applied over a rectangle with a vectorised 2x2 stencil
/// per tap: the fast path for a brush dab whose filter is constant.
#[derive(Clone, Debug, Default)]
pub struct Taps {
    pub(crate) taps: Vec<Tap>,
}

impl Taps {
    /// The number of bilinear lookups per pixel.
    #[must_use]
    pub fn len(&self) -> usize {
        self.taps.len()
    }

    /// No lookups.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.taps.is_empty()
    }

    /// Appends `other`'s lookups (their weights already include any blend weight).
    pub fn extend(&mut self, other: Taps) {
        self.taps.extend(other.taps);
    }

    /// Filters the rectangle `x0..x0 + width`, `y0..y0 + height` of `stack`
    /// (which must be the stack the taps were made for): returns
    /// `width * height * channels` values, row-major, interleaved.
    ///
    /// # Errors
    /// [`FilterError::InvalidParameter`] when the rectangle leaves the image
    /// or a tap refers to a level the stack does not have.
    pub fn apply_region(
        &self,
        stack: &ScaleStack,
        x0: usize,
        y0: usize,
        width: usize,
        height: usize,
    ) -> Result<Vec<f32>, FilterError> {
        stack.check_whole("taps at a constant pose")?;
        if x0 + width > stack.width() || y0 + height > stack.height() {
            return Err(FilterError::InvalidParameter(format!(
                "region {width}x{height} at ({x0}, {y0}) leaves the {}x{} image",
                stack.width(),
                stack.height()
            )));
        }
        if self.taps.iter().any(|t| t.level >= stack.levels.len()) {
            return Err(FilterError::InvalidParameter(
                "the taps were made for another stack".into(),
            ));
        }
        let c = stack.channels();
        let mut out = vec![0.0f32; width * height * c];
        if width == 0 {
            return Ok(out);
        }
        out.par_chunks_mut(width * c)
            .enumerate()
            .for_each(|(j, row)| row_constant(stack, &self.taps, y0 + j, x0..x0 + width, row));
        Ok(out)
    }
}
