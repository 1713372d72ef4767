//! Levels by direct separable correlation: each stored sample is the sum of
//! the border-extended image times the level's sampled Gaussian, down the
//! columns (every output row sums its input rows over the image columns,
//! read in place) and then along the row. The FFT build ([`super::build`])
//! computes the same samples; [`choose`] takes whichever its cost model
//! says is cheaper, and the brush's region refresh ([`super::refresh`])
//! always takes this one (its windows are small).
//!
//! # Which sum
//! Sample `(i, j)` of a level with sigma `s`, step `q` and origin `o` is
//! `sum_{dy, dx} g(dy) g(dx) f(o + i q + dx, o + j q + dy)` over
//! `|dx|, |dy| <= r`, `r = ceil(5 s) + 1` ([`reach`]),
//! `g(d) = exp(-d^2 / (2 s^2)) / (sqrt(2 pi) s)` (the sampled normalised
//! Gaussian of [`super::ScaleStack`]) and `f` the image extended by the
//! border mode. The FFT build sums the same samples with a reach of
//! `ceil(5 s_max) + 1`; the tails beyond `r` weigh at most
//! `2 Q(5) = 5.7e-7` of the signal per axis, below `f32` rounding of the
//! transforms (the two builds agree to 2e-6 of the image's range, tested on
//! every border mode, pyramid levels and both interpolations).
//!
//! # Cost, and the choice
//! A level of `nx x ny` stored samples whose Gaussian has `T = 2 r + 1`
//! taps costs `T ny (w + nx)` multiply-adds per channel (`w` image columns
//! summed down, then `nx` outputs along each row), in 8 or 16 lanes
//! ([`weighted_sum`]): with the sigma a few stored samples (a pyramid level,
//! or a narrow full-resolution one) that is cheaper than the FFT build's
//! forward transform of the padded image plus an inverse transform per level.
//! Wide unsubsampled levels (`T` in the hundreds) go the other way. The model
//! ([`MACS_PER_FFT_SAMPLE`]) was measured on one core: for a 1024x1024 image
//! it picked the faster build in each of eight stacks tried, and the direct
//! build ran 1.1-2.7x faster where it was picked (BENCHMARKS.md).
//! `IFD_STACK_BUILD=fft` or `direct` in the environment forces a build.
//!
//! # Bits
//! Every output is the sum over taps in tap order. The AVX-512 and AVX2
//! kernels fuse each multiply-add and agree bit for bit (tested); the
//! baseline kernel rounds each product (a software fused multiply-add would
//! be slow) and agrees with them to rounding.
#![allow(
    unsafe_code,
    reason = "calling the kernel compiled for AVX2 or AVX-512 after run-time detection; see weighted_sum"
)]

use std::sync::atomic::{AtomicU8, Ordering};

use rayon::prelude::*;

use super::LevelLayout;
use crate::border::Border;

/// The image a window is computed from: interleaved samples and the border
/// mode that extends them.
#[derive(Clone, Copy)]
pub(super) struct Source<'a> {
    pub(super) data: &'a [f32],
    pub(super) width: usize,
    pub(super) height: usize,
    pub(super) channels: usize,
    pub(super) border: Border,
}

/// Reach of a level's Gaussian: 5 sigma and one pixel.
pub(super) fn reach(sigma: f64) -> i64 {
    (5.0 * sigma).ceil() as i64 + 1
}

/// The sampled normalised Gaussian at offsets `-r..=r`.
fn sampled_gaussian(sigma: f64, r: i64) -> Vec<f32> {
    let norm = 1.0 / ((2.0 * std::f64::consts::PI).sqrt() * sigma);
    (-r..=r)
        .map(|d| (norm * (-(d * d) as f64 / (2.0 * sigma * sigma)).exp()) as f32)
        .collect()
}

/// Output rows per parallel task.
const ROWS_PER_TASK: usize = 8;

