//! Building a stack: every level by FFT (the exact DFT of the sampled
//! Gaussian), rows and columns in blocks, pyramid levels subsampled.

use std::sync::Arc;

use rayon::prelude::*;
use rustfft::num_complex::{Complex32, Complex64};
use rustfft::{Fft, FftPlanner};

use super::{Interpolation, Level, LevelLayout, StackLayout};
use crate::border::Border;
use crate::error::FilterError;

/// Errors on the first non-finite sample.
pub(crate) fn check_finite(data: &[f32], width: usize, channels: usize) -> Result<(), FilterError> {
    let count = data.iter().filter(|v| !v.is_finite()).count();
    if let Some(i) = data.iter().position(|v| !v.is_finite()) {
        let pixel = i / channels;
        return Err(FilterError::NonFinite {
            what: "image",
            count,
            x: pixel % width,
            y: pixel / width,
            channel: i % channels,
        });
    }
    Ok(())
}

/// The exact DFT (length `n`) of the sampled 1D normalised Gaussian,
/// periodised on `n` samples. The 2D transfer function is the outer product.
pub(super) fn gaussian_transfer(sigma: f64, n: usize, planner: &mut FftPlanner<f64>) -> Vec<f32> {
    let mut buf = vec![Complex64::new(0.0, 0.0); n];
    let r = (10.0 * sigma).ceil() as i64 + 1;
    let norm = 1.0 / ((2.0 * std::f64::consts::PI).sqrt() * sigma);
    let n_i = n as i64;
    for d in -r..=r {
        let g = norm * (-(d * d) as f64 / (2.0 * sigma * sigma)).exp();
        buf[d.rem_euclid(n_i) as usize].re += g;
    }
    planner.plan_fft_forward(n).process(&mut buf);
    // The kernel is real and even, so its DFT is real.
    buf.iter().map(|c| c.re as f32).collect()
}

/// A planned FFT.
type FftPlan = Arc<dyn Fft<f32>>;

/// The coarse FFT sample (along either axis) of a level's first stored
/// sample: coarse sample `i` is padded index `i * step`, and the level
/// starts `origin` full-resolution pixels from the image, `pad` after the
/// FFT domain's start.
pub(super) fn first_stored(pad: usize, level: &LevelLayout) -> usize {
    ((pad / level.step) as i64 + level.origin / level.step as i64) as usize
}

/// Row `kx` of a level's coarse spectrum: the image spectrum times the
/// Gaussian's transfer, alias-summed over the `step x step` fine frequencies
/// that fold onto each coarse one (a plain product when `step == 1`).
pub(super) fn blurred_coarse_row(
    kx: usize,
    row: &mut [Complex32],
    step: usize,
    spec_ref: &[Complex32],
    gx: &[f32],
    gy: &[f32],
) {
    let zero = Complex32::new(0.0, 0.0);
    let my = row.len();
    let nyp = my * step;
    let mx = gx.len() / step;
    if step == 1 {
        let g = gx[kx];
        let srow = &spec_ref[kx * nyp..(kx + 1) * nyp];
        for ((o, s), gyv) in row.iter_mut().zip(srow).zip(gy) {
            *o = s * (g * gyv);
        }
        return;
    }
    row.fill(zero);
    for ax in 0..step {
        let fx = kx + ax * mx;
        let g = gx[fx];
        if g.abs() < 1e-12 {
            continue;
        }
        let srow = &spec_ref[fx * nyp..(fx + 1) * nyp];
        for ay in 0..step {
            let base = ay * my;
            for (ky, o) in row.iter_mut().enumerate() {
                let fy = base + ky;
                *o += srow[fy] * (g * gy[fy]);
            }
        }
    }
}

/// The cubic B-spline prefilter on a periodic grid of `n` samples: the
/// inverse of the sampled B-spline's transfer `2/3 + cos(2 pi k / n) / 3`
/// (never below `1/3`), so that the spline through the stored coefficients
/// interpolates the level's samples.
pub(super) fn bspline_prefilter(n: usize) -> Vec<f32> {
    (0..n)
        .map(|k| {
            let c = (std::f64::consts::TAU * k as f64 / n as f64).cos();
            (1.0 / (2.0 / 3.0 + c / 3.0)) as f32
        })
        .collect()
}

