//! The evaluation error a plan is expected to add on white noise, computed
//! exactly (for the plan's model of its levels) instead of bounded.
//!
//! # The model
//! A term `t` (weight `w_t`, effective sigma `sigma_t` at scale `s`, offset
//! `c_t`) is, at a pixel `p` rotated by `theta`, the Gaussian
//! `g_{sigma_t}(n - q_t)`, `q_t = p + s R_theta c_t`, correlated with the
//! image. Through the stack it is instead a blend of levels: level `l`
//! (sigma `sigma_l`, stored every `h_l` pixels) read at `q_t` is a weighted
//! sum of its stored samples `x_k` around `q_t`, so the image correlated with
//! `sum_k lambda_k g_{sigma_l}(n - x_k)`: bilinear reads weigh the four
//! nearest samples; cubic ones read B-spline coefficients, which is reading
//! the samples with the interpolating cubic spline's weights (16 x 16 of
//! them kept, [`TAPS`]). So the whole evaluation errs by the image
//! correlated with
//!
//! ```text
//! D(n) = sum_t w_t ( sum_l omega_l sum_k lambda_k g_{sigma_l}(n - x_k) - g_{sigma_t}(n - q_t) )
//! ```
//!
//! (`omega_l`: the level blend's weights, one level of weight 1 when the
//! levels are the terms' own sigmas). For white noise of unit variance the
//! expected squared error is `||D||^2`, a sum over pairs of these shifted
//! Gaussians of `<g_a(. - x), g_b(. - y)> = g_{sqrt(a^2 + b^2)}(x - y)`
//! (exact for the continuous Gaussians; the pixel sums differ by aliases
//! below `exp(-2 pi^2 sigma^2)`, as `kernel_norm` assumes). Every part is a
//! product of an `x` and a `y` factor, so each inner product is a product of
//! two 1D sums; two reads on one grid need one exponential per distinct
//! difference of their samples. Relative to the filter, `||D|| / ||k_s||`
//! with `||k_s||^2` the same kind of sum over the terms.
//!
//! The error depends on the pose: the fractional positions of the `q_t` on
//! their levels' grids (and, on a log-uniform stack, where the scaled sigmas
//! fall between its levels, placed as the stack places them). [`WhiteNoise::expected`] averages `||D||^2` over
//! [`POSES`] poses (fewer for hundreds of terms, [`WhiteNoise::new`]) spread
//! evenly (a low-discrepancy sequence) over the
//! rotations (the full turn), the integer translations (bit-reversed: every
//! pyramid step sees every phase) and, with a per-pixel scale, the scales
//! (log-uniform over the planned range).
//! No pixel is sampled: the same decomposition and plan always give the same
//! number.
//!
//! # Why not the bound
//! The bound ([`super::EvalPlan::error_bound`]) adds the terms' errors as if
//! they all pointed the same way. They do not: a term's error is a high
//! frequency pattern tied to its own position, and the patterns of terms
//! apart are nearly uncorrelated, so they add nearly in quadrature (the
//! pairs of overlapping terms make the rest). Measured errors are 2 to 50
//! times below the
//! bound, so a rule on the bound stored levels finer than the accuracy asked
//! for needed. This sum is the measured error's expectation: filtering white
//! noise measures within 15% of it (tested; the rest is the poses'
//! sampling).

use crate::decomposition::Decomposition;
use crate::stack::for_decomposition::evaluated_directly;
use crate::stack::{Interpolation, LevelLocator, log_uniform_sigmas, pyramid_step};
use std::f64::consts::PI;

/// Poses averaged over: rotation, translation and (per-pixel scale)
/// scale.
const POSES: usize = 24;

/// Where the levels a term reads are.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Levels {
    /// At the terms' own (effective) sigmas: one level per term.
    AtSigmas,
    /// Log-uniform, `per_octave` levels per octave: each term blends the two
    /// levels around its sigma, weights linear in `ln sigma`, or (`nearest`)
    /// reads the one nearest it.
    LogUniform {
        /// Levels per octave.
        per_octave: usize,
        /// Each term reads its nearest level alone.
        nearest: bool,
    },
}