/// The samples of level `l` at stored indices `i0..=i1` by `j0..=j1` (which
/// may lie beyond the stored ones), interleaved, row-major: the sum of the
/// module documentation, along columns first (each output row sums its
/// `2 r + 1` input rows over every image column it needs, read in place),
/// then along the row.
fn level_window(
    src: &Source<'_>,
    l: &LevelLayout,
    (i0, i1): (i64, i64),
    (j0, j1): (i64, i64),
) -> Vec<f32> {
    let c = src.channels;
    let r = reach(l.sigma);
    let g = sampled_gaussian(l.sigma, r);
    let taps = g.len();
    let step = l.step;
    let ni = (i1 - i0 + 1) as usize;
    let nj = (j1 - j0 + 1) as usize;
    let x_first = l.origin + i0 * step as i64;
    let y_first = l.origin + j0 * step as i64;
    let rows: Vec<Option<usize>> = (0..(nj - 1) * step + taps)
        .map(|k| src.border.resolve(y_first - r + k as i64, src.height))
        .collect();
    // Input columns, by phase: phase p holds columns p, p + step, ...
    let width = (ni - 1) * step + taps;
    let plen = width.div_ceil(step);
    let map = ColumnMap::new(src, x_first - r, width, step, plen);
    // Tap d of an output reads phase d % step, d / step samples on.
    let along_row: Vec<usize> = (0..taps)
        .map(|d| ((d % step) * plen + d / step) * c)
        .collect();
    let total: f32 = g.iter().sum();
    let mut out = vec![0.0f32; ni * nj * c];
    out.par_chunks_mut(ni * c * ROWS_PER_TASK)
        .enumerate()
        .for_each_init(Scratch::default, |scratch, (task, chunk)| {
            for (jj, orow) in chunk.chunks_mut(ni * c).enumerate() {
                let j = task * ROWS_PER_TASK + jj;
                column_sums(src, &g, &rows[j * step..j * step + taps], &map, scratch);
                fill_phases(
                    src,
                    &scratch.sums,
                    &map,
                    src.border.constant() * total,
                    &mut scratch.phases,
                );
                weighted_sum(&g, &scratch.phases, &along_row, orow);
            }
        });
    out
}

/// Buffers a thread reuses from row to row.
#[derive(Default)]
struct Scratch {
    /// Column sums over the image columns `map.lo..=map.hi`.
    sums: Vec<f32>,
    phases: Vec<f32>,
    weights: Vec<f32>,
    offsets: Vec<usize>,
}

/// `scratch.sums[x] = sum_d g[d] f(map.lo + x, rows[d])`: the weights of
/// the image rows through [`weighted_sum`], the border constant's rows
/// added after.
fn column_sums(
    src: &Source<'_>,
    g: &[f32],
    rows: &[Option<usize>],
    map: &ColumnMap,
    scratch: &mut Scratch,
) {
    let c = src.channels;
    let len = (map.hi + 1 - map.lo) * c;
    scratch.sums.resize(len, 0.0);
    scratch.weights.clear();
    scratch.offsets.clear();
    let mut outside = 0.0f32;
    for (&gd, row) in g.iter().zip(rows) {
        match row {
            Some(y) => {
                scratch.weights.push(gd);
                scratch.offsets.push((y * src.width + map.lo) * c);
            }
            None => outside += gd,
        }
    }
    weighted_sum(
        &scratch.weights,
        src.data,
        &scratch.offsets,
        &mut scratch.sums,
    );
    if outside != 0.0 {
        let add = outside * src.border.constant();
        scratch.sums.iter_mut().for_each(|v| *v += add);
    }
}

/// Where a window's input columns come from: runs of consecutive image
/// columns (copied as one slice when the step is 1) and border constants.
struct ColumnMap {
    /// `(first input column, count, first image column or None)`.
    runs: Vec<(usize, usize, Option<usize>)>,
    /// Per input column, its place among the phases (step > 1).
    dst: Vec<usize>,
    /// The first and last image columns read.
    lo: usize,
    hi: usize,
    /// Samples (per channel) of all phases: `step * ceil(width / step)`.
    samples: usize,
}

impl ColumnMap {
    fn new(src: &Source<'_>, x0: i64, width: usize, step: usize, plen: usize) -> Self {
        let mut runs: Vec<(usize, usize, Option<usize>)> = Vec::new();
        for q in 0..width {
            let x = src.border.resolve(x0 + q as i64, src.width);
            match runs.last_mut() {
                Some((q0, n, Some(x0))) if x == Some(*x0 + (q - *q0)) => *n += 1,
                Some((_, n, None)) if x.is_none() => *n += 1,
                _ => runs.push((q, 1, x)),
            }
        }
        let dst = if step > 1 {
            (0..width).map(|q| (q % step) * plen + q / step).collect()
        } else {
            Vec::new()
        };
        let read = runs
            .iter()
            .filter_map(|&(_, n, x)| x.map(|x| (x, x + n - 1)));
        let (lo, hi) = read.fold((usize::MAX, 0), |(lo, hi), (a, b)| (lo.min(a), hi.max(b)));
        let (lo, hi) = if lo > hi { (0, 0) } else { (lo, hi) };
        Self {
            runs,
            dst,
            lo,
            hi,
            samples: step * plen,
        }
    }
}

