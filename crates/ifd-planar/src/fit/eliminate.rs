//! Support elimination: least-squares refits on a fixed support (with the
//! DC constraint), the cost of removing each atom, and the pruning of the
//! support that `decompose` drives.

use crate::dictionary::Dictionary;
use crate::sparsa::{LinearOperator, debias};

use super::linalg::factor;

/// The growth of the squared residual when an atom with coefficient `z`
/// and (constrained) inverse diagonal `p` is removed: `z^2 / p`; infinite
/// when `p` vanishes (the constraint then pins the atom: the last atom of a
/// DC-constrained fit cannot go).
pub(super) fn removal_cost(z: f64, p: f64) -> f64 {
    if p > 1e-14 { z * z / p } else { f64::INFINITY }
}

/// Supports larger than this are refitted by conjugate gradients instead of
/// a Cholesky factorisation of their Gram matrix.
pub(super) const DIRECT_LIMIT: usize = 2500;
/// Iteration cap of one continuation stage.
pub(super) const STAGE_ITER: usize = 2000;

/// A fit on a fixed support: least-squares weights and their error.
#[derive(Clone)]
pub(super) struct Candidate {
    /// Atom indices.
    pub(super) support: Vec<usize>,
    /// Unit-norm coefficients on the support.
    pub(super) z: Vec<f64>,
    /// Relative L2 error.
    pub(super) err: f64,
    /// Increase of the squared residual if atom `k` were removed and the rest
    /// refitted: `z_k^2 / (G^-1)_kk`. Empty when not computed.
    pub(super) scores: Vec<f64>,
    pub(super) tau: f64,
}

impl Candidate {
    pub(super) fn nnz(&self) -> usize {
        self.support.len()
    }
}

/// The DC constraint of a fit (module docs, "Exact DC").
pub(super) struct DcConstraint {
    /// The kernel's sum `s` (on the pixel grid).
    pub(super) target: f64,
    /// The fit's grid is this many times finer than the pixels: an atom at
    /// `(x, y, sigma)` fine px is a term at `(x, y, sigma) / q` px with its
    /// weight divided by `q^2`.
    pub(super) q: f64,
}

/// `sum_i g_sigma(i - c)` over all integers: the sampled 1D normalised
/// Gaussian's sum (1 for `sigma >= 1` to 1e-8).
pub(super) fn sampled_sum(c: f64, sigma: f64) -> f64 {
    let r = (8.0 * sigma).ceil() + 1.0;
    let norm = 1.0 / ((std::f64::consts::TAU).sqrt() * sigma);
    let (lo, hi) = ((c - r).floor() as i64, (c + r).ceil() as i64);
    (lo..=hi)
        .map(|i| (-(i as f64 - c).powi(2) / (2.0 * sigma * sigma)).exp() * norm)
        .sum()
}

pub(super) struct Fitter<'a> {
    pub(super) dict: &'a Dictionary,
    pub(super) y: &'a [f64],
    /// `A^T y`.
    pub(super) aty: Vec<f64>,
    pub(super) yy: f64,
    pub(super) dc: Option<DcConstraint>,
}