/// The sigmas a log-uniform stack for `decomposition` at scales in
/// `[scale_min, scale_max]` spans
/// ([`crate::stack::for_decomposition::sigma_bounds`] of its terms' sigmas).
pub(crate) fn stack_sigmas(
    decomposition: &Decomposition,
    (scale_min, scale_max): (f64, f64),
) -> (f64, f64) {
    let sigma_range = decomposition
        .terms
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), t| {
            (lo.min(t.sigma), hi.max(t.sigma))
        });
    crate::stack::for_decomposition::sigma_bounds(
        decomposition.sampling,
        sigma_range,
        (scale_min, scale_max),
    )
}

/// A decomposition's poses and its filter's norm at each: what every
/// estimate of one planning shares.
pub(crate) struct WhiteNoise<'a> {
    decomposition: &'a Decomposition,
    direct_sigma: f64,
    /// The sigmas a log-uniform stack for the scale range spans
    /// ([`crate::stack::for_decomposition::sigma_bounds`]).
    stack_sigmas: (f64, f64),
    /// Each pose, its scale and `||k_s||^2` there.
    poses: Vec<(Pose, f64, f64)>,
}

impl<'a> WhiteNoise<'a> {
    /// The poses for scales in `[scale_min, scale_max]` (log-uniform among
    /// them), terms that [`evaluated_directly`] with `direct_sigma` being
    /// exact: [`POSES`] of them, fewer for decompositions of many terms
    /// (12 from 65 terms, 8 from 257), whose errors average over the terms
    /// already and whose sums cost more.
    pub(crate) fn new(
        decomposition: &'a Decomposition,
        (scale_min, scale_max): (f64, f64),
        direct_sigma: f64,
    ) -> Self {
        let n = match decomposition.terms.len() {
            0..=64 => POSES,
            65..=256 => POSES / 2,
            _ => POSES / 3,
        };
        // One scale: one norm for every pose.
        let fixed = (scale_min == scale_max).then(|| kernel_norm2(decomposition, scale_min));
        let poses = (0..n)
            .map(|i| {
                let pose = Pose::nth(i, n);
                let s = scale_min * (scale_max / scale_min).powf(pose.scale);
                let norm2 = fixed.unwrap_or_else(|| kernel_norm2(decomposition, s));
                (pose, s, norm2)
            })
            .collect();
        Self {
            decomposition,
            direct_sigma,
            stack_sigmas: stack_sigmas(decomposition, (scale_min, scale_max)),
            poses,
        }
    }

    /// The same, for a log-uniform stack spanning `sigmas` (a stack shared
    /// with other decompositions: its levels lie where the whole range puts
    /// them, not where this decomposition's own would).
    pub(crate) fn with_stack_sigmas(mut self, sigmas: (f64, f64)) -> Self {
        self.stack_sigmas = sigmas;
        self
    }

    /// The terms read through the stack (not [`evaluated_directly`]) at
    /// the first pose's scale.
    pub(crate) fn terms_read(&self) -> usize {
        let d = self.decomposition;
        let s = self.poses.first().map_or(1.0, |p| p.1);
        d.terms
            .iter()
            .filter(|t| !evaluated_directly(d.sampling, t, s, self.direct_sigma))
            .count()
    }

    /// The sigmas of the log-uniform stack with `per_octave` levels per
    /// octave that the estimate places.
    pub(crate) fn level_sigmas(&self, per_octave: usize) -> Vec<f64> {
        log_uniform_sigmas(self.stack_sigmas.0, self.stack_sigmas.1, per_octave)
    }

    /// The expected relative RMS error on white noise of lookups with
    /// `interpolation` (module docs) at pyramid factor `factor` from
    /// `levels` (the poses on rayon's threads, summed in order).
    #[cfg(test)]
    pub(crate) fn expected(&self, read: (Interpolation, f64), levels: Levels) -> f64 {
        self.screened(read, levels, None).0
    }