/// The column sums of one output row, border-extended over the input
/// columns (`outside` for the border constant's columns) and split into
/// `step` phases.
fn fill_phases(
    src: &Source<'_>,
    sums: &[f32],
    map: &ColumnMap,
    outside: f32,
    phases: &mut Vec<f32>,
) {
    let c = src.channels;
    phases.resize(map.samples * c, 0.0);
    for &(q0, n, x0) in &map.runs {
        match (x0, map.dst.is_empty()) {
            (Some(x), true) => {
                let at = (x - map.lo) * c;
                phases[q0 * c..(q0 + n) * c].copy_from_slice(&sums[at..at + n * c]);
            }
            (None, true) => phases[q0 * c..(q0 + n) * c].fill(outside),
            (Some(x), false) => {
                let from = &sums[(x - map.lo) * c..(x - map.lo + n) * c];
                for (&at, v) in map.dst[q0..q0 + n].iter().zip(from.chunks_exact(c)) {
                    for (k, &v) in v.iter().enumerate() {
                        phases[at * c + k] = v;
                    }
                }
            }
            (None, false) => {
                for &at in &map.dst[q0..q0 + n] {
                    for k in 0..c {
                        phases[at * c + k] = outside;
                    }
                }
            }
        }
    }
}

/// How a [`super::ScaleStack`]'s levels were computed
/// ([`super::ScaleStack::build_method`]): both give the same samples to
/// `f32` rounding; the stack takes the cheaper for its layout.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StackBuild {
    /// Direct separable correlation with each level's sampled Gaussian.
    Direct,
    /// One forward FFT of the padded image, an inverse one per level.
    Fft,
}

impl StackBuild {
    /// `direct` or `FFT`, for reports.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Direct => "direct",
            Self::Fft => "FFT",
        }
    }
}

/// Multiply-adds of the direct build that cost as much as one padded FFT
/// sample's share of a transform (measured with AVX-512 and AVX2 on one
/// core: about 7.4 ns per padded sample of a real 2D transform of a
/// 1024-pixel image against 0.085 ns per multiply-add).
const MACS_PER_FFT_SAMPLE: f64 = 87.0;

/// The cheaper build for `layout`, by the cost model of the module
/// documentation; `IFD_STACK_BUILD=fft` or `direct` in the environment
/// forces one (for measuring).
pub(super) fn choose(layout: &super::StackLayout) -> StackBuild {
    match std::env::var("IFD_STACK_BUILD").as_deref() {
        Ok("fft") => return StackBuild::Fft,
        Ok("direct") => return StackBuild::Direct,
        _ => {}
    }
    choose_by_cost(layout)
}

/// [`choose`] without the environment.
fn choose_by_cost(layout: &super::StackLayout) -> StackBuild {
    if direct_cost(layout) <= fft_cost(layout) {
        StackBuild::Direct
    } else {
        StackBuild::Fft
    }
}

/// Multiply-adds of the direct build, per channel.
fn direct_cost(layout: &super::StackLayout) -> f64 {
    let cubic = layout.interpolation == super::Interpolation::Cubic;
    layout
        .levels
        .iter()
        .map(|l| {
            let taps = (2 * reach(l.sigma) + 1) as f64;
            let (nx, ny) = (l.nx as f64, l.ny as f64);
            let cols_in = (layout.width as f64).min(nx * l.step as f64 + taps);
            let spline = if cubic {
                let k = CUBIC_TAPS as f64;
                (2.0 * k + 1.0) * 2.0 * (nx + 2.0 * k) * (ny + 2.0 * k)
            } else {
                0.0
            };
            taps * ny * (cols_in + nx) + spline
        })
        .sum()
}

/// The FFT build's cost in the same unit: a forward transform of the padded
/// domain, and per level an inverse one of the level's (subsampled) domain
/// plus a pass over the fine spectrum.
fn fft_cost(layout: &super::StackLayout) -> f64 {
    let padded = (layout.fft_width * layout.fft_height) as f64;
    let levels: f64 = layout
        .levels
        .iter()
        .map(|l| 1.0 / (l.step * l.step) as f64 + 0.05)
        .sum();
    MACS_PER_FFT_SAMPLE * padded * (1.0 + levels)
}

