//! The error of one read of a stack: a lookup of a level at a fractional
//! position ([`lookup_error`]) and a sigma between levels, blended
//! ([`level_blend_error`]) or read at the nearest ([`nearest_level_error`]).

use crate::stack::Interpolation;

/// Relative RMS error of one lookup along one axis (see the module docs) for
/// a level whose Gaussian has `r` stored samples of standard deviation,
/// averaged over the fractional phase, for white-noise input.
///
/// ```
/// use ifd_planar::{Interpolation, internals::accuracy::lookup_error};
/// let lin = lookup_error(Interpolation::Linear, 2.0);
/// let cub = lookup_error(Interpolation::Cubic, 2.0);
/// assert!((lin - 0.0195).abs() < 5e-4 && (cub - 3.7e-4).abs() < 3e-5);
/// ```
#[must_use]
pub fn lookup_error(interpolation: Interpolation, r: f64) -> f64 {
    use std::f64::consts::PI;
    let table = frequency_table();
    let mut num = 0.0;
    let mut den = 0.0;
    for i in 0..NU {
        // Midpoints of [-1/2, 1/2]; the integrand is even in nu.
        let nu = (i as f64 + 0.5) / NU as f64 - 0.5;
        let g: f64 = (-3..=3)
            .map(|k| (-2.0 * PI * PI * r * r * (nu + f64::from(k)).powi(2)).exp())
            .sum();
        let g2 = g * g;
        den += g2 * PHASES as f64;
        let taps = &table.taps[i];
        for p in 0..PHASES {
            let phi = p as f64 / PHASES as f64;
            let (re, im) = match interpolation {
                Interpolation::Linear => {
                    let (s, c) = taps[2];
                    (1.0 - phi + phi * c, phi * s)
                }
                Interpolation::Cubic => {
                    let w = crate::stack::bspline_weights(phi as f32);
                    let (mut re, mut im) = (0.0, 0.0);
                    for (&(s, c), wk) in taps.iter().zip(w) {
                        re += f64::from(wk) * c;
                        im += f64::from(wk) * s;
                    }
                    let b0 = 2.0 / 3.0 + table.cos[i] / 3.0;
                    (re / b0, im / b0)
                }
            };
            let (s, c) = table.shift[i * PHASES + p];
            num += g2 * ((re - c).powi(2) + (im - s).powi(2));
        }
    }
    (num / den).sqrt()
}

/// [`lookup_error`]'s frequencies (midpoints of `[-1/2, 1/2]`).
const NU: usize = 256;
/// [`lookup_error`]'s fractional phases.
const PHASES: usize = 16;

/// The sines and cosines [`lookup_error`] reads, which do not depend on
/// `r`: computed once per process (a plan tries a few dozen `r`).
struct FrequencyTable {
    /// `sin_cos(2 pi nu k)` for the interpolation taps `k = -1..=2`, per
    /// frequency.
    taps: Vec<[(f64, f64); 4]>,
    /// `sin_cos(2 pi nu phi)`, per frequency and phase.
    shift: Vec<(f64, f64)>,
    /// `cos(2 pi nu)` (libm's `cos`, as the cubic prefilter's gain was
    /// always computed), per frequency.
    cos: Vec<f64>,
}

fn frequency_table() -> &'static FrequencyTable {
    use std::f64::consts::TAU;
    static TABLE: std::sync::OnceLock<FrequencyTable> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        let nus = (0..NU).map(|i| (i as f64 + 0.5) / NU as f64 - 0.5);
        FrequencyTable {
            taps: nus
                .clone()
                .map(|nu| [-1.0, 0.0, 1.0, 2.0].map(|k: f64| (TAU * nu * k).sin_cos()))
                .collect(),
            cos: nus.clone().map(|nu| (TAU * nu).cos()).collect(),
            shift: nus
                .flat_map(|nu| {
                    (0..PHASES).map(move |p| (TAU * nu * (p as f64 / PHASES as f64)).sin_cos())
                })
                .collect(),
        }
    })
}

/// Relative RMS error of reading a Gaussian between two levels of a
/// log-uniform stack with `samples_per_octave` levels per octave, by the
/// stack's blend (weights linear in `ln sigma` between the bracketing
/// levels `sigma_a` and `sigma_b = rho sigma_a`, `rho = 2^(1 / n)`),
/// averaged over the position between them as [`lookup_error`] averages
/// over the phase. Exact for 2D normalised Gaussians: with
/// `<g_a, g_b> = 1 / (2 pi (sigma_a^2 + sigma_b^2))`,
///
/// ```text
/// e(f)^2 = ||w_a g_a + w_b g_b - g_sigma||^2 / ||g_sigma||^2,  sigma = sigma_a rho^f
/// ```
///
/// expands into six such inner products (scale-invariant: it depends on
/// `rho` and `f` alone); the mean of `e(f)^2` is taken at 64 midpoints.
/// 0.77% at 4 levels per octave, 1.4% at 3, 3.0% at 2, 12% at 1 (the
/// largest over `f`, half-way: 1.06%, 1.9%, 4.2%, 16%).
///
/// ```
/// use ifd_planar::internals::accuracy::level_blend_error;
/// assert!((level_blend_error(4) - 0.0077).abs() < 1e-4);
/// assert!((level_blend_error(2) - 0.0305).abs() < 3e-4);
/// ```
#[must_use]
pub fn level_blend_error(samples_per_octave: usize) -> f64 {
    const POSITIONS: usize = 64;
    let rho = 2f64.powf(1.0 / samples_per_octave.max(1) as f64);
    let mean_square = (0..POSITIONS)
        .map(|i| blend_error_at(rho, (i as f64 + 0.5) / POSITIONS as f64).powi(2))
        .sum::<f64>()
        / POSITIONS as f64;
    mean_square.sqrt()
}