    /// [`Self::expected`], or, when `screen` is a budget and every
    /// [`SCREEN_STRIDE`]-th pose alone (a subset spread like the whole)
    /// puts the estimate above [`SCREEN_MARGIN`] times it, that subset's
    /// mean: a candidate far over its budget is rejected at a quarter of
    /// the work. The flag says which (`true`: every pose, the same bits as
    /// [`Self::expected`]). A screened value always exceeds the budget, so
    /// a comparison with it decides as the full estimate would unless the
    /// subset errs by more than the margin (on fitted decompositions,
    /// measured: at most 8% above the full estimate and 27% below,
    /// `screens_agree_with_every_pose`).
    pub(crate) fn screened(
        &self,
        (interpolation, factor): (Interpolation, f64),
        levels: Levels,
        screen: Option<f64>,
    ) -> (f64, bool) {
        use rayon::prelude::*;
        let levels = match levels {
            Levels::AtSigmas => Placement::AtSigmas,
            Levels::LogUniform {
                per_octave,
                nearest,
            } => Placement::log_uniform(self.stack_sigmas, per_octave, nearest),
        };
        // Each pose's error relative to its norm (`None`: a pose without a
        // norm, left out), in pose order.
        let each = |poses: Vec<usize>| -> Vec<(usize, Option<f64>)> {
            poses
                .into_par_iter()
                .map_init(
                    || (Vec::new(), Vec::new()),
                    |(terms, parts), i| {
                        let (pose, s, norm2) = &self.poses[i];
                        if !(norm2.is_finite() && *norm2 > 0.0) {
                            return (i, None);
                        }
                        place(
                            self.decomposition,
                            *s,
                            pose,
                            (interpolation, factor),
                            self.direct_sigma,
                            &levels,
                            terms,
                            parts,
                        );
                        let err2 = if grid_cost(parts) < pair_cost(terms, parts) {
                            // (grid_cost is infinite past MAX_GRID_CELLS)
                            error2_on_grid(parts)
                        } else {
                            error2(terms, parts)
                        };
                        (i, Some(err2 / norm2))
                    },
                )
                .collect()
        };
        // Summed in pose order: the same bits on any number of threads
        // (tiles and chunks of one image plan alike). No pose with a norm,
        // or a sum that is not a number (absurd scales through the API):
        // infinite, never within a budget.
        let mean = |values: &[(usize, Option<f64>)]| {
            let valid: Vec<f64> = values.iter().filter_map(|&(_, v)| v).collect();
            let mean = valid.iter().sum::<f64>() / valid.len() as f64;
            if mean.is_nan() {
                f64::INFINITY
            } else {
                mean.max(0.0).sqrt()
            }
        };
        let n = self.poses.len();
        let subset: Vec<usize> = (0..n).step_by(SCREEN_STRIDE).collect();
        let mut values = Vec::new();
        if let Some(budget) = screen
            && subset.len() >= SCREEN_LEAST
        {
            values = each(subset);
            let partial = mean(&values);
            if partial.is_finite() && partial > SCREEN_MARGIN * budget {
                return (partial, false);
            }
        }
        let rest: Vec<usize> = (0..n)
            .filter(|i| values.is_empty() || i % SCREEN_STRIDE != 0)
            .collect();
        values.extend(each(rest));
        values.sort_unstable_by_key(|&(i, _)| i);
        (mean(&values), true)
    }
}

/// A screen ([`WhiteNoise::screened`]) averages every `SCREEN_STRIDE`-th
/// pose: 6 of [`POSES`].
const SCREEN_STRIDE: usize = 4;
/// Fewer poses than this (decompositions of more than 64 terms, whose
/// poses are few already) are not screened.
const SCREEN_LEAST: usize = 6;
/// How far over its budget a screened estimate must be to reject a
/// candidate without the rest of its poses.
pub(crate) const SCREEN_MARGIN: f64 = 1.3;
/// How far below the full estimate a screen may fall (measured: to 0.73 of
/// it, `screens_agree_with_every_pose`): a stall of a screened candidate is
/// decided on full estimates from `0.95 / STALL_SLACK` of the coarser one's.
pub(crate) const STALL_SLACK: f64 = 1.6;

/// One pose: fractions in `[0, 1)` from the additive recurrence of the
/// five-dimensional golden ratio, four of its dimensions (evenly spread in
/// every dimension and every projection).
struct Pose {
    theta: f64,
    tx: f64,
    ty: f64,
    scale: f64,
}