/// The stored samples of level `l` at indices `cols` by `rows`
/// (inclusive, possibly beyond the stored ones): the samples, or for cubic
/// interpolation their B-spline coefficients ([`bspline_coefficients`] of
/// the samples [`CUBIC_TAPS`] further out on each side).
pub(super) fn window(
    src: &Source<'_>,
    l: &LevelLayout,
    (i0, i1): (i64, i64),
    (j0, j1): (i64, i64),
    cubic: bool,
) -> Vec<f32> {
    if !cubic {
        return level_window(src, l, (i0, i1), (j0, j1));
    }
    let k = CUBIC_TAPS as i64;
    let samples = level_window(src, l, (i0 - k, i1 + k), (j0 - k, j1 + k));
    let (ni, nj) = ((i1 - i0 + 1) as usize, (j1 - j0 + 1) as usize);
    bspline_coefficients(
        &samples,
        ni + 2 * CUBIC_TAPS,
        nj + 2 * CUBIC_TAPS,
        src.channels,
    )
}

/// Terms of the cubic B-spline prefilter kept on each side by the direct
/// builds: the prefilter is `sqrt 3 z^|k|`, `z = sqrt 3 - 2`, so the
/// neglected tail is `2 sqrt 3 z^(K + 1) / (1 - z) < 2e-7` of the samples'
/// range, and a change moves coefficients at most `K` samples away by more
/// than that.
pub const CUBIC_TAPS: usize = 12;

/// Cubic B-spline coefficients of the inner `(nx - 2K) x (ny - 2K)` samples
/// of an `nx x ny x c` block ([`CUBIC_TAPS`] `= K`): the separable
/// prefilter `sqrt 3 z^|k|`, `|k| <= K`, along rows then columns.
pub(super) fn bspline_coefficients(samples: &[f32], nx: usize, ny: usize, c: usize) -> Vec<f32> {
    let k = CUBIC_TAPS;
    let z = 3f64.sqrt() - 2.0;
    let h: Vec<f32> = (0..=2 * k)
        .map(|i| (3f64.sqrt() * z.powi((i as i32 - k as i32).abs())) as f32)
        .collect();
    let (mx, my) = (nx - 2 * k, ny - 2 * k);
    let len = mx * c;
    // Along rows: every row, inner columns.
    let mut rows = vec![0.0f32; ny * len];
    rows.par_chunks_mut(len)
        .zip(samples.par_chunks(nx * c))
        .for_each(|(out, src)| {
            let offsets: Vec<usize> = (0..h.len()).map(|d| d * c).collect();
            weighted_sum(&h, src, &offsets, out);
        });
    // Along columns: inner rows.
    let mut out = vec![0.0f32; my * len];
    out.par_chunks_mut(len).enumerate().for_each(|(j, row)| {
        let offsets: Vec<usize> = (0..h.len()).map(|d| (j + d) * len).collect();
        weighted_sum(&h, &rows, &offsets, row);
    });
    out
}

/// `out[k] = sum_d w[d] src[offsets[d] + k]`, summed in tap order with each
/// product rounded (no fused multiply-add), so every instruction set gives
/// the same bits.
///
/// # Panics
/// When `src` ends before `offsets[d] + out.len()` for some `d`.
///
/// # The `unsafe` here
/// Calling a function compiled for AVX2 or AVX-512 is `unsafe` in stable
/// Rust; each call is made only after `is_x86_feature_detected!` reported
/// the instruction set (cached in [`ISA`]). The kernels are safe code.
pub(super) fn weighted_sum(w: &[f32], src: &[f32], offsets: &[usize], out: &mut [f32]) {
    debug_assert_eq!(w.len(), offsets.len());
    #[cfg(target_arch = "x86_64")]
    match isa() {
        Isa::Avx512 => {
            // SAFETY: the CPU has AVX-512F (detected at run time).
            unsafe { weighted_sum_avx512(w, src, offsets, out) };
            return;
        }
        Isa::Avx2 => {
            // SAFETY: the CPU has AVX2 (detected at run time).
            unsafe { weighted_sum_avx2(w, src, offsets, out) };
            return;
        }
        Isa::Baseline => {}
    }
    weighted_sum_body::<32, false>(w, src, offsets, out);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,fma")]
fn weighted_sum_avx512(w: &[f32], src: &[f32], offsets: &[usize], out: &mut [f32]) {
    weighted_sum_body::<128, true>(w, src, offsets, out);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn weighted_sum_avx2(w: &[f32], src: &[f32], offsets: &[usize], out: &mut [f32]) {
    weighted_sum_body::<64, true>(w, src, offsets, out);
}

/// Blocks of `B` outputs (`B / lanes` vector accumulators), then blocks of
/// 16, then one output at a time; every output in tap order.
#[inline(always)]
#[expect(
    clippy::inline_always,
    reason = "compiled into each target_feature caller, for its instruction set"
)]
fn weighted_sum_body<const B: usize, const FMA: bool>(
    w: &[f32],
    src: &[f32],
    offsets: &[usize],
    out: &mut [f32],
) {
    let n = out.len();
    let mut k0 = 0;
    while k0 + B <= n {
        block::<B, FMA>(w, src, offsets, k0, &mut out[k0..k0 + B]);
        k0 += B;
    }
    while k0 + 16 <= n {
        block::<16, FMA>(w, src, offsets, k0, &mut out[k0..k0 + 16]);
        k0 += 16;
    }
    for (k, o) in out.iter_mut().enumerate().skip(k0) {
        let mut acc = 0.0f32;
        for (wd, &off) in w.iter().zip(offsets) {
            acc = madd::<FMA>(*wd, src[off + k], acc);
        }
        *o = acc;
    }
}