/// Relative RMS error of reading a Gaussian from the level of a
/// log-uniform stack (`samples_per_octave` levels per octave) nearest it in
/// `ln sigma` alone
/// ([`StackOptions::nearest_level`](crate::StackOptions::nearest_level)),
/// averaged over the position between two levels as [`level_blend_error`]
/// averages: the sigma
/// is off by up to a factor `2^(1 / 2n)`. 14% at 2 levels per octave, 7.1%
/// at 4, 4.7% at 6, 3.5% at 8 (the largest, half-way: 27%, 13%, 8.4%,
/// 6.3%); for small offsets `sqrt(2)` times the relative sigma offset.
///
/// ```
/// use ifd_planar::internals::accuracy::{level_blend_error, nearest_level_error};
/// assert!((nearest_level_error(4) - 0.071).abs() < 1e-3);
/// // blending two levels is far more accurate than reading the nearest
/// assert!(nearest_level_error(8) > level_blend_error(2));
/// ```
#[must_use]
pub fn nearest_level_error(samples_per_octave: usize) -> f64 {
    const POSITIONS: usize = 64;
    let rho = 2f64.powf(1.0 / samples_per_octave.max(1) as f64);
    let mean_square = (0..POSITIONS)
        .map(|i| {
            let f = (i as f64 + 0.5) / POSITIONS as f64;
            error_at(rho, f, if f < 0.5 { (1.0, 0.0) } else { (0.0, 1.0) }).powi(2)
        })
        .sum::<f64>()
        / POSITIONS as f64;
    mean_square.sqrt()
}

/// [`level_blend_error`]'s `e(f)` for levels `rho` apart.
fn blend_error_at(rho: f64, f: f64) -> f64 {
    error_at(rho, f, (1.0 - f, f))
}

/// The relative error of `wa g_1 + wb g_rho` for `g_{rho^f}`.
fn error_at(rho: f64, f: f64, (wa, wb): (f64, f64)) -> f64 {
    use std::f64::consts::PI;
    let dot = |a: f64, b: f64| 1.0 / (2.0 * PI * (a * a + b * b));
    let (sa, sb, s) = (1.0, rho, rho.powf(f));
    let e2 =
        wa * wa * dot(sa, sa) + wb * wb * dot(sb, sb) + dot(s, s) + 2.0 * wa * wb * dot(sa, sb)
            - 2.0 * wa * dot(sa, s)
            - 2.0 * wb * dot(sb, s);
    (e2.max(0.0) / dot(s, s)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lookup_error_falls_with_the_right_order() {
        // Doubling r divides the error by 4 (bilinear) and 16 (cubic).
        for (interp, order) in [(Interpolation::Linear, 2.0), (Interpolation::Cubic, 4.0)] {
            let ratio = lookup_error(interp, 4.0) / lookup_error(interp, 8.0);
            assert!((ratio.log2() - order).abs() < 0.15, "{interp:?}: {ratio}");
        }
    }

    /// The closed form of the blend error against sums over a pixel grid
    /// of sampled Gaussians (8 px and wider: sampling adds nothing visible).
    #[test]
    fn level_blend_error_matches_sums_over_a_grid() {
        let g = |s: f64, x: f64, y: f64| {
            (-(x * x + y * y) / (2.0 * s * s)).exp() / (2.0 * std::f64::consts::PI * s * s)
        };
        let rho = 2f64.sqrt();
        for f in [0.1, 0.5, 0.8] {
            let (sa, sb, s) = (8.0, 8.0 * rho, 8.0 * rho.powf(f));
            let (mut num, mut den) = (0.0, 0.0);
            for i in -100..=100 {
                for j in -100..=100 {
                    let (x, y) = (f64::from(i), f64::from(j));
                    let want = g(s, x, y);
                    let got = (1.0 - f) * g(sa, x, y) + f * g(sb, x, y);
                    num += (got - want).powi(2);
                    den += want * want;
                }
            }
            let brute = (num / den).sqrt();
            let closed = blend_error_at(rho, f);
            assert!(
                (brute - closed).abs() < 1e-6 * closed.max(1e-3),
                "{f}: {brute} {closed}"
            );
        }
        // RMS over the position falls as the square of the spacing.
        let ratio = level_blend_error(2) / level_blend_error(4);
        assert!((ratio - 4.0).abs() < 0.1, "{ratio}");
    }
}