impl Fitter<'_> {
    /// The DC gains `c_k` of the unit-norm atoms of `support`, when the fit
    /// is constrained.
    pub(super) fn dc_row(&self, support: &[usize]) -> Option<(Vec<f64>, f64)> {
        let dc = self.dc.as_ref()?;
        let q = dc.q;
        let row = support
            .iter()
            .map(|&k| {
                let a = self.dict.atom(k);
                sampled_sum(a.x / q, a.sigma / q) * sampled_sum(a.y / q, a.sigma / q)
                    / (a.norm * q * q)
            })
            .collect();
        Some((row, dc.target))
    }

    /// Least squares on `support`.
    pub(super) fn solve(&self, support: Vec<usize>, tau: f64) -> Candidate {
        let s = support.len();
        if s == 0 {
            return Candidate {
                support,
                z: Vec::new(),
                err: 1.0,
                scores: Vec::new(),
                tau,
            };
        }
        if s > DIRECT_LIMIT {
            let mut x = vec![0.0; self.dict.len()];
            for &k in &support {
                x[k] = self.aty[k].signum() * f64::EPSILON.max(self.aty[k].abs());
            }
            debias(self.dict, self.y, &mut x, 1e-10, 500);
            let mut ax = vec![0.0; self.y.len()];
            self.dict.apply(&x, &mut ax);
            let r2: f64 = ax.iter().zip(self.y).map(|(u, v)| (u - v).powi(2)).sum();
            let z = support.iter().map(|&k| x[k]).collect();
            return Candidate {
                support,
                z,
                err: (r2 / self.yy).sqrt(),
                scores: Vec::new(),
                tau,
            };
        }
        let gram = self.dict.gram(&support);
        let b: Vec<f64> = support.iter().map(|&k| self.aty[k]).collect();
        let l = factor(&gram, s);
        let mut z = b.clone();
        l.solve(&mut z);
        let mut h_diag = l.inverse_diagonal();
        if let Some((c, target)) = self.dc_row(&support) {
            // z = z0 + u (s - c.z0) / (c.u), u = G^-1 c; diag(P) = diag(H) - u^2 / c.u.
            let mut u = c.clone();
            l.solve(&mut u);
            let cu: f64 = c.iter().zip(&u).map(|(a, b)| a * b).sum();
            if cu > 0.0 && cu.is_finite() {
                let cz: f64 = c.iter().zip(&z).map(|(a, b)| a * b).sum();
                let lambda = (target - cz) / cu;
                for (zi, ui) in z.iter_mut().zip(&u) {
                    *zi += lambda * ui;
                }
                for (d, ui) in h_diag.iter_mut().zip(&u) {
                    *d -= ui * ui / cu;
                }
            }
        }
        // ||y - A z||^2 = ||y||^2 - 2 z.b + z^T G z.
        let mut zgz = 0.0;
        for p in 0..s {
            zgz += z[p]
                * gram[p * s..(p + 1) * s]
                    .iter()
                    .zip(&z)
                    .map(|(g, v)| g * v)
                    .sum::<f64>();
        }
        let zb: f64 = z.iter().zip(&b).map(|(u, v)| u * v).sum();
        let err = ((self.yy - 2.0 * zb + zgz).max(0.0) / self.yy).sqrt();
        let scores = z
            .iter()
            .zip(&h_diag)
            .map(|(v, d)| removal_cost(*v, *d))
            .collect();
        Candidate {
            support,
            z,
            err,
            scores,
            tau,
        }
    }

    pub(super) fn solve_x(&self, x: &[f64], tau: f64) -> Candidate {
        self.solve((0..x.len()).filter(|&k| x[k] != 0.0).collect(), tau)
    }

    /// The support without its `n` least useful atoms (smallest scores, or
    /// smallest coefficients when no scores).
    pub(super) fn drop_weakest(c: &Candidate, n: usize) -> Vec<usize> {
        let mut order: Vec<usize> = (0..c.nnz()).collect();
        if c.scores.len() == c.nnz() {
            order.sort_by(|&a, &b| c.scores[a].total_cmp(&c.scores[b]));
        } else {
            order.sort_by(|&a, &b| c.z[a].abs().total_cmp(&c.z[b].abs()));
        }
        let mut keep: Vec<usize> = order[n.min(order.len())..]
            .iter()
            .map(|&p| c.support[p])
            .collect();
        keep.sort_unstable();
        keep
    }

    /// Backward elimination down to at most `n` atoms.
    pub(super) fn reduce_to(&self, c: Candidate, n: usize) -> Candidate {
        self.eliminate(c, n, f64::INFINITY)
    }

    /// Backward elimination while the error stays within `tol`.
    pub(super) fn prune(&self, c: Candidate, tol: f64) -> Candidate {
        self.eliminate(c, 1, tol)
    }

    /// Removes atoms one at a time, each time the one whose removal (with the
    /// others refitted) raises the residual least, `z_k^2 / (G^-1)_kk`, while
    /// more than `target` remain and the error stays within `tol`. `G^-1` and
    /// `z` are downdated in `O(s^2)` per removal:
    /// `H' = H - h_k h_k^T / H_kk`, `z' = z - z_k h_k / H_kk` (`h_k` = column `k`
    /// of `H = G^-1`). The final support is refitted exactly.
    pub(super) fn eliminate(&self, c: Candidate, target: usize, tol: f64) -> Candidate {
        let s = c.nnz();
        if s <= target.max(1) {
            return c;
        }
        if s > DIRECT_LIMIT {
            // Too large to invert: drop by magnitude, then continue exactly.
            let keep = Self::drop_weakest(&c, s - DIRECT_LIMIT);
            let next = self.solve(keep, c.tau);
            return if next.err <= tol {
                self.eliminate(next, target, tol)
            } else {
                c
            };
        }
        let gram = self.dict.gram(&c.support);
        let mut h = factor(&gram, s).full_inverse();
        if let Some((row, _)) = self.dc_row(&c.support) {
            // The constrained inverse P = H - u u^T / c.u, u = H c (c.z
            // already holds the constrained solution).
            let u: Vec<f64> = (0..s)
                .map(|i| {
                    h[i * s..(i + 1) * s]
                        .iter()
                        .zip(&row)
                        .map(|(a, b)| a * b)
                        .sum()
                })
                .collect();
            let cu: f64 = row.iter().zip(&u).map(|(a, b)| a * b).sum();
            if cu > 0.0 && cu.is_finite() {
                for i in 0..s {
                    for j in 0..s {
                        h[i * s + j] -= u[i] * u[j] / cu;
                    }
                }
            }
        }
        let mut z = c.z.clone();
        let mut r2 = c.err * c.err * self.yy;
        let mut active = vec![true; s];
        let mut count = s;
        let mut removed = Vec::new();
        let mut hk = vec![0.0; s];
        while count > target {
            let mut best = (f64::INFINITY, usize::MAX);
            for k in (0..s).filter(|&k| active[k]) {
                let inc = removal_cost(z[k], h[k * s + k]);
                if inc < best.0 {
                    best = (inc, k);
                }
            }
            let (inc, k) = best;
            if k == usize::MAX || ((r2 + inc) / self.yy).sqrt() > tol {
                break;
            }
            r2 += inc;
            let hkk = h[k * s + k];
            hk.copy_from_slice(&h[k * s..(k + 1) * s]);
            let zk = z[k];
            active[k] = false;
            for i in (0..s).filter(|&i| active[i]) {
                let f = hk[i] / hkk;
                z[i] -= zk * f;
                let row = &mut h[i * s..(i + 1) * s];
                for j in 0..s {
                    row[j] -= f * hk[j];
                }
            }
            removed.push(k);
            count -= 1;
        }
        // Exact refit; undo removals if rounding pushed the error past `tol`.
        loop {
            let support: Vec<usize> = (0..s)
                .filter(|&k| active[k])
                .map(|k| c.support[k])
                .collect();
            let fit = self.solve(support, c.tau);
            if fit.err <= tol || removed.is_empty() {
                return fit;
            }
            if let Some(k) = removed.pop() {
                active[k] = true;
            }
        }
    }
}