/// In-place FFT of every consecutive `len`-long row of `data`, in parallel.
pub(super) fn fft_rows(data: &mut [Complex32], len: usize, fft: &Arc<dyn Fft<f32>>) {
    let rows_per_task = (1usize << 15).div_ceil(len).max(1);
    let scratch_len = fft.get_inplace_scratch_len();
    data.par_chunks_mut(len * rows_per_task).for_each_init(
        || vec![Complex32::new(0.0, 0.0); scratch_len],
        |scratch, chunk| fft.process_with_scratch(chunk, scratch),
    );
}

/// `dst (cols x rows) = transpose(src (rows x cols))`, in parallel, blocked.
pub(super) fn transpose(src: &[Complex32], rows: usize, cols: usize, dst: &mut [Complex32]) {
    const B: usize = 32;
    dst[..rows * cols]
        .par_chunks_mut(rows * B)
        .enumerate()
        .for_each(|(bi, chunk)| {
            let c0 = bi * B;
            let nc = chunk.len() / rows;
            for r0 in (0..rows).step_by(B) {
                let r1 = (r0 + B).min(rows);
                for dc in 0..nc {
                    let c = c0 + dc;
                    let out = &mut chunk[dc * rows..(dc + 1) * rows];
                    for r in r0..r1 {
                        out[r] = src[r * cols + c];
                    }
                }
            }
        });
}

