//! The natural logarithm in `f32`, by one sequence of IEEE operations that
//! the scalar loop and the vector rows (`stack::rows::rules::scale_positions`)
//! both follow, so a per-pixel scale map places every pixel among the
//! levels by the same bits on both paths.
//!
//! # Derivation
//! Write `x = 2^e m` with `m` in `[sqrt(1/2), sqrt(2))`. Subtracting the
//! bits of `sqrt(1/2)` from those of `x` (an `f32` above zero) leaves `e`
//! in the bits above the 23 mantissa bits (an arithmetic shift takes it,
//! negative below `sqrt(1/2)`) and, in the mantissa bits, how far `m` lies
//! above `sqrt(1/2)`; adding `sqrt(1/2)`'s bits back gives `m`. Then
//! `ln x = e ln 2 + ln m` and, with `f = (m - 1) / (m + 1)`
//! (`|f| <= 3 - 2 sqrt 2 < 0.1716`),
//! `ln m = 2 atanh f = 2 (f + f^3/3 + f^5/5 + f^7/7 + f^9/9 + ...)`. The
//! terms left out sum to less than `2 |f|^11 / 11 / (1 - f^2) < 7.2e-10`,
//! below `f32` rounding. `m - 1` is exact (`m` lies within a factor 2 of
//! 1), `m + 1` and the quotient round once each, and `ln 2` is split into
//! `LN2_HI` (nine significant bits: `e LN2_HI` is exact) and the rest, so
//! the result is within a few `f32` units of the exact logarithm (tested
//! against `f64`). libm's `logf` is closer to correctly rounded but is a
//! call per pixel that vector lanes cannot share.

/// The bits of `sqrt(1/2)` (rounded to `f32`).
pub(crate) const SQRT_HALF_BITS: u32 = 0x3f35_04f3;
/// `ln 2` to nine significant bits.
pub(crate) const LN2_HI: f32 = 355.0 / 512.0;
/// `ln 2 - LN2_HI`.
pub(crate) const LN2_LO: f32 = -2.121_944_4e-4;
/// `2 atanh f` is `2 f (1 + z (ATANH[0] + z (ATANH[1] + ...)))`, `z = f^2`.
pub(crate) const ATANH: [f32; 4] = [1.0 / 3.0, 1.0 / 5.0, 1.0 / 7.0, 1.0 / 9.0];

/// `ln x` for `x > 0`. Values below the least normal `f32` (zero,
/// negatives, subnormals, NaN) are taken as that least normal value: the
/// callers pass checked scales, this only keeps every input defined.
#[inline]
#[must_use]
pub(crate) fn ln(x: f32) -> f32 {
    let x = x.max(f32::MIN_POSITIVE);
    let ix = x.to_bits().wrapping_sub(SQRT_HALF_BITS) as i32;
    let e = (ix >> 23) as f32;
    let m = f32::from_bits(((ix & 0x007f_ffff) as u32) + SQRT_HALF_BITS);
    let f = (m - 1.0) / (m + 1.0);
    let z = f * f;
    let r = f + f;
    let p = r + r * z * (ATANH[0] + z * (ATANH[1] + z * (ATANH[2] + z * ATANH[3])));
    e * LN2_HI + (p + e * LN2_LO)
}

#[cfg(test)]
mod tests {
    use super::{LN2_HI, LN2_LO, SQRT_HALF_BITS, ln};

    #[test]
    fn matches_the_f64_logarithm() {
        let check = |x: f32| {
            let exact = f64::from(x).ln();
            let got = f64::from(ln(x));
            // a few f32 units of the result, and of ln 2 for large exponents
            let tol = 4.0 * f64::from(f32::EPSILON) * exact.abs().max(0.5);
            assert!((got - exact).abs() <= tol, "{x}: {got} vs {exact}");
        };
        let mut x = 1e-30_f32;
        while x < 1e30 {
            check(x);
            x *= 1.000_37;
        }
        for i in 0..=20_000 {
            check(0.5 + i as f32 * 1e-4); // the scales maps usually hold
            check(1.0 + (i as f32 - 10_000.0) * 1e-8); // around 1
        }
        for x in [
            f32::MIN_POSITIVE,
            f32::MAX,
            std::f32::consts::FRAC_1_SQRT_2,
            std::f32::consts::SQRT_2,
            // either side of the split at sqrt(1/2) and of sqrt(2)
            f32::from_bits(SQRT_HALF_BITS - 1),
            f32::from_bits(SQRT_HALF_BITS + 1),
            f32::from_bits(std::f32::consts::SQRT_2.to_bits() - 1),
            f32::from_bits(std::f32::consts::SQRT_2.to_bits() + 1),
        ] {
            check(x);
        }
    }

    #[test]
    fn powers_of_two_and_one_are_close_to_exact() {
        assert_eq!(ln(1.0), 0.0);
        assert!((f64::from(LN2_HI) + f64::from(LN2_LO) - 2f64.ln()).abs() < 1e-10);
        for e in -126..=127 {
            let x = 2f32.powi(e);
            let exact = f64::from(e) * 2f64.ln();
            // m = 1 exactly: `e LN2_HI + e LN2_LO`, rounded once
            assert!((f64::from(ln(x)) - exact).abs() <= f64::from(f32::EPSILON) * exact.abs());
        }
    }

    #[test]
    fn inputs_below_the_least_normal_are_that_value() {
        let floor = ln(f32::MIN_POSITIVE);
        for x in [0.0, -0.0, -1.0, 1e-40, f32::NAN, f32::NEG_INFINITY] {
            assert_eq!(ln(x).to_bits(), floor.to_bits(), "{x}");
        }
    }
}