impl Pose {
    /// The `i`-th of `n` poses: rotation and translation from a
    /// low-discrepancy sequence; the scale (the fraction of the scale
    /// range, in `ln s`) at `(i + 1/2) / n`, evenly spaced: where a term
    /// falls between two levels repeats with `ln s` (every level spacing),
    /// and equal steps in `ln s` sample that period more evenly than the
    /// sequence's (the error of reading the nearest level is a sawtooth of
    /// it).
    fn nth(i: usize, n: usize) -> Self {
        // The root of x^6 = x + 1 (the generalised golden ratio for five
        // dimensions): alpha_d = 1 / phi^d.
        const PHI: f64 = 1.134_724_138_401_519_4;
        let k = i as f64 + 0.5;
        let frac = |d: i32| (k / PHI.powi(d)).fract();
        Self {
            theta: 2.0 * PI * frac(1),
            tx: frac(2),
            ty: frac(3),
            scale: k / n as f64,
        }
    }
}

/// An integer translation from a fraction in `[0, 1)`, spread over every
/// pyramid step: the fraction's leading 12 bits reversed, so that its
/// remainders modulo each power of two (what a step of that size sees) are
/// as evenly spread as the fraction itself (steps are at most
/// `2^MAX_PYRAMID_LEVEL = 4096`).
fn translation(fraction: f64) -> f64 {
    let bits = (fraction * 4096.0) as u32 & 0xfff;
    f64::from(bits.reverse_bits() >> 20)
}

/// A term's error at one pose: its centre and the range of its parts in the
/// part list.
struct Placed {
    qx: f64,
    qy: f64,
    /// How far from `q` its parts reach (their points' extent plus ten
    /// standard deviations: beyond it every Gaussian product is below
    /// `exp(-50)` of the largest).
    reach: f64,
    parts: std::ops::Range<usize>,
}

/// Points per axis of a cubic read: the interpolating B-spline's weights on
/// the samples (its cardinal function) decay as `0.268^|j|`; beyond eight
/// samples each side they weigh below `2e-5` together. The kept weights are
/// scaled to sum to one (so constants stay exact); what the cut leaves
/// alternates in sign from sample to sample, a pattern at the sampling's
/// Nyquist frequency that the level's Gaussian (two samples wide or more)
/// has already removed from the signal.
const TAPS: usize = 16;

/// One factor of a part: Gaussians at `start + j step` (`j < n`) weighted
/// `w[j]`.
#[derive(Clone, Copy)]
struct Axis {
    start: f64,
    step: f64,
    n: usize,
    w: [f64; TAPS],
}

impl Axis {
    /// The exact Gaussian's single point.
    fn point(q: f64) -> Self {
        let mut w = [0.0; TAPS];
        w[0] = 1.0;
        Self {
            start: q,
            step: 0.0,
            n: 1,
            w,
        }
    }

    /// The samples a read at `q` of a level stored every `h` weighs, and
    /// their weights.
    fn read(q: f64, h: f64, interpolation: Interpolation) -> Self {
        let m0 = (q / h).floor();
        let phi = q / h - m0;
        let mut w = [0.0; TAPS];
        match interpolation {
            Interpolation::Linear => {
                (w[0], w[1]) = (1.0 - phi, phi);
                Self {
                    start: m0 * h,
                    step: h,
                    n: 2,
                    w,
                }
            }
            Interpolation::Cubic => {
                // Sample m0 + j, j = 1 - TAPS / 2 ..= TAPS / 2, weighs the
                // cardinal cubic spline at phi - j.
                let first = 1 - (TAPS / 2) as i64;
                for (i, wi) in w.iter_mut().enumerate() {
                    *wi = cardinal_cubic(phi - (first + i as i64) as f64);
                }
                let sum: f64 = w.iter().sum();
                for wi in &mut w {
                    *wi /= sum;
                }
                Self {
                    start: (m0 + first as f64) * h,
                    step: h,
                    n: TAPS,
                    w,
                }
            }
        }
    }

    /// How far its points reach from `q`.
    fn extent(&self, q: f64) -> f64 {
        let last = self.start + (self.n - 1) as f64 * self.step;
        (q - self.start).abs().max((last - q).abs())
    }
}

/// A separable part of a term's error: `coef X(x) Y(y)`, Gaussians of
/// variance `var`.
#[derive(Clone, Copy)]
struct Part {
    coef: f64,
    var: f64,
    x: Axis,
    y: Axis,
}