/// Fills every level: one forward FFT per pair of channels (packed as real
/// and imaginary parts — the Gaussian is real and even, so the two channels
/// do not mix), then per level a product with the transfer function, an
/// alias sum down to the level's resolution and an inverse FFT. A channel
/// without a partner (a grey image, the third of RGB) takes the real-input
/// path, [`build_lone_channel`], at half the cost.
pub(super) fn build_levels(
    layout: &StackLayout,
    data: &[f32],
    border: Border,
    levels: &mut [Level],
) {
    let (w, h, channels) = (layout.width, layout.height, layout.channels);
    let (nxp, nyp, pad) = (layout.fft_width, layout.fft_height, layout.pad);
    let mut planner = FftPlanner::<f32>::new();
    let mut planner64 = FftPlanner::<f64>::new();
    let fwd_x = planner.plan_fft_forward(nxp);
    let fwd_y = planner.plan_fft_forward(nyp);
    let transfers: Vec<(Vec<f32>, Vec<f32>)> = layout
        .levels
        .iter()
        .map(|l| {
            (
                gaussian_transfer(l.sigma, nxp, &mut planner64),
                gaussian_transfer(l.sigma, nyp, &mut planner64),
            )
        })
        .collect();
    let inverse: Vec<(FftPlan, FftPlan)> = layout
        .levels
        .iter()
        .map(|l| {
            (
                planner.plan_fft_inverse(nxp / l.step),
                planner.plan_fft_inverse(nyp / l.step),
            )
        })
        .collect();
    let xmap: Vec<Option<usize>> = (0..nxp)
        .map(|n| border.resolve(n as i64 - pad as i64, w))
        .collect();
    let ymap: Vec<Option<usize>> = (0..nyp)
        .map(|n| border.resolve(n as i64 - pad as i64, h))
        .collect();
    let cval = border.constant();
    let zero = Complex32::new(0.0, 0.0);
    // The pair buffers (none for a single channel).
    let paired = if channels > 1 { nxp * nyp } else { 0 };
    let mut z = vec![zero; paired];
    let mut spec = vec![zero; paired];
    let mut coarse = vec![zero; paired];
    let scale = 1.0 / (nxp as f64 * nyp as f64);
    for c0 in (0..channels).step_by(2) {
        let c1 = (c0 + 1 < channels).then_some(c0 + 1);
        if c1.is_none() {
            let plans = LonePlans {
                fwd_x: &fwd_x,
                fwd_y: &fwd_y,
                inverse: &inverse,
                transfers: &transfers,
            };
            build_lone_channel(layout, data, c0, (&xmap, &ymap, cval), &plans, levels);
            continue;
        }
        z.par_chunks_mut(nxp).enumerate().for_each(|(py, row)| {
            let sy = ymap[py];
            for (px, v) in row.iter_mut().enumerate() {
                *v = match (sy, xmap[px]) {
                    (Some(y), Some(x)) => {
                        let i = (y * w + x) * channels;
                        Complex32::new(data[i + c0], c1.map_or(0.0, |c1| data[i + c1]))
                    }
                    _ => Complex32::new(cval, if c1.is_some() { cval } else { 0.0 }),
                };
            }
        });
        fft_rows(&mut z, nxp, &fwd_x);
        transpose(&z, nyp, nxp, &mut spec);
        fft_rows(&mut spec, nyp, &fwd_y);
        // spec[kx * nyp + ky]
        for (li, level) in levels.iter_mut().enumerate() {
            let step = level.layout.step;
            let (mx, my) = (nxp / step, nyp / step);
            let (gx, gy) = (&transfers[li].0, &transfers[li].1);
            let cbuf = &mut coarse[..mx * my];
            let spec_ref = &spec;
            let pre = (layout.interpolation == Interpolation::Cubic)
                .then(|| (bspline_prefilter(mx), bspline_prefilter(my)));
            cbuf.par_chunks_mut(my).enumerate().for_each(|(kx, row)| {
                blurred_coarse_row(kx, row, step, spec_ref, gx, gy);
                if let Some((px, py)) = &pre {
                    let p = px[kx];
                    for (o, q) in row.iter_mut().zip(py) {
                        *o *= p * q;
                    }
                }
            });
            let (inv_x, inv_y) = &inverse[li];
            fft_rows(cbuf, my, inv_y);
            let zbuf = &mut z[..mx * my];
            transpose(cbuf, mx, my, zbuf);
            fft_rows(zbuf, mx, inv_x);
            // zbuf[y' * mx + x'], coarse sample i <-> padded index i * step.
            let first = first_stored(pad, &level.layout);
            let nx = level.layout.nx;
            let zref = &*zbuf;
            level
                .data
                .par_chunks_mut(nx * channels)
                .enumerate()
                .for_each(|(iy, row)| {
                    let src = &zref[(first + iy) * mx + first..];
                    for ix in 0..nx {
                        let v = src[ix];
                        row[ix * channels + c0] = (f64::from(v.re) * scale) as f32;
                        if let Some(c1) = c1 {
                            row[ix * channels + c1] = (f64::from(v.im) * scale) as f32;
                        }
                    }
                });
        }
    }
}

/// The plans and transfer functions [`build_lone_channel`] shares with
/// [`build_levels`].
pub(super) struct LonePlans<'a> {
    fwd_x: &'a FftPlan,
    fwd_y: &'a FftPlan,
    /// Per level: inverse plans of lengths `nxp / step` and `nyp / step`.
    inverse: &'a [(FftPlan, FftPlan)],
    /// Per level: the transfer along x (length `nxp`) and along y (`nyp`).
    transfers: &'a [(Vec<f32>, Vec<f32>)],
}

