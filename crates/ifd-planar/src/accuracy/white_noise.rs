//! The evaluation error a plan is expected to add, computed exactly for
//! bilinear lookups on white noise instead of bounded.
//!
//! # The model
//! A term `t` (weight `w_t`, effective sigma `sigma_t` at scale `s`, offset
//! `c_t`) is, at a pixel `p` rotated by `theta`, the Gaussian
//! `g_{sigma_t}(n - q_t)`, `q_t = p + s R_theta c_t`, correlated with the
//! image. Through the stack it is instead a blend of levels: level `l`
//! (sigma `sigma_l`, stored every `h_l` pixels) read bilinearly at `q_t`
//! is the image correlated with `sum_k lambda_k g_{sigma_l}(n - x_k)`, the
//! level's Gaussian at the four stored samples `x_k` around `q_t` with the
//! bilinear weights `lambda_k`. So the whole evaluation errs by the image
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
//! below `exp(-2 pi^2 sigma^2)`, as [`super::kernel_norm`] assumes). Every
//! part is a product of an `x` and a `y` factor, so each inner product is a
//! product of two 1D sums of at most four Gaussians. Relative to the filter,
//! `||D|| / ||k_s||` with `||k_s||^2` the same kind of sum over the terms.
//!
//! The error depends on the pose: the fractional positions of the `q_t` on
//! their levels' grids (and, on a log-uniform stack, where the scaled sigmas
//! fall between levels). [`expected_error`] averages `||D||^2` over
//! [`POSES`] poses spread evenly (a low-discrepancy sequence) over the
//! rotations, the integer translations (bit-reversed: every pyramid step sees
//! every phase) and, with a
//! per-pixel scale, the scales (log-uniform over the planned range). No
//! pixel is sampled: the same decomposition and plan always give the same
//! number.
//!
//! # Why not the bound
//! The bound ([`super::EvalPlan::error_bound`]) adds the terms' errors as if
//! they all pointed the same way. They do not: a term's error is a high
//! frequency pattern tied to its own position, and neighbouring terms'
//! patterns partly cancel. Measured errors are 2 to 10 times below the
//! bound, so a rule on the bound stored levels finer than the accuracy asked
//! for needed. This sum is the measured error's expectation: filtering white
//! noise lands within a few per cent of it (tested).

use crate::decomposition::Decomposition;
use crate::stack::for_decomposition::evaluated_directly;
use crate::stack::pyramid_step;
use std::f64::consts::{LN_2, PI};

/// Poses averaged over: rotation, translation and (per-pixel scale) scale
/// and level offset.
const POSES: usize = 24;

/// Where the levels a term reads are.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Levels {
    /// At the terms' own (effective) sigmas: one level per term.
    AtSigmas,
    /// Log-uniform, `per_octave` levels per octave: each term blends the two
    /// levels around its sigma, weights linear in `ln sigma`.
    LogUniform {
        /// Levels per octave.
        per_octave: usize,
    },
}

/// The expected relative RMS error on white noise of bilinear lookups
/// (module docs) with pyramid factor `factor`, for scales in
/// `[scale_min, scale_max]` (log-uniform among them), terms that
/// [`evaluated_directly`] with `direct_sigma` being exact.
pub(crate) fn expected_error(
    decomposition: &Decomposition,
    (scale_min, scale_max): (f64, f64),
    factor: f64,
    direct_sigma: f64,
    levels: Levels,
) -> f64 {
    let mut sum = 0.0;
    let mut terms: Vec<Placed> = Vec::with_capacity(decomposition.terms.len());
    let mut parts: Vec<Part> = Vec::with_capacity(3 * decomposition.terms.len());
    for i in 0..POSES {
        let pose = Pose::nth(i);
        let s = scale_min * (scale_max / scale_min).powf(pose.scale);
        let norm2 = kernel_norm2(decomposition, s);
        if !norm2.is_finite() || norm2 <= 0.0 {
            continue;
        }
        place(
            decomposition,
            s,
            &pose,
            factor,
            direct_sigma,
            levels,
            &mut terms,
            &mut parts,
        );
        sum += error2(&terms, &parts) / norm2;
    }
    (sum / POSES as f64).max(0.0).sqrt()
}

/// One pose: fractions in `[0, 1)` from the additive recurrence of the
/// five-dimensional golden ratio (evenly spread in every dimension and
/// every projection).
struct Pose {
    theta: f64,
    tx: f64,
    ty: f64,
    scale: f64,
    offset: f64,
}