/// The cubic B-spline `beta3`.
fn bspline3(x: f64) -> f64 {
    let a = x.abs();
    if a < 1.0 {
        2.0 / 3.0 - a * a + 0.5 * a * a * a
    } else if a < 2.0 {
        (2.0 - a).powi(3) / 6.0
    } else {
        0.0
    }
}

/// The interpolating cubic spline's weight on a sample `x` away:
/// `sum_k beta3(x - k) p_k` with `p_k = sqrt(3) (sqrt(3) - 2)^|k|`, the
/// inverse of the sampled B-spline `(1/6, 2/3, 1/6)` (the stack's
/// coefficient prefilter), so that reading coefficients with `beta3` is
/// reading samples with this.
fn cardinal_cubic(x: f64) -> f64 {
    let z = 3f64.sqrt() - 2.0;
    let k0 = (x - 2.0).ceil() as i64;
    (k0..=k0 + 4)
        .map(|k| bspline3(x - k as f64) * 3f64.sqrt() * z.powi(k.unsigned_abs() as i32))
        .sum()
}

/// Where [`place`] puts the levels a term reads.
#[derive(Clone, Debug)]
enum Placement {
    /// One level at the term's own sigma.
    AtSigmas,
    /// The levels of a log-uniform stack, located as the stack's lookups
    /// locate them.
    LogUniform {
        sigmas: Vec<f64>,
        locator: LevelLocator,
    },
}

impl Placement {
    /// The levels a log-uniform stack over `(lo, hi)` with `per_octave`
    /// levels per octave stores ([`log_uniform_sigmas`]), read at the
    /// nearest level or not.
    fn log_uniform((lo, hi): (f64, f64), per_octave: usize, nearest: bool) -> Self {
        let sigmas = log_uniform_sigmas(lo, hi, per_octave);
        let locator = LevelLocator::new(&sigmas, true, nearest);
        Self::LogUniform { sigmas, locator }
    }
}

#[allow(clippy::too_many_arguments)]
fn place(
    decomposition: &Decomposition,
    s: f64,
    pose: &Pose,
    (interpolation, factor): (Interpolation, f64),
    direct_sigma: f64,
    levels: &Placement,
    terms: &mut Vec<Placed>,
    parts: &mut Vec<Part>,
) {
    terms.clear();
    parts.clear();
    let (sin, cos) = pose.theta.sin_cos();
    let (px, py) = (translation(pose.tx), translation(pose.ty));
    for t in &decomposition.terms {
        if evaluated_directly(decomposition.sampling, t, s, direct_sigma) {
            continue;
        }
        let sigma = decomposition.sampling.effective_sigma(t.sigma, s);
        let (qx, qy) = (
            px + s * (cos * t.x - sin * t.y),
            py + s * (sin * t.x + cos * t.y),
        );
        let start = parts.len();
        parts.push(Part {
            coef: -t.weight,
            var: sigma * sigma,
            x: Axis::point(qx),
            y: Axis::point(qy),
        });
        let mut reach: f64 = 10.0 * sigma;
        let mut read = |level_sigma: f64, omega: f64| {
            if omega == 0.0 {
                return;
            }
            let h = pyramid_step(level_sigma, factor) as f64;
            let (x, y) = (
                Axis::read(qx, h, interpolation),
                Axis::read(qy, h, interpolation),
            );
            reach = reach.max(x.extent(qx).hypot(y.extent(qy)) + 10.0 * level_sigma);
            parts.push(Part {
                coef: t.weight * omega,
                var: level_sigma * level_sigma,
                x,
                y,
            });
        };
        match levels {
            Placement::AtSigmas => read(sigma, 1.0),
            Placement::LogUniform { sigmas, locator } => {
                // The bracketing levels, weights linear in ln sigma (`wb`
                // zero on a level, and off the half-way point when the
                // stack is read at the nearest level), clamped to the stack.
                let (a, b, wa, wb) = locator.locate(sigma);
                read(sigmas[a], f64::from(wa));
                read(sigmas[b], f64::from(wb));
            }
        }
        terms.push(Placed {
            qx,
            qy,
            reach,
            parts: start..parts.len(),
        });
    }
}

