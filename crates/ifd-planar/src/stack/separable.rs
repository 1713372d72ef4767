//! Levels by direct separable correlation: each stored sample is the sum of
//! the border-extended image times the level's sampled Gaussian, down the
//! columns (every output row sums its input rows over the image columns,
//! strip by strip so that they stay in the first cache level) and then along
//! the row. Where the levels allow, a level is instead the level before it
//! correlated with the Gaussian in between ([`build_levels`]: a chain; a
//! few samples wide where the level's own Gaussian would be many, and on its
//! coarser grid where the pyramid step doubles). The FFT build
//! ([`super::build`]) computes the same samples; [`choose`] takes whichever
//! its cost model says is cheaper, and the brush's region refresh
//! ([`super::refresh`]) always takes the unchained sums of [`window`] (its
//! windows are small).
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
//! transforms. A chain's link composes two sampled Gaussians, exact up to
//! their aliases ([`chained_sigma`]). The builds agree to 2e-6 of the
//! image's range, chained or not (tested on every border mode, pyramid
//! levels and both interpolations).
//!
//! # Cost, and the choice
//! A level of `nx x ny` stored samples whose Gaussian has `T = 2 r + 1`
//! taps costs `T ny (w + nx)` multiply-adds per channel (`w` source columns
//! summed down, the image's or the chain's previous level's, then `nx`
//! outputs along each row), in 8 or 16 lanes ([`super::weighted_sum`]): with the
//! sigma a few stored samples (a pyramid level, or a narrow full-resolution
//! one) that is cheaper than the FFT build's forward transform of the
//! padded image plus an inverse transform per level. Wide unsubsampled
//! levels (`T` in the hundreds) go the other way. The model
//! ([`MACS_PER_FFT_SAMPLE`]) was measured on one core; BENCHMARKS.md has
//! both builds side by side on the stacks of
//! `tests/bench/bench_stack_build.py`.
//! `IFD_STACK_BUILD=fft` or `direct` in the environment forces a build.
//!
//! # Bits
//! See [`super::weighted_sum`]: the AVX-512 and AVX2 sums agree bit for bit,
//! the baseline's to rounding.

use std::borrow::Cow;

use rayon::prelude::*;

use super::plan::CUBIC_TAPS;
use super::weighted_sum::weighted_sum;
use super::{LevelLayout, Window, area, is_empty};
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

/// `nj` rows of `ni` samples, interleaved, row-major: the source
/// correlated with the sampled Gaussian of `sigma` samples of the source,
/// at source coordinates `(x_first + i step, y_first + j step)`, down the
/// columns first (each output row sums its `2 r + 1` input rows over every
/// source column it needs, read in place), then along the row.
fn correlate(
    src: &Source<'_>,
    sigma: f64,
    step: usize,
    xs: (i64, usize),
    ys: (i64, usize),
) -> Vec<f32> {
    let mut out = Vec::new();
    correlate_into(src, sigma, step, xs, ys, &mut out);
    out
}

/// [`correlate`] into `out` (resized; its allocation reused).
fn correlate_into(
    src: &Source<'_>,
    sigma: f64,
    step: usize,
    (x_first, ni): (i64, usize),
    (y_first, nj): (i64, usize),
    out: &mut Vec<f32>,
) {
    let c = src.channels;
    let r = reach(sigma);
    let g = sampled_gaussian(sigma, r);
    let taps = g.len();
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
    out.clear();
    out.resize(ni * nj * c, 0.0);
    out.par_chunks_mut(ni * c * ROWS_PER_TASK)
        .enumerate()
        .for_each_init(Scratch::default, |scratch, (task, chunk)| {
            let band = chunk.len() / (ni * c);
            let j0 = task * ROWS_PER_TASK;
            column_sums(src, &g, &rows[j0 * step..], (band, step), &map, scratch);
            for (jj, orow) in chunk.chunks_mut(ni * c).enumerate() {
                let len = scratch.sums.len() / band;
                fill_phases(
                    src,
                    &scratch.sums[jj * len..(jj + 1) * len],
                    &map,
                    src.border.constant() * total,
                    &mut scratch.phases,
                );
                weighted_sum(&g, &scratch.phases, &along_row, orow);
            }
        });
}

