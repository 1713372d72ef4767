//! Closed-form zonal coefficients of the slices that are zonal: Lambert (about
//! the normal) and the normalised Phong lobe (about the mirror direction).
//!
//! The derivation and conventions are documented on [`zonal_slice`].

use crate::brdf::{Brdf, Model};

/// `I_l(s) = int_0^1 t^s P_l(t) dt` for `l = 0..=l_max` (see the module docs).
///
/// ```
/// let i = ifd_shade::legendre_moments(2.0, 3);
/// // P_2 = (3t^2 - 1) / 2: int_0^1 t^2 P_2 = (3/5 - 1/3) / 2 = 2/15
/// assert!((i[2] - 2.0 / 15.0).abs() < 1e-15);
/// ```
#[must_use]
pub fn legendre_moments(s: f64, l_max: usize) -> Vec<f64> {
    let mut out = vec![0.0; l_max + 1];
    out[0] = 1.0 / (s + 1.0);
    if l_max >= 1 {
        out[1] = 1.0 / (s + 2.0);
    }
    for l in 0..l_max.saturating_sub(1) {
        let lf = l as f64;
        out[l + 2] = (s - lf) / (s + lf + 3.0) * out[l];
    }
    out
}

/// The axis and zonal coefficients `k_l` of a slice that is zonal in closed
/// form (Lambert about the normal, Phong about the mirror direction of `wo`),
/// `None` for the other models.
///
/// # Derivation
/// A zonal function `k(w) = g(a . w)` about an axis `a` has the SH expansion
/// `k(w) = sum_l k_l y_l^0(a . w)` (`y_l^0` read as a function of the cosine
/// to the axis) with
///
/// ```text
/// k_l = 2 pi int_{-1}^{1} g(t) y_l^0(t) dt,   y_l^0(t) = sqrt((2l + 1) / (4 pi)) P_l(t),
/// ```
///
/// and, by the addition theorem, coefficients `c_l^m = k_l pi_l y_l^m(a)` in the
/// global basis (`pi_l = sqrt(4 pi / (2l + 1))`). For `g(t) = C max(t, 0)^s`
/// the integral is the Legendre moment `I_l(s) = int_0^1 t^s P_l(t) dt`, which
/// the Legendre three-term recurrence turns into
///
/// ```text
/// I_0 = 1 / (s + 1),   I_1 = 1 / (s + 2),   I_{l+2} = (s - l) / (s + l + 3) I_l
/// ```
///
/// (from the closed form `I_l(s) = sqrt(pi) 2^(-s-1) Gamma(s + 1) /
/// (Gamma(1 + (s - l) / 2) Gamma((s + l + 3) / 2))`, whose ratio for `l` and
/// `l + 2` is `(s - l) / (s + l + 3)`), stable for every `s > -1`. So
///
/// - Lambert, `g(t) = A / pi max(t, 0)`: `k_l = 2 A sqrt((2l + 1) / (4 pi)) I_l(1)`;
///   the classic irradiance factors are `pi_l k_l = (A / pi) A_hat_l` with
///   `A_hat_0 = pi`, `A_hat_1 = 2 pi / 3`, `A_hat_2 = pi / 4`, `A_hat_l = 0` for
///   odd `l > 1`;
/// - Phong, `g(t) = A (s + 1) / (2 pi) max(t, 0)^s`:
///   `k_l = A (s + 1) sqrt((2l + 1) / (4 pi)) I_l(s)`, and `pi_l k_l / A` is the
///   SHRM paper's `Lambda_l rho_l`, close to `exp(-l^2 / (2 s))` for large `s`.
#[must_use]
pub fn zonal_slice(brdf: &Brdf, wo: [f64; 3], l_max: usize) -> Option<([f64; 3], Vec<f64>)> {
    let a = brdf.albedo();
    let norm = |l: usize| ((2 * l + 1) as f64 / (4.0 * std::f64::consts::PI)).sqrt();
    match *brdf.model() {
        Model::Lambert => {
            // like every model but Phong, zero for a view below the horizon
            let a = if wo[2] > 0.0 { a } else { 0.0 };
            let i = legendre_moments(1.0, l_max);
            let k = (0..=l_max).map(|l| 2.0 * a * norm(l) * i[l]).collect();
            Some(([0.0, 0.0, 1.0], k))
        }
        Model::Phong { s } => {
            let i = legendre_moments(s, l_max);
            let k = (0..=l_max)
                .map(|l| a * (s + 1.0) * norm(l) * i[l])
                .collect();
            Some(([-wo[0], -wo[1], wo[2]], k))
        }
        _ => None,
    }
}