/// `||D||^2` (module docs): the inner products of every pair of parts of
/// terms close enough to overlap.
fn error2(terms: &[Placed], parts: &[Part]) -> f64 {
    let mut sum = 0.0;
    for (i, a) in terms.iter().enumerate() {
        for (j, b) in terms.iter().enumerate().skip(i) {
            if (a.qx - b.qx).hypot(a.qy - b.qy) > a.reach + b.reach {
                continue;
            }
            let mut pair = 0.0;
            for p in &parts[a.parts.clone()] {
                for q in &parts[b.parts.clone()] {
                    let var = p.var + q.var;
                    pair += p.coef
                        * q.coef
                        * axis_product(&p.x, &q.x, var)
                        * axis_product(&p.y, &q.y, var);
                }
            }
            sum += if i == j { pair } else { 2.0 * pair };
        }
    }
    sum
}

/// Multiply-adds of [`error2`] (an exponential counted as eight), every
/// pair of terms taken as near: the pair sums grow with the square of the
/// terms.
fn pair_cost(terms: &[Placed], parts: &[Part]) -> f64 {
    let per_term = parts.len() as f64 / terms.len().max(1) as f64;
    let per_axis: f64 = parts
        .iter()
        .map(|p| (p.x.n * p.x.n) as f64 + 8.0 * (2 * p.x.n) as f64)
        .sum::<f64>()
        / parts.len().max(1) as f64;
    0.5 * (terms.len() as f64).powi(2) * per_term * per_term * 2.0 * per_axis
}

/// The most pixels [`error2_on_grid`] allocates (32 MiB of `f64` per
/// thread); past it the pair sums, whose cost does not grow with the scale.
const MAX_GRID_CELLS: f64 = 4_194_304.0;

/// Lanes of a vector that [`grid_cost`] counts [`error2_on_grid`]'s window
/// sums in: they run in AVX-512 or AVX2 vectors (the baseline's are
/// two wide, where the grid costs more than counted; the choice is the same
/// on every machine, so are the bits).
const GRID_LANES: f64 = 4.0;

/// Multiply-adds of [`error2_on_grid`]: each part's window (in vectors of
/// [`GRID_LANES`]) and its factors (the Gaussians by a recurrence, then one
/// multiply-add per sample read), and the grid;
/// infinite for a grid of more than [`MAX_GRID_CELLS`] (or positions that
/// are not numbers).
fn grid_cost(parts: &[Part]) -> f64 {
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for p in parts {
        let r = GRID_SIGMAS * p.var.sqrt() + 1.0;
        x0 = x0.min(p.x.start - r);
        x1 = x1.max(p.x.start + p.x.span() + r);
        y0 = y0.min(p.y.start - r);
        y1 = y1.max(p.y.start + p.y.span() + r);
    }
    let area = (x1 - x0 + 1.0) * (y1 - y0 + 1.0);
    if area.is_nan() || area > MAX_GRID_CELLS {
        return f64::INFINITY;
    }
    let windows: f64 = parts
        .iter()
        .map(|p| {
            let r = 2.0 * GRID_SIGMAS * p.var.sqrt();
            let (lx, ly) = (p.x.span() + r, p.y.span() + r);
            lx * ly / GRID_LANES + lx * p.x.n as f64 + ly * p.y.n as f64
        })
        .sum();
    windows + area
}

/// Standard deviations a part's Gaussians are summed to on the grid: the
/// tails beyond weigh `exp(-18) = 1.5e-8` of the peak, which moves an
/// error of `1e-4` of the filter by about `1e-4` of itself.
const GRID_SIGMAS: f64 = 6.0;

impl Axis {
    /// Distance from the first point to the last.
    fn span(&self) -> f64 {
        (self.n - 1) as f64 * self.step
    }

    /// The pixels `lo..=hi` its Gaussians (standard deviation `sigma`)
    /// reach within [`GRID_SIGMAS`].
    fn window(&self, sigma: f64) -> (i64, i64) {
        let r = GRID_SIGMAS * sigma;
        (
            (self.start - r).floor() as i64,
            (self.start + self.span() + r).ceil() as i64,
        )
    }