#[inline(always)]
#[expect(
    clippy::inline_always,
    reason = "compiled into each target_feature caller, for its instruction set"
)]
fn block<const B: usize, const FMA: bool>(
    w: &[f32],
    src: &[f32],
    offsets: &[usize],
    k0: usize,
    out: &mut [f32],
) {
    let mut acc = [0.0f32; B];
    for (wd, &off) in w.iter().zip(offsets) {
        let s: &[f32; B] = src[off + k0..off + k0 + B].try_into().expect("B samples");
        for k in 0..B {
            acc[k] = madd::<FMA>(*wd, s[k], acc[k]);
        }
    }
    out.copy_from_slice(&acc);
}

/// `a b + c`, fused (one rounding) where the kernel is compiled with FMA.
#[inline(always)]
#[expect(
    clippy::inline_always,
    reason = "compiled into each target_feature caller, for its instruction set"
)]
fn madd<const FMA: bool>(a: f32, b: f32, c: f32) -> f32 {
    if FMA { a.mul_add(b, c) } else { a * b + c }
}

/// Instruction sets of [`weighted_sum`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Isa {
    Baseline,
    Avx2,
    Avx512,
}

/// The chosen instruction set: 0 not yet chosen, else `Isa as u8 + 1`.
static ISA: AtomicU8 = AtomicU8::new(0);

fn isa() -> Isa {
    match ISA.load(Ordering::Relaxed) {
        1 => Isa::Baseline,
        2 => Isa::Avx2,
        3 => Isa::Avx512,
        _ => {
            let best = detected();
            ISA.store(best as u8 + 1, Ordering::Relaxed);
            best
        }
    }
}

