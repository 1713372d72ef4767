//! Sine and cosine of an angle in degrees, in `f32`, by one sequence of
//! IEEE operations that the scalar loop and the vector rows
//! (`stack::rows::rules::rotations`) both follow, so the two paths rotate every
//! pixel's terms by the same bits.
//!
//! # Derivation
//! With `q` the nearest integer to `theta / 90` (ties to even) and
//! `r = theta - 90 q` (`|r| <= 45` up to the rounding of `theta / 90`),
//! `sin(theta) = sin(r + 90 q)` is `sin r`, `cos r`, `-sin r`, `-cos r` for
//! `q mod 4 = 0, 1, 2, 3`, and `cos(theta)` is `cos r`, `-sin r`, `-cos r`,
//! `sin r`: odd `q` swap the two, `q mod 4` in `{2, 3}` negates the sine and
//! in `{1, 2}` the cosine (bit 1 of `q` and of `q + 1`). The reduction is
//! exact: `90 q` is an integer below `2^24` for the angles a field admits
//! (`|theta| <= 1e6`), and `theta - 90 q` is representable. Right angles give
//! exactly 0 and ±1.
//!
//! On `|x| <= pi / 4` (`x = r pi / 180`) the Taylor series to `x^9` (sine)
//! and `x^10` (cosine) leave out at most `x^11 / 11! < 2e-9` and
//! `x^12 / 12! < 1e-10`, below `f32` rounding; Horner's rule in `x^2`
//! adds a few roundings, so both are within a few `f32` units of the exact
//! values (tested against `f64`). libm's `sincosf` is closer to correctly
//! rounded but is a call per pixel that vector lanes cannot share.

/// `1 / 90`.
pub(crate) const INV_RIGHT_ANGLE: f32 = 1.0 / 90.0;
/// `pi / 180`.
pub(crate) const RADIANS_PER_DEGREE: f32 = std::f32::consts::PI / 180.0;
/// The sine's Taylor coefficients of `x^3, x^5, x^7, x^9`.
pub(crate) const SIN: [f32; 4] = [-1.0 / 6.0, 1.0 / 120.0, -1.0 / 5040.0, 1.0 / 362_880.0];
/// The cosine's Taylor coefficients of `x^2, x^4, .., x^10`.
pub(crate) const COS: [f32; 5] = [
    -0.5,
    1.0 / 24.0,
    -1.0 / 720.0,
    1.0 / 40_320.0,
    -1.0 / 3_628_800.0,
];

/// `(sin theta, cos theta)` for `theta` in degrees (finite, at most about
/// `1e6` in magnitude, as fields are checked to be).
#[inline]
#[must_use]
pub(crate) fn sin_cos_degrees(theta: f32) -> (f32, f32) {
    let q = (theta * INV_RIGHT_ANGLE).round_ties_even();
    let x = (theta - q * 90.0) * RADIANS_PER_DEGREE;
    let x2 = x * x;
    let s = x + x * x2 * (SIN[0] + x2 * (SIN[1] + x2 * (SIN[2] + x2 * SIN[3])));
    let c = 1.0 + x2 * (COS[0] + x2 * (COS[1] + x2 * (COS[2] + x2 * (COS[3] + x2 * COS[4]))));
    let q = q as i32;
    let (s, c) = if q & 1 == 0 { (s, c) } else { (c, s) };
    let s = if q & 2 == 0 { s } else { -s };
    let c = if q.wrapping_add(1) & 2 == 0 { c } else { -c };
    (s, c)
}

#[cfg(test)]
mod tests {
    use super::sin_cos_degrees;

    #[test]
    fn matches_f64_sine_and_cosine() {
        let check = |theta: f32| {
            let (s, c) = sin_cos_degrees(theta);
            let (es, ec) = f64::from(theta).to_radians().sin_cos();
            // the f32 angle itself is exact; both values within 3e-7
            let err = (f64::from(s) - es).abs().max((f64::from(c) - ec).abs());
            assert!(err < 3e-7, "{theta}: ({s}, {c}) vs ({es}, {ec})");
        };
        for i in -20_000..=20_000 {
            check(i as f32 * 0.0173);
        }
        for theta in [
            44.999_996, 45.0, 45.000_004, 135.0, -45.0, -135.0, 1e6, -1e6, 999_999.94,
        ] {
            check(theta);
        }
    }

    #[test]
    fn right_angles_are_exact() {
        for (k, (s, c)) in [(0.0, 1.0), (1.0, 0.0), (0.0, -1.0), (-1.0, 0.0)]
            .into_iter()
            .enumerate()
        {
            for turns in [-3i32, -1, 0, 2, 1000] {
                let theta = (k as i32 + 4 * turns) as f32 * 90.0;
                let (gs, gc) = sin_cos_degrees(theta);
                assert_eq!((gs.abs(), gc.abs()), (f32::abs(s), f32::abs(c)), "{theta}");
                assert!(gs * s >= 0.0 && gc * c >= 0.0, "{theta}: ({gs}, {gc})");
            }
        }
    }
}