/// One real channel's levels through half spectra. The spectrum of a real
/// image is Hermitian, `X(-k) = conj X(k)`, so only the columns
/// `kx = 0..=nxp/2` are computed and kept:
///
/// - forward: rows are transformed two at a time, packed as `z = a + i b`;
///   then `A(k) = (Z(k) + conj Z(-k)) / 2` and
///   `B(k) = (Z(k) - conj Z(-k)) / 2i` are the two rows' spectra; the
///   columns `0..=nxp/2` are transformed along y;
/// - per level: the alias sum onto the coarse columns `0..=mx/2` reads
///   fine columns above `nxp/2` as `conj X(nxp - kx, -ky)`; after the
///   inverse transforms along y, two coarse rows `a`, `b` (real, with
///   Hermitian half spectra `A`, `B`) are rebuilt together as one complex
///   row `Z(k) = A(k) + i B(k)` (`k <= mx/2`), `conj A(mx-k) + i conj
///   B(mx-k)` (above), whose inverse transform is `a + i b`.
///
/// Half the transforms of the packed-pair path, for the same samples up to
/// f32 rounding (the stack tests compare both against direct correlation).
pub(super) fn build_lone_channel(
    layout: &StackLayout,
    data: &[f32],
    c0: usize,
    (xmap, ymap, cval): (&[Option<usize>], &[Option<usize>], f32),
    plans: &LonePlans<'_>,
    levels: &mut [Level],
) {
    let (w, channels) = (layout.width, layout.channels);
    let (nxp, nyp) = (layout.fft_width, layout.fft_height);
    let pad = layout.pad;
    let zero = Complex32::new(0.0, 0.0);
    let hx = nxp / 2 + 1;
    let pairs = nyp.div_ceil(2);
    let value = |py: usize, px: usize| -> f32 {
        match (ymap[py], xmap[px]) {
            (Some(y), Some(x)) => data[(y * w + x) * channels + c0],
            _ => cval,
        }
    };
    // Rows 2r and 2r + 1 as one complex row.
    let mut z = vec![zero; pairs * nxp];
    z.par_chunks_mut(nxp).enumerate().for_each(|(r, row)| {
        let (ya, yb) = (2 * r, 2 * r + 1);
        for (px, v) in row.iter_mut().enumerate() {
            let b = if yb < nyp { value(yb, px) } else { 0.0 };
            *v = Complex32::new(value(ya, px), b);
        }
    });
    fft_rows(&mut z, nxp, plans.fwd_x);
    // Split into the half spectra of the single rows, written transposed:
    // spec[kx * nyp + ky], kx in 0..hx (one pass, no intermediate buffer;
    // buffers are reused across levels below: a fresh one costs a page
    // fault per 4 KiB, which was as much as the transforms).
    let mut spec = vec![zero; hx * nyp];
    let z_ref = &z;
    spec.par_chunks_mut(nyp * COLUMN_BLOCK)
        .enumerate()
        .for_each(|(block, cols)| {
            let k0 = block * COLUMN_BLOCK;
            let kn = cols.len() / nyp;
            for r in 0..pairs {
                let zr = &z_ref[r * nxp..(r + 1) * nxp];
                for j in 0..kn {
                    let k = k0 + j;
                    let zk = zr[k];
                    let zm = zr[(nxp - k) % nxp].conj();
                    let col = &mut cols[j * nyp..(j + 1) * nyp];
                    col[2 * r] = (zk + zm) * 0.5;
                    if 2 * r + 1 < nyp {
                        let d = (zk - zm) * 0.5;
                        // d / i = -i d
                        col[2 * r + 1] = Complex32::new(d.im, -d.re);
                    }
                }
            }
        });
    fft_rows(&mut spec, nyp, plans.fwd_y);
    let mut coarse = vec![zero; hx * nyp];
    let scale = 1.0 / (nxp as f64 * nyp as f64);
    for (li, level) in levels.iter_mut().enumerate() {
        let step = level.layout.step;
        let (mx, my) = (nxp / step, nyp / step);
        let mh = mx / 2 + 1;
        let (gx, gy) = (&plans.transfers[li].0, &plans.transfers[li].1);
        let pre = (layout.interpolation == Interpolation::Cubic)
            .then(|| (bspline_prefilter(mx), bspline_prefilter(my)));
        let cbuf = &mut coarse[..mh * my];
        let spec_ref = &spec;
        cbuf.par_chunks_mut(my).enumerate().for_each(|(kx, row)| {
            blurred_half_row(kx, row, step, spec_ref, gx, gy);
            if let Some((px, py)) = &pre {
                let p = px[kx];
                for (o, q) in row.iter_mut().zip(py) {
                    *o *= p * q;
                }
            }
        });
        let (inv_x, inv_y) = &plans.inverse[li];
        fft_rows(cbuf, my, inv_y);
        // cbuf[kx * my + y'], kx in 0..mh: rebuild rows 2r and 2r + 1 as
        // one complex row, reading the columns directly (blocks of row
        // pairs keep the columns' lines in cache).
        let cols = &*cbuf;
        let row_pairs = my.div_ceil(2);
        let out = &mut z[..row_pairs * mx];
        out.par_chunks_mut(mx * ROW_PAIR_BLOCK)
            .enumerate()
            .for_each(|(block, o)| {
                let r0 = block * ROW_PAIR_BLOCK;
                // A real row's spectrum is real at 0 and at mx / 2 (even
                // mx): drop the rounding there so that it does not leak
                // into the partner row.
                let fix = |mut c: Complex32, k: usize| {
                    if k == 0 || 2 * k == mx {
                        c.im = 0.0;
                    }
                    c
                };
                for (dr, o) in o.chunks_mut(mx).enumerate() {
                    let (ya, yb) = (2 * (r0 + dr), 2 * (r0 + dr) + 1);
                    for (k, v) in o.iter_mut().enumerate() {
                        let (j, conj) = if k < mh { (k, false) } else { (mx - k, true) };
                        let ca = fix(cols[j * my + ya], j);
                        let cb = if yb < my {
                            fix(cols[j * my + yb], j)
                        } else {
                            zero
                        };
                        let (ca, cb) = if conj {
                            (ca.conj(), cb.conj())
                        } else {
                            (ca, cb)
                        };
                        // A + i B
                        *v = Complex32::new(ca.re - cb.im, ca.im + cb.re);
                    }
                }
            });
        fft_rows(out, mx, inv_x);
        let first = first_stored(pad, &level.layout);
        let nx = level.layout.nx;
        let out_ref = &*out;
        level
            .data
            .par_chunks_mut(nx * channels)
            .enumerate()
            .for_each(|(iy, row)| {
                let y = first + iy;
                let src = &out_ref[(y / 2) * mx + first..];
                let odd = y % 2 == 1;
                for ix in 0..nx {
                    let v = src[ix];
                    let v = if odd { v.im } else { v.re };
                    row[ix * channels + c0] = (f64::from(v) * scale) as f32;
                }
            });
    }
}

