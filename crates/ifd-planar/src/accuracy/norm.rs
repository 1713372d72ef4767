//! The L2 norm of a decomposition's kernel, in closed form: the
//! normalisation of the plan's bound and estimate.

use crate::decomposition::Decomposition;
use crate::error::FilterError;

/// [`kernel_norm`] of a decomposition with terms, refused when it has none
/// or its kernel's norm is zero or not finite.
pub(super) fn checked_kernel_norm(decomposition: &Decomposition) -> Result<f64, FilterError> {
    if decomposition.terms.is_empty() {
        return Err(FilterError::InvalidParameter(
            "the decomposition has no terms".into(),
        ));
    }
    let norm = kernel_norm(decomposition);
    if !(norm.is_finite() && norm > 0.0) {
        return Err(FilterError::InvalidParameter(format!(
            "the decomposition's kernel has norm {norm}: nothing to apply"
        )));
    }
    Ok(norm)
}

/// `||k||_2` of the continuous sum of Gaussians, in closed form:
/// `sum_{t,u} w_t w_u g_{sqrt(sigma_t^2 + sigma_u^2)}(c_t - c_u)`.
fn kernel_norm(decomposition: &Decomposition) -> f64 {
    gaussian_sum_norm2(&decomposition.terms, 1.0, |sigma| sigma)
        .max(0.0)
        .sqrt()
}

/// `||sum_t w_t g_{sigma(sigma_t)}(. - s c_t)||^2` in closed form (the 2D
/// Gaussians' inner products are Gaussians of the summed variances), each
/// pair of terms once: the squared norm of a decomposition's kernel at
/// scale `s` with sigmas `sigma` of the terms' (the bound's and, with the
/// pixel footprint, the estimate's normalisation).
pub(super) fn gaussian_sum_norm2(
    terms: &[crate::term::Term],
    s: f64,
    sigma: impl Fn(f64) -> f64,
) -> f64 {
    let sigmas: Vec<f64> = terms.iter().map(|t| sigma(t.sigma)).collect();
    let mut sum = 0.0;
    for (i, a) in terms.iter().enumerate() {
        for (j, b) in terms.iter().enumerate().skip(i) {
            let v = sigmas[i] * sigmas[i] + sigmas[j] * sigmas[j];
            let d2 = s * s * ((a.x - b.x).powi(2) + (a.y - b.y).powi(2));
            let g =
                a.weight * b.weight * (-d2 / (2.0 * v)).exp() / (2.0 * std::f64::consts::PI * v);
            sum += if i == j { g } else { 2.0 * g };
        }
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::term::Term;

    #[test]
    fn kernel_norm_of_one_gaussian() {
        let d = Decomposition::from_terms(vec![Term {
            weight: 2.0,
            x: 5.0,
            y: -1.0,
            sigma: 3.0,
        }]);
        let expected = 2.0 / (2.0 * std::f64::consts::PI.sqrt() * 3.0);
        assert!((kernel_norm(&d) - expected).abs() < 1e-12);
    }
}
