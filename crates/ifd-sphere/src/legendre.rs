//! Legendre polynomials and Gauss-Legendre quadrature on `[-1, 1]`: the
//! zonal (`m = 0`) side of the SH, for zonal projections and transforms.

use std::f64::consts::PI;

/// Legendre polynomial `P_l(t)` (unnormalised, `P_l(1) = 1`), by the Bonnet recurrence.
#[must_use]
pub fn legendre_p(l: usize, t: f64) -> f64 {
    let (mut p0, mut p1) = (1.0, t);
    if l == 0 {
        return 1.0;
    }
    for k in 2..=l {
        let kf = k as f64;
        let p = ((2.0 * kf - 1.0) * t * p1 - (kf - 1.0) * p0) / kf;
        p0 = p1;
        p1 = p;
    }
    p1
}

/// All `P_l(t)` for `l = 0..=l_max` into `out`.
pub fn legendre_all(l_max: usize, t: f64, out: &mut [f64]) {
    out[0] = 1.0;
    if l_max == 0 {
        return;
    }
    out[1] = t;
    for k in 2..=l_max {
        let kf = k as f64;
        out[k] = ((2.0 * kf - 1.0) * t * out[k - 1] - (kf - 1.0) * out[k - 2]) / kf;
    }
}

/// Gauss-Legendre nodes and weights on `[-1, 1]` (Newton on the Bonnet
/// recurrence; exact for polynomials of degree `2n - 1`).
#[must_use]
pub fn gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut x = vec![0.0; n];
    let mut w = vec![0.0; n];
    let nf = n as f64;
    for i in 0..n.div_ceil(2) {
        let mut t = (PI * (i as f64 + 0.75) / (nf + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0, t);
            for k in 2..=n {
                let kf = k as f64;
                let p = ((2.0 * kf - 1.0) * t * p1 - (kf - 1.0) * p0) / kf;
                p0 = p1;
                p1 = p;
            }
            let (p, pm1) = if n == 1 { (t, 1.0) } else { (p1, p0) };
            dp = nf * (t * p - pm1) / (t * t - 1.0);
            let dt = p / dp;
            t -= dt;
            if dt.abs() < 1e-16 {
                break;
            }
        }
        x[i] = t;
        x[n - 1 - i] = -t;
        let wi = 2.0 / ((1.0 - t * t) * dp * dp);
        w[i] = wi;
        w[n - 1 - i] = wi;
    }
    (x, w)
}