/// Columns of the half spectrum written per task by the forward split of
/// [`build_lone_channel`].
pub(super) const COLUMN_BLOCK: usize = 16;
/// Row pairs rebuilt per task by its inverse.
pub(super) const ROW_PAIR_BLOCK: usize = 8;

/// Row `kx` (`<= mx / 2`) of a level's coarse half spectrum from the fine
/// half spectrum `spec_half[kx * nyp + ky]` (`kx <= nxp / 2`): as
/// [`blurred_coarse_row`], reading the fine columns above `nxp / 2` by
/// Hermitian symmetry, `X(kx, ky) = conj X(nxp - kx, (nyp - ky) mod nyp)`.
pub(super) fn blurred_half_row(
    kx: usize,
    row: &mut [Complex32],
    step: usize,
    spec_half: &[Complex32],
    gx: &[f32],
    gy: &[f32],
) {
    let my = row.len();
    let nyp = my * step;
    let nxp = gx.len();
    let mx = nxp / step;
    row.fill(Complex32::new(0.0, 0.0));
    for ax in 0..step {
        let fx = kx + ax * mx;
        let g = gx[fx];
        if g.abs() < 1e-12 {
            continue;
        }
        if 2 * fx <= nxp {
            let srow = &spec_half[fx * nyp..(fx + 1) * nyp];
            for ay in 0..step {
                let base = ay * my;
                for (ky, o) in row.iter_mut().enumerate() {
                    let fy = base + ky;
                    *o += srow[fy] * (g * gy[fy]);
                }
            }
        } else {
            let mirror = nxp - fx;
            let srow = &spec_half[mirror * nyp..(mirror + 1) * nyp];
            for ay in 0..step {
                let base = ay * my;
                for (ky, o) in row.iter_mut().enumerate() {
                    let fy = base + ky;
                    *o += srow[(nyp - fy) % nyp].conj() * (g * gy[fy]);
                }
            }
        }
    }
}