/// The widest instruction set this CPU has.
fn detected() -> Isa {
    let cap = std::env::var("IFD_SIMD");
    #[cfg(target_arch = "x86_64")]
    {
        if cap.as_deref() == Ok("baseline") {
            return Isa::Baseline;
        }
        let fma = std::arch::is_x86_feature_detected!("fma");
        if fma && cap.as_deref() != Ok("avx2") && std::arch::is_x86_feature_detected!("avx512f") {
            return Isa::Avx512;
        }
        if fma && std::arch::is_x86_feature_detected!("avx2") {
            return Isa::Avx2;
        }
    }
    Isa::Baseline
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stack::refresh::test_images::lcg_noise;
    use crate::stack::{Interpolation, Level, StackLayout, StackOptions, build::build_levels};

    /// Every kernel this CPU runs against an `f64` sum, and the two fused
    /// kernels against each other bit for bit (same taps, same order).
    #[test]
    fn weighted_sum_kernels_agree() {
        let taps = 23;
        let n = 300; // 2 blocks of 128, then 16s, then single outputs
        let src: Vec<f32> = (0..n + 3 * taps)
            .map(|i| ((i * 37 % 101) as f32 - 50.0) / 7.0)
            .collect();
        let w: Vec<f32> = (0..taps).map(|d| 1.0 / (1.0 + d as f32)).collect();
        let offsets: Vec<usize> = (0..taps).map(|d| 3 * d).collect();
        let exact: Vec<f64> = (0..n)
            .map(|k| {
                w.iter()
                    .zip(&offsets)
                    .map(|(&wd, &o)| f64::from(wd) * f64::from(src[o + k]))
                    .sum()
            })
            .collect();
        let check = |name: &str, out: &[f32]| {
            for (k, (&o, &e)) in out.iter().zip(&exact).enumerate() {
                assert!(
                    (f64::from(o) - e).abs() < 1e-5 * (1.0 + e.abs()),
                    "{name} {k}: {o} vs {e}"
                );
            }
        };
        let mut base = vec![0.0f32; n];
        weighted_sum_body::<32, false>(&w, &src, &offsets, &mut base);
        check("baseline", &base);
        #[cfg(target_arch = "x86_64")]
        {
            let fma = std::arch::is_x86_feature_detected!("fma");
            let mut avx2 = vec![0.0f32; n];
            if fma && std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: AVX2 and FMA detected.
                unsafe { weighted_sum_avx2(&w, &src, &offsets, &mut avx2) };
                check("avx2", &avx2);
            }
            if fma && std::arch::is_x86_feature_detected!("avx512f") {
                let mut avx512 = vec![0.0f32; n];
                // SAFETY: AVX-512F and FMA detected.
                unsafe { weighted_sum_avx512(&w, &src, &offsets, &mut avx512) };
                check("avx512", &avx512);
                assert_eq!(avx512, avx2, "the fused kernels differ");
            }
        }
    }

    /// The direct build against the FFT build: every border, one to three
    /// channels, full-resolution and pyramid levels, both interpolations,
    /// an odd-sized image.
    #[test]
    fn direct_build_matches_the_fft_build() {
        let (w, h) = (53usize, 38usize);
        for c in 1..=3 {
            let img = lcg_noise(w, h, c, 7 + c as u32);
            for border in [
                Border::Reflect101,
                Border::Wrap,
                Border::Replicate,
                Border::Constant(0.3),
            ] {
                for (interpolation, factor, margin) in [
                    (Interpolation::Linear, 2.0, 0),
                    (Interpolation::Linear, 1.0, 3),
                    (Interpolation::Cubic, 2.0, 0),
                ] {
                    let options = StackOptions {
                        samples_per_octave: 2,
                        pyramid_factor: factor,
                        margin,
                        interpolation,
                    };
                    let layout = StackLayout::new(w, h, c, 0.8, 9.0, options).unwrap();
                    assert!(layout.levels.iter().any(|l| l.step > 1));
                    let mut fft: Vec<Level> = layout
                        .levels
                        .iter()
                        .map(|l| Level {
                            layout: *l,
                            origin: l.origin as f32,
                            inv_step: 1.0 / l.step as f32,
                            data: vec![0.0; l.nx * l.ny * c],
                        })
                        .collect();
                    build_levels(&layout, img.data(), border, &mut fft);
                    let src = Source {
                        data: img.data(),
                        width: w,
                        height: h,
                        channels: c,
                        border,
                    };
                    let cubic = interpolation == Interpolation::Cubic;
                    for level in &fft {
                        let l = level.layout;
                        let direct =
                            window(&src, &l, (0, l.nx as i64 - 1), (0, l.ny as i64 - 1), cubic);
                        let worst = direct
                            .iter()
                            .zip(&level.data)
                            .map(|(a, b)| (a - b).abs())
                            .fold(0.0f32, f32::max);
                        assert!(
                            worst < 2e-6,
                            "c {c}, {border:?}, {interpolation:?}, factor {factor}, sigma {}, step {}: {worst}",
                            l.sigma,
                            l.step
                        );
                    }
                }
            }
        }
    }

    /// The cost model picks the direct build for narrow full-resolution
    /// levels and for pyramids, and the FFT for wide unsubsampled ones.
    #[test]
    fn the_cost_model_picks_by_width() {
        let layout = |lo, hi, factor| {
            let options = StackOptions {
                pyramid_factor: factor,
                ..StackOptions::default()
            };
            StackLayout::new(1024, 1024, 1, lo, hi, options).unwrap()
        };
        assert_eq!(choose_by_cost(&layout(4.0, 6.73, 4.0)), StackBuild::Direct);
        assert_eq!(choose_by_cost(&layout(1.0, 32.0, 2.0)), StackBuild::Direct);
        assert_eq!(
            choose_by_cost(&layout(8.0, 32.0, f64::INFINITY)),
            StackBuild::Fft
        );
    }
}