    /// The factor at pixels `lo..lo + out.len()`: `sum_j w_j g(x - x_j)`.
    /// Reads (points on the integer grid) take the Gaussian from a table of
    /// integer offsets; the exact Gaussian (one fractional point) is
    /// evaluated at each pixel.
    #[inline(always)]
    #[expect(
        clippy::inline_always,
        reason = "compiled into each of run_vectorized's targets, for its instruction set"
    )]
    fn fill(&self, sigma: f64, lo: i64, out: &mut [f64]) {
        let inv = -0.5 / (sigma * sigma);
        let norm = 1.0 / ((2.0 * PI).sqrt() * sigma);
        if self.n == 1 {
            gaussian_run(lo as f64 - self.start, inv, norm, out);
            return;
        }
        // Offsets from the first point's pixel: -reach ..= reach + span.
        let first = self.start.round() as i64;
        let step = self.step.round() as i64;
        let len = out.len() as i64;
        let (kmin, kmax) = (
            lo - first - (self.n as i64 - 1) * step,
            lo + len - 1 - first,
        );
        let mut table = vec![0.0; (kmax - kmin + 1) as usize];
        gaussian_run(kmin as f64, inv, norm, &mut table);
        // out[i] = sum_j w_j table[lo + i - first - j step - kmin], summed
        // in j order: one contiguous run of the table per sample.
        out.fill(0.0);
        let len = out.len();
        for j in 0..self.n {
            let at = (lo - first - j as i64 * step - kmin) as usize;
            let w = self.w[j];
            for (o, &t) in out.iter_mut().zip(&table[at..at + len]) {
                *o += w * t;
            }
        }
    }
}

/// `out[i] = norm exp(inv (d0 + i)^2)`, by the recurrence of successive
/// ratios (`e_{i+1} = e_i r_i`, `r_{i+1} = r_i exp(2 inv)`): three
/// exponentials per [`RUN_ANCHOR`] samples instead of one each, within
/// about `1e-13` of them relative (re-anchored on an exact exponential
/// every [`RUN_ANCHOR`]). A run whose anchor or ratios leave the range
/// where they are normal numbers (Gaussians narrower than about 0.05
/// samples, or an anchor more than about 35 standard deviations out,
/// whose recurrence could not climb back to the peak) takes the
/// exponentials one by one.
#[inline(always)]
#[allow(
    clippy::inline_always,
    reason = "compiled into each of run_vectorized's targets, for its instruction set"
)]
fn gaussian_run(d0: f64, inv: f64, norm: f64, out: &mut [f64]) {
    // exp of at most this (in magnitude) is a normal number
    const NORMAL: f64 = 600.0;
    let c = (2.0 * inv).exp();
    for (k, chunk) in out.chunks_mut(RUN_ANCHOR).enumerate() {
        let d = d0 + (k * RUN_ANCHOR) as f64;
        let (ea, ra) = (d * d * inv, (2.0 * d + 1.0) * inv);
        if !(ea.abs() <= NORMAL && ra.abs() <= NORMAL && 2.0 * inv.abs() <= NORMAL) {
            for (i, o) in chunk.iter_mut().enumerate() {
                let x = d + i as f64;
                *o = norm * (x * x * inv).exp();
            }
            continue;
        }
        let mut e = norm * ea.exp();
        let mut r = ra.exp();
        for o in chunk {
            *o = e;
            e *= r;
            r *= c;
        }
    }
}

/// Samples per exact exponential in [`gaussian_run`].
const RUN_ANCHOR: usize = 32;

/// The pixels every part's window covers: `(x0, x1, y0, y1)`, inclusive.
fn bounds(parts: &[Part]) -> Option<(i64, i64, i64, i64)> {
    parts.iter().fold(None, |acc, p| {
        let sigma = p.var.sqrt();
        let ((a, b), (c, d)) = (p.x.window(sigma), p.y.window(sigma));
        Some(match acc {
            None => (a, b, c, d),
            Some((x0, x1, y0, y1)) => (x0.min(a), x1.max(b), y0.min(c), y1.max(d)),
        })
    })
}

/// `||D||^2` summed over the pixels: every part added to a grid as the
/// outer product of its two factors (the pixel sums the filter computes, so
/// exact where the pair sums' integrals approximate them, below about a
/// pixel of sigma). Its cost grows with the terms, not their square: the
/// way for decompositions of many overlapping terms, or cubic reads.
///
/// Its loops are plain lane-wise arithmetic, run by
/// [`ifd_simd::run_vectorized`] compiled for AVX-512, AVX2 or the baseline;
/// without fused multiply-adds (Rust never contracts them) the three give
/// the same bits.
fn error2_on_grid(parts: &[Part]) -> f64 {
    ifd_simd::run_vectorized(GridError(parts))
}