impl Pose {
    fn nth(i: usize) -> Self {
        // The root of x^6 = x + 1 (the generalised golden ratio for five
        // dimensions): alpha_d = 1 / phi^d.
        const PHI: f64 = 1.134_724_138_401_519_4;
        let n = i as f64 + 0.5;
        let frac = |d: i32| (n / PHI.powi(d)).fract();
        Self {
            theta: 2.0 * PI * frac(1),
            tx: frac(2),
            ty: frac(3),
            scale: frac(4),
            offset: frac(5),
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

/// A term's error at one pose: its weight, centre and the range of its
/// parts in the part list.
struct Placed {
    qx: f64,
    qy: f64,
    /// How far from `q` its parts reach (the largest step plus a margin of
    /// standard deviations).
    reach: f64,
    sigma_max: f64,
    parts: std::ops::Range<usize>,
}

/// A separable part of a term's error: `coef X(x) Y(y)`, each factor one or
/// two Gaussians of variance `var` at weighted points.
#[derive(Clone, Copy)]
struct Part {
    coef: f64,
    var: f64,
    x: [(f64, f64); 2],
    y: [(f64, f64); 2],
    /// Points used in each factor (1 for the exact Gaussian, 2 for a
    /// bilinear read).
    n: usize,
}

#[allow(clippy::too_many_arguments)]
fn place(
    decomposition: &Decomposition,
    s: f64,
    pose: &Pose,
    factor: f64,
    direct_sigma: f64,
    levels: Levels,
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
            x: [(qx, 1.0), (0.0, 0.0)],
            y: [(qy, 1.0), (0.0, 0.0)],
            n: 1,
        });
        let mut read = |level_sigma: f64, omega: f64| {
            if omega == 0.0 {
                return 0.0;
            }
            let h = pyramid_step(level_sigma, factor) as f64;
            let axis = |q: f64| {
                let x0 = (q / h).floor() * h;
                let phi = (q - x0) / h;
                [(x0, 1.0 - phi), (x0 + h, phi)]
            };
            parts.push(Part {
                coef: t.weight * omega,
                var: level_sigma * level_sigma,
                x: axis(qx),
                y: axis(qy),
                n: 2,
            });
            h
        };
        let (h, sigma_max) = match levels {
            Levels::AtSigmas => (read(sigma, 1.0), sigma),
            Levels::LogUniform { per_octave } => {
                let ln_rho = LN_2 / per_octave.max(1) as f64;
                let u = pose.offset + sigma.ln() / ln_rho;
                let f = u - u.floor();
                let sigma_a = sigma * (-f * ln_rho).exp();
                let sigma_b = sigma_a * ln_rho.exp();
                let ha = read(sigma_a, 1.0 - f);
                let hb = read(sigma_b, f);
                (ha.max(hb), sigma_b)
            }
        };
        terms.push(Placed {
            qx,
            qy,
            reach: h + 10.0 * sigma_max,
            sigma_max,
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
            let d = (a.qx - b.qx).hypot(a.qy - b.qy);
            // Beyond the parts' reach every Gaussian product is below
            // exp(-50) of the largest.
            if d > a.reach + b.reach && d > 10.0 * a.sigma_max.hypot(b.sigma_max) {
                continue;
            }
            let mut pair = 0.0;
            for p in &parts[a.parts.clone()] {
                for q in &parts[b.parts.clone()] {
                    let var = p.var + q.var;
                    pair += p.coef
                        * q.coef
                        * axis_product(&p.x[..p.n], &q.x[..q.n], var)
                        * axis_product(&p.y[..p.n], &q.y[..q.n], var);
                }
            }
            sum += if i == j { pair } else { 2.0 * pair };
        }
    }
    sum
}

/// `sum_{a, b} w_a w_b g(x_a - x_b)` for the 1D Gaussian of variance `var`.
fn axis_product(a: &[(f64, f64)], b: &[(f64, f64)], var: f64) -> f64 {
    let inv = -0.5 / var;
    let mut sum = 0.0;
    for &(xa, wa) in a {
        for &(xb, wb) in b {
            let d = xa - xb;
            sum += wa * wb * (d * d * inv).exp();
        }
    }
    sum / (2.0 * PI * var).sqrt()
}

/// `||k_s||^2`: the squared norm of the sum of the terms' Gaussians at
/// scale `s` (effective sigmas, offsets scaled).
fn kernel_norm2(decomposition: &Decomposition, s: f64) -> f64 {
    let terms = &decomposition.terms;
    let sigmas: Vec<f64> = terms
        .iter()
        .map(|t| decomposition.sampling.effective_sigma(t.sigma, s))
        .collect();
    let mut sum = 0.0;
    for (i, a) in terms.iter().enumerate() {
        for (j, b) in terms.iter().enumerate().skip(i) {
            let v = sigmas[i] * sigmas[i] + sigmas[j] * sigmas[j];
            let d2 = s * s * ((a.x - b.x).powi(2) + (a.y - b.y).powi(2));
            let g = a.weight * b.weight * (-d2 / (2.0 * v)).exp() / (2.0 * PI * v);
            sum += if i == j { g } else { 2.0 * g };
        }
    }
    sum
}
