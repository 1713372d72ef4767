//! The band matrices `(M_l)_{m j} = pi_l y_l^m(z_j)` of a direction set
//! (ISD Eq. 10), their condition numbers and checked inverses.

use nalgebra::DMatrix;

use crate::error::{Result, SphereError};
use crate::sh::{ShEvaluator, pi_l, sh_count};

/// `(M_l)_{m j} = pi_l y_l^m(z_j)` for the given band-`l` directions.
pub(crate) fn band_matrix(sh: &ShEvaluator, l: usize, dirs: &[[f64; 3]]) -> DMatrix<f64> {
    let n = 2 * l + 1;
    let mut y = vec![0.0; sh_count(sh.l_max())];
    let mut m = DMatrix::zeros(n, dirs.len());
    let p = pi_l(l);
    let sub = ShEvaluator::new(l).ok();
    let ev = sub.as_ref().unwrap_or(sh);
    for (j, d) in dirs.iter().enumerate() {
        ev.eval_into(*d, &mut y);
        for i in 0..n {
            m[(i, j)] = p * y[l * l + i];
        }
    }
    m
}

/// The inverse and condition number of band `band`'s matrix, refused as
/// [`SphereError::Degenerate`] when the condition number exceeds `limit` or
/// the inversion fails.
pub(crate) fn checked_inverse(
    m: &DMatrix<f64>,
    band: usize,
    limit: f64,
) -> Result<(DMatrix<f64>, f64)> {
    let cond = condition_number(m);
    let inv = if cond <= limit {
        m.clone().try_inverse()
    } else {
        None
    };
    inv.map(|i| (i, cond))
        .ok_or(SphereError::Degenerate { band, cond, limit })
}

/// 2-norm condition number (ratio of extreme singular values; infinite when singular).
#[must_use]
pub fn condition_number(m: &DMatrix<f64>) -> f64 {
    if m.is_empty() {
        return 1.0;
    }
    let sv = m.clone().svd(false, false).singular_values;
    let max = sv.iter().copied().fold(0.0, f64::max);
    let min = sv.iter().copied().fold(f64::INFINITY, f64::min);
    if min.is_nan() || min <= 0.0 || !max.is_finite() {
        f64::INFINITY
    } else {
        max / min
    }
}