/// [`error2_on_grid`] as a [`ifd_simd::VectorKernel`].
struct GridError<'a>(&'a [Part]);

impl ifd_simd::VectorKernel for GridError<'_> {
    type Output = f64;
    #[inline(always)]
    #[expect(
        clippy::inline_always,
        reason = "the kernel is compiled into each target of `run_vectorized`"
    )]
    fn run(self) -> f64 {
        error2_on_grid_body(self.0)
    }
}

#[inline(always)]
#[expect(
    clippy::inline_always,
    reason = "compiled into each of run_vectorized's targets, for its instruction set"
)]
fn error2_on_grid_body(parts: &[Part]) -> f64 {
    let Some((x0, x1, y0, y1)) = bounds(parts) else {
        return 0.0;
    };
    let w = (x1 - x0 + 1) as usize;
    let mut grid = vec![0.0; w * (y1 - y0 + 1) as usize];
    let (mut fx, mut fy) = (Vec::new(), Vec::new());
    for p in parts {
        let sigma = p.var.sqrt();
        let ((a, b), (c, d)) = (p.x.window(sigma), p.y.window(sigma));
        fx.resize((b - a + 1) as usize, 0.0);
        fy.resize((d - c + 1) as usize, 0.0);
        p.x.fill(sigma, a, &mut fx);
        p.y.fill(sigma, c, &mut fy);
        for (j, &vy) in fy.iter().enumerate() {
            let row = (c - y0) as usize + j;
            let at = row * w + (a - x0) as usize;
            let cy = p.coef * vy;
            for (g, &vx) in grid[at..at + fx.len()].iter_mut().zip(&fx) {
                *g += cy * vx;
            }
        }
    }
    // The squares in eight running sums (lanes of a vector), then those.
    let mut lanes = [0.0; 8];
    let chunks = grid.chunks_exact(8);
    let tail: f64 = chunks.remainder().iter().map(|v| v * v).sum();
    for c in chunks {
        for (l, v) in lanes.iter_mut().zip(c) {
            *l += v * v;
        }
    }
    lanes.iter().sum::<f64>() + tail
}

/// `sum_{j, k} w_j w'_k g(x_j - x'_k)` for the 1D Gaussian of variance
/// `var`. Two reads on one grid see only `n + n' - 1` distinct differences
/// (`start - start' + (j - k) step`): one exponential each.
fn axis_product(a: &Axis, b: &Axis, var: f64) -> f64 {
    let inv = -0.5 / var;
    let g = |d: f64| (d * d * inv).exp();
    let mut sum = 0.0;
    if a.n > 1 && b.n > 1 && a.step == b.step {
        let delta = a.start - b.start;
        let mut e = [0.0; 2 * TAPS - 1];
        for (m, em) in e.iter_mut().enumerate().take(a.n + b.n - 1) {
            *em = g(delta + (m as f64 - (b.n - 1) as f64) * a.step);
        }
        for (j, wa) in a.w[..a.n].iter().enumerate() {
            let row = &e[j..j + b.n];
            // e[j + (b.n - 1) - k] for k = 0..b.n: the row reversed.
            let inner: f64 = b.w[..b.n]
                .iter()
                .zip(row.iter().rev())
                .map(|(wb, ek)| wb * ek)
                .sum();
            sum += wa * inner;
        }
    } else {
        for j in 0..a.n {
            let xa = a.start + j as f64 * a.step;
            for k in 0..b.n {
                sum += a.w[j] * b.w[k] * g(xa - (b.start + k as f64 * b.step));
            }
        }
    }
    sum / (2.0 * PI * var).sqrt()
}

/// `||k_s||^2`: the squared norm of the sum of the terms' Gaussians at
/// scale `s` (effective sigmas, offsets scaled).
fn kernel_norm2(decomposition: &Decomposition, s: f64) -> f64 {
    let sampling = decomposition.sampling;
    super::norm::gaussian_sum_norm2(&decomposition.terms, s, |sigma| {
        sampling.effective_sigma(sigma, s)
    })
}

#[cfg(test)]
#[path = "white_noise_tests.rs"]
mod tests;