/// Buffers a thread reuses from row to row.
#[derive(Default)]
struct Scratch {
    /// Column sums of a band's output rows over the image columns `map.lo..=map.hi`.
    sums: Vec<f32>,
    phases: Vec<f32>,
    weights: Vec<f32>,
    offsets: Vec<usize>,
    outside: Vec<f32>,
}

/// Source columns summed down per pass: the rows of a band's strip stay in
/// the first cache level while every output row of the band sums them.
const COLUMN_STRIP: usize = 128;

/// For the `band` output rows `jj` of a task, `scratch.sums[jj][x] = sum_d
/// g[d] f(map.lo + x, rows[jj step + d])`, strip by strip of source
/// columns: the image rows through [`weighted_sum`], the border constant's
/// rows added after.
fn column_sums(
    src: &Source<'_>,
    g: &[f32],
    rows: &[Option<usize>],
    (band, step): (usize, usize),
    map: &ColumnMap,
    scratch: &mut Scratch,
) {
    let c = src.channels;
    let len = (map.hi + 1 - map.lo) * c;
    scratch.sums.resize(band * len, 0.0);
    // Per output row: the weights of its image rows, their offsets, and the
    // weight of its rows outside the image.
    scratch.weights.clear();
    scratch.offsets.clear();
    scratch.outside.clear();
    for jj in 0..band {
        let mut outside = 0.0f32;
        for (&gd, row) in g.iter().zip(&rows[jj * step..jj * step + g.len()]) {
            if let Some(y) = row {
                scratch.weights.push(gd);
                scratch.offsets.push((y * src.width + map.lo) * c);
            } else {
                // Zero weight on an in-image row keeps the layout fixed.
                scratch.weights.push(0.0);
                scratch.offsets.push(map.lo * c);
                outside += gd;
            }
        }
        scratch.outside.push(outside);
    }
    let taps = g.len();
    let (sums, weights, offsets) = (&mut scratch.sums, &scratch.weights, &scratch.offsets);
    for x0 in (0..len).step_by(COLUMN_STRIP) {
        let x1 = (x0 + COLUMN_STRIP).min(len);
        for jj in 0..band {
            weighted_sum(
                &weights[jj * taps..(jj + 1) * taps],
                &src.data[x0..],
                &offsets[jj * taps..(jj + 1) * taps],
                &mut sums[jj * len + x0..jj * len + x1],
            );
        }
    }
    for (jj, &outside) in scratch.outside.iter().enumerate() {
        if outside != 0.0 {
            let add = outside * src.border.constant();
            sums[jj * len..(jj + 1) * len]
                .iter_mut()
                .for_each(|v| *v += add);
        }
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
/// With `windows` (one per level) the direct build computes only the
/// samples within them ([`build_levels`]), and costs that share of each
/// level.
pub(super) fn choose(layout: &super::StackLayout, windows: Option<&[Window]>) -> StackBuild {
    match std::env::var("IFD_STACK_BUILD").as_deref() {
        Ok("fft") => return StackBuild::Fft,
        Ok("direct") => return StackBuild::Direct,
        _ => {}
    }
    choose_by_cost(layout, windows)
}

/// [`choose`] without the environment.
fn choose_by_cost(layout: &super::StackLayout, windows: Option<&[Window]>) -> StackBuild {
    if direct_cost(layout, windows) <= fft_cost(layout) {
        StackBuild::Direct
    } else {
        StackBuild::Fft
    }
}

/// Multiply-adds of the direct build, per channel ([`build_levels`]; the
/// chained levels' wider windows left out); with `windows`, over the
/// samples [`computed_windows`] computes.
fn direct_cost(layout: &super::StackLayout, windows: Option<&[Window]>) -> f64 {
    let cubic = layout.interpolation == super::Interpolation::Cubic;
    let levels = &layout.levels;
    let spline = |l: &LevelLayout| {
        let k = CUBIC_TAPS as f64;
        let (nx, ny) = (l.nx as f64, l.ny as f64);
        if cubic {
            (2.0 * k + 1.0) * 2.0 * (nx + 2.0 * k) * (ny + 2.0 * k)
        } else {
            0.0
        }
    };
    if let Some(windows) = windows {
        let (links, need) = computed_windows(layout, Some(windows));
        return levels
            .iter()
            .enumerate()
            .map(|(i, l)| {
                let per_sample = links[i].map_or(sample_cost(l.sigma, l.step), |d| {
                    sample_cost(d, l.step / levels[i - 1].step)
                });
                let share = area(need[i]) / (l.nx * l.ny) as f64;
                per_sample * area(need[i]) + share.min(1.0) * spline(l)
            })
            .sum();
    }
    let links = chains(layout);
    levels
        .iter()
        .enumerate()
        .map(|(i, l)| {
            let (nx, ny) = (l.nx as f64, l.ny as f64);
            let chained = links[i].map(|d| (d, &levels[i - 1]));
            // Taps, and the source columns summed down per output row.
            let (taps, cols_in) = if let Some((d, a)) = chained {
                ((2 * reach(d) + 1) as f64, a.nx as f64)
            } else {
                let taps = (2 * reach(l.sigma) + 1) as f64;
                (taps, (layout.width as f64).min(nx * l.step as f64 + taps))
            };
            taps * ny * (cols_in + nx) + spline(l)
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
    let k = if cubic { CUBIC_TAPS as i64 } else { 0 };
    let (ni, nj) = (
        (i1 - i0 + 1 + 2 * k) as usize,
        (j1 - j0 + 1 + 2 * k) as usize,
    );
    let step = l.step as i64;
    let samples = correlate(
        src,
        l.sigma,
        l.step,
        (l.origin + (i0 - k) * step, ni),
        (l.origin + (j0 - k) * step, nj),
    );
    if cubic {
        bspline_coefficients(&samples, ni, nj, src.channels)
    } else {
        samples
    }
}

/// The Gaussian that takes level `a` to level `b`, in samples of `a`, when
/// level `b` is built from `a` (the next level of a chain): `b` on `a`'s
/// grid or every second sample of it, and both `a`'s Gaussian and the one
/// between at least a sample wide. Sampled Gaussians compose exactly up to
/// their aliases, `exp(-2 pi^2 s^2)` at zero frequency (`2.7e-9` at one
/// sample) and about `exp(-pi^2 (s_a^2 + s_d^2) / 2)` at the Nyquist
/// frequency, where the level itself has no more than that.
fn chained_sigma(a: &LevelLayout, b: &LevelLayout) -> Option<f64> {
    let s = a.step as f64;
    let d = (b.sigma * b.sigma - a.sigma * a.sigma).sqrt() / s;
    let on_grid = b.step == a.step || b.step == 2 * a.step;
    (on_grid && a.sigma / s >= MIN_CHAIN_SIGMA && d >= MIN_CHAIN_SIGMA).then_some(d)
}

/// Per level, the Gaussian (in samples of the level before) it is built
/// with from the level before, or `None`: from the image. A chain widens
/// the windows of its levels by the reaches of the links after them; a
/// link that would widen the chain's first level by more than a sixteenth
/// of the image's shorter side starts a new chain instead (from the image,
/// at about `20 k` multiply-adds per pixel for pyramid factor `k`).
fn chains(layout: &super::StackLayout) -> Vec<Option<f64>> {
    let levels = &layout.levels;
    let limit = (layout.width.min(layout.height) as f64 / 16.0).max(8.0);
    let mut widening = 0.0;
    (0..levels.len())
        .map(|i| {
            let link = (i > 0)
                .then(|| chained_sigma(&levels[i - 1], &levels[i]))
                .flatten();
            let more = link.map(|d| reach(d) as f64 * levels[i - 1].step as f64);
            match more {
                Some(more) if widening + more <= limit => {
                    widening += more;
                    link
                }
                _ => {
                    widening = 0.0;
                    None
                }
            }
        })
        .collect()
}

/// The narrowest Gaussian, in samples, a chained build starts from or adds.
const MIN_CHAIN_SIGMA: f64 = 1.0;

/// The samples of each level the direct build computes (stored-sample
/// indices, `k` = [`CUBIC_TAPS`] more on each side for cubic levels, and
/// beyond the stored ones where a chain needs them) and the chain's links
/// ([`chains`]), from the last level back: a chained level widens the one
/// before it to what it reads. With `windows` a link is kept only where it
/// is cheaper than building the level from the image, counting the
/// samples it adds to the level before ([`sample_cost`]): a level read
/// over a wide window after one read over a narrow one starts a chain of
/// its own.
fn computed_windows(
    layout: &super::StackLayout,
    windows: Option<&[Window]>,
) -> (Vec<Option<f64>>, Vec<Window>) {
    let levels = &layout.levels;
    let cubic = layout.interpolation == super::Interpolation::Cubic;
    let k = if cubic { CUBIC_TAPS as i64 } else { 0 };
    let mut chained = chains(layout);
    let mut need: Vec<Window> = levels
        .iter()
        .enumerate()
        .map(|(i, l)| {
            let window = windows.map_or(((0, l.nx as i64 - 1), (0, l.ny as i64 - 1)), |w| w[i]);
            if is_empty(window) {
                // Read nowhere: nothing to compute (unless a chain needs it).
                return window;
            }
            let ((i0, i1), (j0, j1)) = window;
            ((i0 - k, i1 + k), (j0 - k, j1 + k))
        })
        .collect();
    for i in (1..levels.len()).rev() {
        let Some(d) = chained[i] else { continue };
        if is_empty(need[i]) {
            continue;
        }
        let (a, b) = (&levels[i - 1], &levels[i]);
        let m = (b.step / a.step) as i64;
        let off = (b.origin - a.origin) / a.step as i64;
        let r = reach(d);
        let ((i0, i1), (j0, j1)) = need[i];
        let wanted = (
            (off + i0 * m - r, off + i1 * m + r),
            (off + j0 * m - r, off + j1 * m + r),
        );
        let widened = if is_empty(need[i - 1]) {
            wanted
        } else {
            let ((a0, a1), (b0, b1)) = need[i - 1];
            (
                (a0.min(wanted.0.0), a1.max(wanted.0.1)),
                (b0.min(wanted.1.0), b1.max(wanted.1.1)),
            )
        };
        if windows.is_some() {
            // The level before, per sample: from the image, or the cheaper
            // of that and its own link.
            let before = chained[i - 1].map_or(sample_cost(a.sigma, a.step), |d| {
                sample_cost(a.sigma, a.step).min(sample_cost(d, a.step / levels[i - 2].step))
            });
            let added = area(widened) - area(need[i - 1]);
            let link = sample_cost(d, m as usize) * area(need[i]) + before * added;
            if link > sample_cost(b.sigma, b.step) * area(need[i]) {
                chained[i] = None;
                continue;
            }
        }
        need[i - 1] = widened;
    }
    (chained, need)
}

/// The share of `layout`'s stored samples [`build_levels`] computes with
/// `windows`.
pub(super) fn computed_share(layout: &super::StackLayout, windows: &[Window]) -> f64 {
    let (_, need) = computed_windows(layout, Some(windows));
    let k = if layout.interpolation == super::Interpolation::Cubic {
        CUBIC_TAPS as i64
    } else {
        0
    };
    let (mut held, mut all) = (0.0, 0.0);
    for (l, ((i0, i1), (j0, j1))) in layout.levels.iter().zip(need) {
        let (nx, ny) = (l.nx as i64, l.ny as i64);
        let stored = ((i0 + k).max(0), (i1 - k).min(nx - 1));
        let rows = ((j0 + k).max(0), (j1 - k).min(ny - 1));
        held += area((stored, rows));
        all += (nx * ny) as f64;
    }
    held / all
}

/// Multiply-adds per output sample of correlating with a Gaussian of
/// `sigma` source samples at every `step`-th source sample: its taps down
/// `step` source columns per output, then along the row.
fn sample_cost(sigma: f64, step: usize) -> f64 {
    (2 * reach(sigma) + 1) as f64 * (step + 1) as f64
}

/// Every level of `layout`, stored samples (or B-spline coefficients), by
/// the direct build: a level is the image correlated with its Gaussian, or,
/// where [`chained_sigma`] allows, the level before it correlated with the
/// Gaussian in between (a few samples of that level wide where the level's
/// own would be many, and on its coarser grid when the step doubles). Each
/// level of a chain is computed over a window wide enough for the rest of
/// the chain and cropped.
///
/// With `windows` (one per level, stored-sample indices) a level is
/// computed over its window only (and what the chain after it needs), the
/// rest of its samples left zero: a stack for one filter's reads
/// ([`super::reads`]). A sample computed is the same sum, in the same
/// order, as without windows, but where [`computed_windows`] starts a new
/// chain at a level: that level's samples then agree with the chained ones
/// to the builds' 2e-6 of the image's range.
pub(super) fn build_levels(
    src: &Source<'_>,
    layout: &super::StackLayout,
    windows: Option<&[Window]>,
) -> Vec<Vec<f32>> {
    let levels = &layout.levels;
    let cubic = layout.interpolation == super::Interpolation::Cubic;
    let k = if cubic { CUBIC_TAPS as i64 } else { 0 };
    let c = src.channels;
    let (chained, need) = computed_windows(layout, windows);
    let mut out: Vec<Vec<f32>> = Vec::with_capacity(levels.len());
    // Windows other than the stored samples are computed into one of two
    // buffers, reused (a fresh one costs a page fault per 4 KiB); where the
    // previous level's window is one, `prev_work` says which.
    let mut work: [Vec<f32>; 2] = [Vec::new(), Vec::new()];
    let mut prev_work: Option<usize> = None;
    for (i, l) in levels.iter().enumerate() {
        if is_empty(need[i]) {
            // Read nowhere, and no level after it is built from it.
            out.push(vec![0.0; l.nx * l.ny * c]);
            prev_work = None;
            continue;
        }
        let ((i0, i1), (j0, j1)) = need[i];
        let (ni, nj) = ((i1 - i0 + 1) as usize, (j1 - j0 + 1) as usize);
        let (sx, sy) = (l.nx + 2 * k as usize, l.ny + 2 * k as usize);
        // The stored window itself, or another one to crop.
        let own = (i0, j0, ni, nj) == (0, 0, sx, sy) && !cubic;
        let slot = i % 2;
        let mut dst = if own {
            Vec::new()
        } else {
            std::mem::take(&mut work[slot])
        };
        if let Some(d) = chained[i] {
            let a = &levels[i - 1];
            let ((p0, p1), (q0, q1)) = need[i - 1];
            let m = l.step / a.step;
            let off = (l.origin - a.origin) / a.step as i64;
            let data = match prev_work {
                Some(s) => &work[s],
                None => &out[i - 1],
            };
            // Every read is inside the window (`need` made it so); the
            // border mode is never consulted.
            let from = Source {
                data,
                width: (p1 - p0 + 1) as usize,
                height: (q1 - q0 + 1) as usize,
                channels: c,
                border: Border::Replicate,
            };
            let xs = (off + i0 * m as i64 - p0, ni);
            let ys = (off + j0 * m as i64 - q0, nj);
            correlate_into(&from, d, m, xs, ys, &mut dst);
        } else {
            let step = l.step as i64;
            let xs = (l.origin + i0 * step, ni);
            let ys = (l.origin + j0 * step, nj);
            correlate_into(src, l.sigma, l.step, xs, ys, &mut dst);
        }
        if own {
            out.push(dst);
            prev_work = None;
            continue;
        }
        out.push(store(&dst, ((i0, ni), (j0, nj)), l, c, k));
        work[slot] = dst;
        prev_work = Some(slot);
    }
    out
}

/// A level's stored samples (or, `k > 0`, B-spline coefficients) from the
/// samples `window` computed over `ni x nj` samples from index `(i0, j0)`
/// of its stored grid (its `k` samples past the stored ones on each side
/// included): the stored ones the window holds, zeros elsewhere.
fn store(
    window: &[f32],
    ((i0, ni), (j0, nj)): ((i64, usize), (i64, usize)),
    l: &LevelLayout,
    c: usize,
    k: i64,
) -> Vec<f32> {
    let (values, vx, vy, x0, y0) = if k > 0 {
        // Coefficients of the window's inner samples, from index (i0 + k, j0 + k).
        let coefficients = bspline_coefficients(window, ni, nj, c);
        let ku = k as usize;
        (
            Cow::Owned(coefficients),
            ni - 2 * ku,
            nj - 2 * ku,
            i0 + k,
            j0 + k,
        )
    } else {
        (Cow::Borrowed(window), ni, nj, i0, j0)
    };
    let (nx, ny) = (l.nx as i64, l.ny as i64);
    let (xa, xb) = (x0.max(0), (x0 + vx as i64).min(nx));
    let (ya, yb) = (y0.max(0), (y0 + vy as i64).min(ny));
    let mut level = vec![0.0f32; l.nx * l.ny * c];
    if xa < xb {
        let len = (xb - xa) as usize * c;
        for y in ya..yb {
            let from = (((y - y0) as usize * vx) + (xa - x0) as usize) * c;
            let to = ((y as usize * l.nx) + xa as usize) * c;
            level[to..to + len].copy_from_slice(&values[from..from + len]);
        }
    }
    level
}

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
    let along_row: Vec<usize> = (0..h.len()).map(|d| d * c).collect();
    rows.par_chunks_mut(len)
        .zip(samples.par_chunks(nx * c))
        .for_each(|(out, src)| weighted_sum(&h, src, &along_row, out));
    // Along columns: inner rows.
    let mut out = vec![0.0f32; my * len];
    out.par_chunks_mut(len).enumerate().for_each(|(j, row)| {
        let offsets: Vec<usize> = (0..h.len()).map(|d| (j + d) * len).collect();
        weighted_sum(&h, &rows, &offsets, row);
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stack::refresh::test_images::lcg_noise;
    use crate::stack::{Interpolation, Level, StackLayout, StackOptions, build::build_levels};

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
                        nearest_level: false,
                    };
                    let layout = StackLayout::new(w, h, c, 0.8, 9.0, options).unwrap();
                    assert!(layout.levels.iter().any(|l| l.step > 1));
                    // Chains on one grid and across a pyramid step.
                    let chains: Vec<(usize, usize)> = layout
                        .levels
                        .windows(2)
                        .filter(|p| chained_sigma(&p[0], &p[1]).is_some())
                        .map(|p| (p[0].step, p[1].step))
                        .collect();
                    assert!(chains.iter().any(|(a, b)| a == b), "{chains:?}");
                    if factor > 1.0 {
                        assert!(chains.iter().any(|(a, b)| b == &(2 * a)), "{chains:?}");
                    }
                    let mut fft: Vec<Level> = layout
                        .levels
                        .iter()
                        .map(|l| Level::new(l, vec![0.0; l.nx * l.ny * c]))
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
        assert_eq!(
            choose_by_cost(&layout(4.0, 6.73, 4.0), None),
            StackBuild::Direct
        );
        assert_eq!(
            choose_by_cost(&layout(1.0, 32.0, 2.0), None),
            StackBuild::Direct
        );
        assert_eq!(
            choose_by_cost(&layout(8.0, 32.0, f64::INFINITY), None),
            StackBuild::Fft
        );
    }
}
