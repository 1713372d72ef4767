//! The dense linear algebra of the refits: Cholesky factorisation, solves
//! and the inverses whose diagonals score atoms for removal (row-major,
//! lower triangles).

/// In-place Cholesky factorisation `G = L L^T` (lower triangle of `g`, row-major).
pub(super) fn cholesky(g: &mut [f64], s: usize) -> bool {
    for j in 0..s {
        let mut d = g[j * s + j];
        for k in 0..j {
            d -= g[j * s + k] * g[j * s + k];
        }
        if d <= 0.0 || !d.is_finite() {
            return false;
        }
        let d = d.sqrt();
        g[j * s + j] = d;
        for i in j + 1..s {
            let mut v = g[i * s + j];
            for k in 0..j {
                v -= g[i * s + k] * g[j * s + k];
            }
            g[i * s + j] = v / d;
        }
    }
    true
}

/// Cholesky factor of `gram` (`s x s`), with a tiny ridge added when needed
/// (unit-norm atoms: `diag(G) = 1`; near-coincident atoms make `G` singular).
pub(super) fn factor(gram: &[f64], s: usize) -> Vec<f64> {
    let mut l = gram.to_vec();
    let mut ridge = 1e-12;
    while !cholesky(&mut l, s) {
        l.copy_from_slice(gram);
        for i in 0..s {
            l[i * s + i] += ridge;
        }
        ridge *= 100.0;
    }
    l
}

/// `L^-1` (lower triangular, row-major) from a Cholesky factor.
pub(super) fn lower_inverse(l: &[f64], s: usize) -> Vec<f64> {
    let mut inv = vec![0.0; s * s];
    for j in 0..s {
        inv[j * s + j] = 1.0 / l[j * s + j];
        for i in j + 1..s {
            let mut v = 0.0;
            for k in j..i {
                v -= l[i * s + k] * inv[k * s + j];
            }
            inv[i * s + j] = v / l[i * s + i];
        }
    }
    inv
}

/// `diag(G^-1)` = column sums of squares of `L^-1`.
pub(super) fn inverse_diagonal(l: &[f64], s: usize) -> Vec<f64> {
    let inv = lower_inverse(l, s);
    (0..s)
        .map(|j| (j..s).map(|i| inv[i * s + j].powi(2)).sum())
        .collect()
}

/// `G^-1 = L^-T L^-1` from a Cholesky factor, row-major.
pub(super) fn full_inverse(l: &[f64], s: usize) -> Vec<f64> {
    let inv = lower_inverse(l, s);
    let mut h = vec![0.0; s * s];
    for a in 0..s {
        for b in 0..=a {
            let v: f64 = (a..s).map(|i| inv[i * s + a] * inv[i * s + b]).sum();
            h[a * s + b] = v;
            h[b * s + a] = v;
        }
    }
    h
}

/// Solves `L L^T x = rhs` in place from a Cholesky factor (row-major).
pub(super) fn cholesky_solve(l: &[f64], s: usize, x: &mut [f64]) {
    for i in 0..s {
        let mut v = x[i];
        for k in 0..i {
            v -= l[i * s + k] * x[k];
        }
        x[i] = v / l[i * s + i];
    }
    for i in (0..s).rev() {
        let mut v = x[i];
        for k in i + 1..s {
            v -= l[k * s + i] * x[k];
        }
        x[i] = v / l[i * s + i];
    }
}
