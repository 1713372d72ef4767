//! `SpaRSA` (Wright, Nowak and Figueiredo, *Sparse Reconstruction by Separable
//! Approximation*, IEEE TSP 2009) for the l1-regularised least-squares problem
//!
//! ```text
//! minimise  F(x) = 0.5 ||y - A x||^2 + tau ||x||_1
//! ```
//!
//! with `A` given only as an operator ([`LinearOperator`]: `A x` and `A^T r`).
//!
//! Each iteration solves the separable model
//! `x+ = argmin_z  grad . (z - x) + alpha/2 ||z - x||^2 + tau ||z||_1`, i.e.
//! `x+ = soft(x - grad / alpha, tau / alpha)` with `grad = A^T (A x - y)`;
//! `alpha` is the Barzilai-Borwein curvature `||A dx||^2 / ||dx||^2` of the last
//! step, increased (times 2) until the safeguarded non-monotone condition
//! `F(x+) <= max_{last M+1} F - sigma/2 alpha ||dx||^2` (M = 5, sigma = 0.01)
//! holds. [`sparsa`] adds the reference implementation's continuation on `tau`
//! (stages `tau_k = max(tau, 0.2 ||A^T r||_inf)`, warm-started, each stopped on
//! a relative objective change of `1e-5`), stops the final stage on the relative
//! duality gap, and can debias by conjugate gradients on the support
//! ([`debias`]).

use std::collections::VecDeque;

/// A real matrix given as an operator.
///
/// Implementations must satisfy `<A x, r> = <x, A^T r>` (to rounding).
pub trait LinearOperator: Sync {
    /// Number of rows (length of `A x`).
    fn rows(&self) -> usize;
    /// Number of columns (length of `x`).
    fn cols(&self) -> usize;
    /// `out = A x` (`out` is overwritten). `x` is often sparse; implementations
    /// should skip its zeros cheaply.
    fn apply(&self, x: &[f64], out: &mut [f64]);
    /// `out = A^T r` (`out` is overwritten).
    fn apply_adjoint(&self, r: &[f64], out: &mut [f64]);
    /// `out[k] = (A^T r)[idx[k]]` for a few columns. The default computes the
    /// whole product; operators with cheap columns should override it.
    fn apply_adjoint_subset(&self, r: &[f64], idx: &[usize], out: &mut [f64]) {
        let mut full = vec![0.0; self.cols()];
        self.apply_adjoint(r, &mut full);
        for (o, &i) in out.iter_mut().zip(idx) {
            *o = full[i];
        }
    }
    /// `out = A^T A d` for a sparse `d` (its non-zero entries `vals` at
    /// `idx`, increasing), formed from the operator's structured Gram
    /// matrix without the image `A d`; `false`, leaving `out` untouched,
    /// when the operator has no such product (the default), and the solver
    /// goes through `apply` and `apply_adjoint` instead. The answer must not
    /// depend on `d`: the solver asks once, for an empty `d`.
    fn gram_apply(&self, idx: &[usize], vals: &[f64], out: &mut [f64]) -> bool {
        let _ = (idx, vals, out);
        false
    }
}

/// A small dense row-major matrix as a [`LinearOperator`] (tests, small problems).
///
/// ```
/// use ifd_planar::internals::sparsa::{DenseOperator, LinearOperator};
/// let a = DenseOperator::new(2, 2, vec![1.0, 2.0, 3.0, 4.0]);
/// let mut y = [0.0; 2];
/// a.apply(&[1.0, 1.0], &mut y);
/// assert_eq!(y, [3.0, 7.0]);
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct DenseOperator {
    rows: usize,
    cols: usize,
    data: Vec<f64>,
}

impl DenseOperator {
    /// A `rows x cols` matrix from row-major entries.
    ///
    /// # Panics
    /// When `data.len() != rows * cols`.
    #[must_use]
    pub fn new(rows: usize, cols: usize, data: Vec<f64>) -> Self {
        assert_eq!(data.len(), rows * cols, "DenseOperator: wrong entry count");
        Self { rows, cols, data }
    }
}

impl LinearOperator for DenseOperator {
    fn rows(&self) -> usize {
        self.rows
    }
    fn cols(&self) -> usize {
        self.cols
    }
    fn apply(&self, x: &[f64], out: &mut [f64]) {
        for (o, row) in out.iter_mut().zip(self.data.chunks_exact(self.cols)) {
            *o = row.iter().zip(x).map(|(a, b)| a * b).sum();
        }
    }
    fn apply_adjoint(&self, r: &[f64], out: &mut [f64]) {
        out.fill(0.0);
        for (row, &ri) in self.data.chunks_exact(self.cols).zip(r) {
            for (o, a) in out.iter_mut().zip(row) {
                *o += a * ri;
            }
        }
    }
}

/// When a `SpaRSA` stage stops.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StopCriterion {
    /// Relative duality gap `(P - D) / P` at or below the value.
    DualityGap(f64),
    /// Relative change of the objective between iterations at or below the value.
    ObjectiveChange(f64),
}

/// Options of [`sparsa`].
#[derive(Clone, Debug, PartialEq)]
pub struct SparsaOptions {
    /// The l1 weight `tau` (absolute).
    pub tau: f64,
    /// Stopping rule of the final stage (default: relative duality gap 0.01).
    pub stop: StopCriterion,
    /// Iteration limit over all stages.
    pub max_iter: usize,
    /// Minimum iterations of the final stage.
    pub min_iter: usize,
    /// Continuation on `tau` (default on).
    pub continuation: bool,
    /// Debias by conjugate gradients on the support after the last stage.
    pub debias: bool,
}

impl Default for SparsaOptions {
    fn default() -> Self {
        Self {
            tau: 1e-3,
            stop: StopCriterion::DualityGap(0.01),
            max_iter: 10_000,
            min_iter: 5,
            continuation: true,
            debias: false,
        }
    }
}

/// The result of [`sparsa`].
#[derive(Clone, Debug, PartialEq)]
pub struct SparsaOutput {
    /// The solution (debiased when asked).
    pub x: Vec<f64>,
    /// `F(x)` before debiasing.
    pub objective: f64,
    /// `SpaRSA` iterations over all stages.
    pub iterations: usize,
    /// Conjugate-gradient iterations of the debiasing.
    pub debias_iterations: usize,
}

/// Safeguard parameters (reference values).
const MEMORY: usize = 5;
const SIGMA: f64 = 0.01;
const ETA: f64 = 2.0;
const ALPHA_MIN: f64 = 1e-30;
const ALPHA_MAX: f64 = 1e30;

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn norm_inf(a: &[f64]) -> f64 {
    a.iter().fold(0.0, |m, v| m.max(v.abs()))
}

fn soft(v: f64, t: f64) -> f64 {
    if v > t {
        v - t
    } else if v < -t {
        v + t
    } else {
        0.0
    }
}

/// A `SpaRSA` solver state: the iterate `x`, `A^T r` for the residual
/// `r = y - A x`, and the scalars `||r||^2` and `r.y` that the objective and
/// the duality gap need, kept between stages so that continuation
/// warm-starts.
///
/// # Coefficient space
/// An iteration needs the image `r` only through `A^T r`, `||r||^2` and
/// `r.y`, and a step `d` changes them by `A^T A d`, `-2 d.A^T r + d.A^T A d`
/// and `-d.A^T y`. Where the operator forms `A^T A d` from its Gram
/// structure ([`LinearOperator::gram_apply`]: the separable dictionary does,
/// at a cost that grows with the support of `d`, not with the image), the
/// solver never touches the image; otherwise it keeps `r` and applies `A`
/// and `A^T` per iteration.
pub struct Sparsa<'a, A: LinearOperator + ?Sized> {
    a: &'a A,
    y: &'a [f64],
    x: Vec<f64>,
    /// The residual, kept only on the image path (`None` where the operator
    /// forms the Gram product).
    r: Option<Vec<f64>>,
    atr: Vec<f64>,
    aty: Vec<f64>,
    /// `||r||^2`.
    rr: f64,
    /// `r.y`.
    ry: f64,
    iterations: usize,
}

impl<'a, A: LinearOperator + ?Sized> Sparsa<'a, A> {
    /// A solver starting from `x0` (zero when `None`).
    ///
    /// # Panics
    /// When `y` or `x0` have the wrong length.
    pub fn new(a: &'a A, y: &'a [f64], x0: Option<&[f64]>) -> Self {
        let mut aty = vec![0.0; a.cols()];
        a.apply_adjoint(y, &mut aty);
        Self::with_aty(a, y, aty, x0)
    }

    /// As [`Sparsa::new`] with `A^T y` already at hand.
    ///
    /// # Panics
    /// When `y`, `aty` or `x0` have the wrong length.
    pub fn with_aty(a: &'a A, y: &'a [f64], aty: Vec<f64>, x0: Option<&[f64]>) -> Self {
        assert_eq!(y.len(), a.rows(), "sparsa: y has the wrong length");
        assert_eq!(aty.len(), a.cols(), "sparsa: A^T y has the wrong length");
        let x = x0.map_or_else(|| vec![0.0; a.cols()], <[f64]>::to_vec);
        assert_eq!(x.len(), a.cols(), "sparsa: x0 has the wrong length");
        let (r, atr) = if x.iter().all(|v| *v == 0.0) {
            (y.to_vec(), aty.clone())
        } else {
            let mut ax = vec![0.0; a.rows()];
            a.apply(&x, &mut ax);
            let r: Vec<f64> = y.iter().zip(&ax).map(|(y, ax)| y - ax).collect();
            let mut atr = vec![0.0; a.cols()];
            a.apply_adjoint(&r, &mut atr);
            (r, atr)
        };
        // Whether the operator forms A^T A d (asked once, for an empty d):
        // then the iterations never need the image residual.
        let gram = a.gram_apply(&[], &[], &mut vec![0.0; a.cols()]);
        Self {
            a,
            y,
            x,
            rr: dot(&r, &r),
            ry: dot(&r, y),
            r: (!gram).then_some(r),
            atr,
            aty,
            iterations: 0,
        }
    }

    /// The current iterate.
    #[must_use]
    pub fn x(&self) -> &[f64] {
        &self.x
    }

    /// The current residual `y - A x` (formed anew on the coefficient-space
    /// path).
    #[must_use]
    pub fn residual(&self) -> Vec<f64> {
        if let Some(r) = &self.r {
            return r.clone();
        }
        let mut ax = vec![0.0; self.a.rows()];
        self.a.apply(&self.x, &mut ax);
        self.y.iter().zip(&ax).map(|(y, v)| y - v).collect()
    }

    /// `||A^T (y - A x)||_inf` at the current iterate (`||A^T y||_inf` at zero:
    /// the smallest `tau` whose solution is zero).
    #[must_use]
    pub fn max_correlation(&self) -> f64 {
        norm_inf(&self.atr)
    }

    /// Iterations done so far, over all stages.
    #[must_use]
    pub fn iterations(&self) -> usize {
        self.iterations
    }

    /// `F(x) = 0.5 ||r||^2 + tau ||x||_1` at the current iterate.
    #[must_use]
    pub fn objective(&self, tau: f64) -> f64 {
        0.5 * self.rr.max(0.0) + tau * self.x.iter().map(|v| v.abs()).sum::<f64>()
    }

    /// Relative duality gap `(P - D) / P` at the current iterate, with the
    /// dual point `u = r min(1, tau / ||A^T r||_inf)`, `D = u.y - 0.5 ||u||^2`.
    #[must_use]
    pub fn relative_gap(&self, tau: f64) -> f64 {
        let p = self.objective(tau);
        let m = norm_inf(&self.atr);
        let scale = if m > tau { tau / m } else { 1.0 };
        let d = scale * self.ry - 0.5 * scale * scale * self.rr.max(0.0);
        if p <= 0.0 {
            0.0
        } else {
            ((p - d) / p).max(0.0)
        }
    }

    /// `||A d||^2` for the step `d` (dense, with its non-zero entries listed
    /// in `idx`/`vals`), and `A^T A d` into `q` through the operator's Gram
    /// product where it has one, else the image `A d` into `ad`.
    fn step_products(
        &self,
        (d, idx, vals): (&[f64], &[usize], &[f64]),
        q: &mut [f64],
        ad: &mut Vec<f64>,
    ) -> f64 {
        if self.r.is_none() {
            assert!(
                self.a.gram_apply(idx, vals, q),
                "sparsa: the operator stopped forming A^T A d"
            );
            return idx.iter().zip(vals).map(|(&k, v)| v * q[k]).sum();
        }
        ad.resize(self.a.rows(), 0.0);
        self.a.apply(d, ad);
        dot(ad, ad)
    }

    /// Runs `SpaRSA` iterations at a fixed `tau` until `stop` holds (after at
    /// least `min_iter` iterations) or `max_iter` more iterations were done.
    /// Calls `progress(total_iterations, objective, nnz)` after each iteration.
    pub fn solve_stage(
        &mut self,
        tau: f64,
        stop: StopCriterion,
        min_iter: usize,
        max_iter: usize,
        progress: &mut dyn FnMut(usize, f64, usize),
    ) {
        let n = self.a.cols();
        let mut alpha = 1.0;
        let mut f = self.objective(tau);
        let mut hist: VecDeque<f64> = VecDeque::with_capacity(MEMORY + 1);
        hist.push_back(f);
        let mut x_new = vec![0.0; n];
        let mut dx = vec![0.0; n];
        let mut q = vec![0.0; n];
        let mut ad = Vec::new();
        let (mut idx, mut vals) = (Vec::new(), Vec::new());
        for it in 0..max_iter {
            let f_ref = hist.iter().fold(f64::NEG_INFINITY, |a, &b| a.max(b));
            // The step: its products, the new squared residual and r.y.
            let (f_new, dxx, add, rr_new) = loop {
                // grad = -A^T r
                let t = tau / alpha;
                idx.clear();
                vals.clear();
                let mut dxx = 0.0;
                for k in 0..n {
                    x_new[k] = soft(self.x[k] + self.atr[k] / alpha, t);
                    dx[k] = x_new[k] - self.x[k];
                    if dx[k] != 0.0 {
                        idx.push(k);
                        vals.push(dx[k]);
                        dxx += dx[k] * dx[k];
                    }
                }
                if dxx == 0.0 {
                    break (f, 0.0, 0.0, self.rr);
                }
                let add = self.step_products((&dx, &idx, &vals), &mut q, &mut ad);
                let datr: f64 = idx.iter().zip(&vals).map(|(&k, v)| v * self.atr[k]).sum();
                // ||r - A d||^2
                let rr_new = self.rr - 2.0 * datr + add;
                let f_new =
                    0.5 * rr_new.max(0.0) + tau * x_new.iter().map(|v| v.abs()).sum::<f64>();
                if f_new <= f_ref - 0.5 * SIGMA * alpha * dxx || alpha >= ALPHA_MAX {
                    break (f_new, dxx, add, rr_new);
                }
                alpha = (alpha * ETA).min(ALPHA_MAX);
            };
            self.iterations += 1;
            if dxx == 0.0 {
                // A fixed point of the prox-gradient map: optimal.
                progress(self.iterations, f, nnz(&self.x));
                return;
            }
            std::mem::swap(&mut self.x, &mut x_new);
            if let Some(r) = &mut self.r {
                for (rv, v) in r.iter_mut().zip(&ad) {
                    *rv -= v;
                }
                self.a.apply_adjoint(r, &mut self.atr);
                self.rr = dot(r, r);
                self.ry = dot(r, self.y);
            } else {
                for (a, qv) in self.atr.iter_mut().zip(&q) {
                    *a -= qv;
                }
                self.rr = rr_new;
                self.ry -= idx
                    .iter()
                    .zip(&vals)
                    .map(|(&k, v)| v * self.aty[k])
                    .sum::<f64>();
            }
            let f_prev = f;
            f = f_new;
            if hist.len() > MEMORY {
                hist.pop_front();
            }
            hist.push_back(f);
            alpha = (add / dxx).clamp(ALPHA_MIN, ALPHA_MAX);
            progress(self.iterations, f, nnz(&self.x));
            if it + 1 >= min_iter {
                let done = match stop {
                    StopCriterion::DualityGap(tol) => self.relative_gap(tau) <= tol,
                    StopCriterion::ObjectiveChange(tol) => {
                        (f_prev - f).abs() <= tol * f_prev.abs().max(f64::MIN_POSITIVE)
                    }
                };
                if done {
                    return;
                }
            }
        }
    }
}

/// Number of non-zero entries.
#[must_use]
pub fn nnz(x: &[f64]) -> usize {
    x.iter().filter(|v| **v != 0.0).count()
}

/// Debiasing: least squares on the support of `x`,
/// `min_z ||y - A_S z||` by conjugate gradients on the normal equations,
/// warm-started at `x_S`, until the squared gradient norm drops below
/// `tol` times its initial value or after `max_iter` iterations. Entries
/// outside the support stay zero. Returns the number of CG iterations.
pub fn debias<A: LinearOperator + ?Sized>(
    a: &A,
    y: &[f64],
    x: &mut [f64],
    tol: f64,
    max_iter: usize,
) -> usize {
    let support: Vec<usize> = (0..x.len()).filter(|&k| x[k] != 0.0).collect();
    if support.is_empty() {
        return 0;
    }
    let m = a.rows();
    let mut ax = vec![0.0; m];
    a.apply(x, &mut ax);
    let mut r: Vec<f64> = y.iter().zip(&ax).map(|(y, v)| y - v).collect();
    let s = support.len();
    let mut g = vec![0.0; s];
    a.apply_adjoint_subset(&r, &support, &mut g);
    let mut p = g.clone();
    let mut gg = dot(&g, &g);
    let g0 = gg;
    let mut full = vec![0.0; x.len()];
    let mut q = vec![0.0; m];
    let mut iters = 0;
    while iters < max_iter && gg > tol * g0 && gg > 0.0 {
        for (k, &i) in support.iter().enumerate() {
            full[i] = p[k];
        }
        a.apply(&full, &mut q);
        let qq = dot(&q, &q);
        if qq <= 0.0 {
            break;
        }
        let step = gg / qq;
        for (k, &i) in support.iter().enumerate() {
            x[i] += step * p[k];
        }
        for (rv, qv) in r.iter_mut().zip(&q) {
            *rv -= step * qv;
        }
        a.apply_adjoint_subset(&r, &support, &mut g);
        let gg_new = dot(&g, &g);
        let beta = gg_new / gg;
        gg = gg_new;
        for (pv, gv) in p.iter_mut().zip(&g) {
            *pv = gv + beta * *pv;
        }
        iters += 1;
    }
    iters
}

/// `SpaRSA` with continuation and optional debiasing (see the source's module documentation).
///
/// ```
/// use ifd_planar::internals::sparsa::{sparsa, DenseOperator, SparsaOptions};
/// // An orthogonal A: the exact answer is soft-thresholding of A^T y.
/// let a = DenseOperator::new(2, 2, vec![0.6, 0.8, -0.8, 0.6]);
/// let y = [1.0, 2.0]; // A^T y = (-1.0, 2.0)
/// let opts = SparsaOptions { tau: 0.5, ..SparsaOptions::default() };
/// let out = sparsa(&a, &y, None, &opts, &mut |_, _, _| {});
/// assert!((out.x[0] + 0.5).abs() < 1e-3 && (out.x[1] - 1.5).abs() < 1e-3);
/// ```
///
/// # Panics
/// When `y` or `x0` have the wrong length.
pub fn sparsa<A: LinearOperator + ?Sized>(
    a: &A,
    y: &[f64],
    x0: Option<&[f64]>,
    opts: &SparsaOptions,
    progress: &mut dyn FnMut(usize, f64, usize),
) -> SparsaOutput {
    let mut s = Sparsa::new(a, y, x0);
    let tau = opts.tau.max(0.0);
    if opts.continuation {
        loop {
            let tau_k = tau.max(0.2 * s.max_correlation());
            if tau_k <= tau || s.iterations() >= opts.max_iter {
                break;
            }
            let left = opts.max_iter - s.iterations();
            s.solve_stage(
                tau_k,
                StopCriterion::ObjectiveChange(1e-5),
                1,
                left,
                progress,
            );
        }
    }
    let left = opts.max_iter.saturating_sub(s.iterations());
    s.solve_stage(tau, opts.stop, opts.min_iter, left, progress);
    let objective = s.objective(tau);
    let iterations = s.iterations();
    let mut x = s.x;
    let debias_iterations = if opts.debias {
        debias(a, y, &mut x, 1e-4, 200)
    } else {
        0
    };
    SparsaOutput {
        x,
        objective,
        iterations,
        debias_iterations,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic pseudo-random generator (xorshift), values in [-1, 1).
    fn rng(seed: &mut u64) -> f64 {
        *seed ^= *seed << 13;
        *seed ^= *seed >> 7;
        *seed ^= *seed << 17;
        (*seed >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }

    fn random_problem(m: usize, n: usize, seed: u64) -> (DenseOperator, Vec<f64>) {
        let mut s = seed;
        let data: Vec<f64> = (0..m * n).map(|_| rng(&mut s)).collect();
        let a = DenseOperator::new(m, n, data);
        let mut x = vec![0.0; n];
        for k in (0..n).step_by(7) {
            x[k] = 3.0 * rng(&mut s);
        }
        let mut y = vec![0.0; m];
        a.apply(&x, &mut y);
        for v in &mut y {
            *v += 0.01 * rng(&mut s);
        }
        (a, y)
    }

    #[test]
    fn kkt_conditions_hold_on_a_dense_problem() {
        let (a, y) = random_problem(40, 100, 12345);
        let mut aty = vec![0.0; 100];
        a.apply_adjoint(&y, &mut aty);
        let tau = 0.1 * norm_inf(&aty);
        let opts = SparsaOptions {
            tau,
            stop: StopCriterion::DualityGap(1e-8),
            ..SparsaOptions::default()
        };
        let out = sparsa(&a, &y, None, &opts, &mut |_, _, _| {});
        // KKT: (A^T r)_i = tau sign(x_i) on the support, |(A^T r)_i| <= tau off it.
        let mut ax = vec![0.0; 40];
        a.apply(&out.x, &mut ax);
        let r: Vec<f64> = y.iter().zip(&ax).map(|(y, v)| y - v).collect();
        let mut atr = vec![0.0; 100];
        a.apply_adjoint(&r, &mut atr);
        assert!(nnz(&out.x) > 0);
        for (xi, gi) in out.x.iter().zip(&atr) {
            if *xi == 0.0 {
                assert!(gi.abs() <= tau * (1.0 + 1e-3), "{gi} > {tau}");
            } else {
                assert!((gi - tau * xi.signum()).abs() < 1e-3 * tau, "{gi} vs {tau}");
            }
        }
    }

    #[test]
    fn orthogonal_operator_gives_soft_thresholding() {
        // A Householder reflection H = I - 2 v v^T / |v|^2 is orthogonal.
        let n = 16;
        let mut s = 99u64;
        let v: Vec<f64> = (0..n).map(|_| rng(&mut s)).collect();
        let vv = dot(&v, &v);
        let mut h = vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                h[i * n + j] = f64::from(u8::from(i == j)) - 2.0 * v[i] * v[j] / vv;
            }
        }
        let a = DenseOperator::new(n, n, h);
        let y: Vec<f64> = (0..n).map(|_| 2.0 * rng(&mut s)).collect();
        let mut aty = vec![0.0; n];
        a.apply_adjoint(&y, &mut aty);
        let tau = 0.4;
        let opts = SparsaOptions {
            tau,
            stop: StopCriterion::DualityGap(1e-10),
            ..SparsaOptions::default()
        };
        let out = sparsa(&a, &y, None, &opts, &mut |_, _, _| {});
        for (xi, bi) in out.x.iter().zip(&aty) {
            assert!(
                (xi - soft(*bi, tau)).abs() < 1e-6,
                "{xi} vs {}",
                soft(*bi, tau)
            );
        }
    }

    #[test]
    fn debiasing_solves_least_squares_on_the_support() {
        let (a, y) = random_problem(60, 30, 777);
        let mut aty = vec![0.0; 30];
        a.apply_adjoint(&y, &mut aty);
        let opts = SparsaOptions {
            tau: 0.05 * norm_inf(&aty),
            debias: true,
            ..SparsaOptions::default()
        };
        let mut out = sparsa(&a, &y, None, &opts, &mut |_, _, _| {});
        assert!(out.debias_iterations > 0);
        // The default debiasing stops at a 1e-4 reduction of |g|^2; go all the way here.
        debias(&a, &y, &mut out.x, 1e-24, 500);
        let support: Vec<usize> = (0..30).filter(|&k| out.x[k] != 0.0).collect();
        assert!(!support.is_empty());
        // Normal equations on the support: A_S^T (y - A x) = 0.
        let mut ax = vec![0.0; 60];
        a.apply(&out.x, &mut ax);
        let r: Vec<f64> = y.iter().zip(&ax).map(|(y, v)| y - v).collect();
        let mut g = vec![0.0; support.len()];
        a.apply_adjoint_subset(&r, &support, &mut g);
        assert!(norm_inf(&g) < 1e-9 * norm_inf(&aty), "{g:?}");
    }

    #[test]
    fn zero_solution_above_tau_max_and_progress_is_called() {
        let (a, y) = random_problem(10, 20, 5);
        let mut aty = vec![0.0; 20];
        a.apply_adjoint(&y, &mut aty);
        let opts = SparsaOptions {
            tau: 1.01 * norm_inf(&aty),
            ..SparsaOptions::default()
        };
        let mut calls = 0;
        let out = sparsa(&a, &y, None, &opts, &mut |_, _, _| calls += 1);
        assert_eq!(nnz(&out.x), 0);
        assert!(calls >= 1);
    }

    /// A dense operator that also forms `A^T A d` from its columns (the
    /// solver's coefficient-space path).
    struct WithGram(DenseOperator);

    impl LinearOperator for WithGram {
        fn rows(&self) -> usize {
            self.0.rows()
        }
        fn cols(&self) -> usize {
            self.0.cols()
        }
        fn apply(&self, x: &[f64], out: &mut [f64]) {
            self.0.apply(x, out);
        }
        fn apply_adjoint(&self, r: &[f64], out: &mut [f64]) {
            self.0.apply_adjoint(r, out);
        }
        fn gram_apply(&self, idx: &[usize], vals: &[f64], out: &mut [f64]) -> bool {
            let mut d = vec![0.0; self.cols()];
            for (&k, v) in idx.iter().zip(vals) {
                d[k] = *v;
            }
            let mut ad = vec![0.0; self.rows()];
            self.0.apply(&d, &mut ad);
            self.0.apply_adjoint(&ad, out);
            true
        }
    }

    #[test]
    fn coefficient_space_iterations_match_the_image_path() {
        let (a, y) = random_problem(30, 60, 11);
        let mut aty = vec![0.0; 60];
        a.apply_adjoint(&y, &mut aty);
        let opts = SparsaOptions {
            tau: 0.05 * norm_inf(&aty),
            stop: StopCriterion::DualityGap(1e-10),
            max_iter: 100_000,
            continuation: false,
            debias: false,
            ..SparsaOptions::default()
        };
        let image = sparsa(&a, &y, None, &opts, &mut |_, _, _| {});
        let gram = WithGram(a.clone());
        let mut s = Sparsa::new(&gram, &y, None);
        s.solve_stage(
            opts.tau,
            opts.stop,
            opts.min_iter,
            opts.max_iter,
            &mut |_, _, _| {},
        );
        assert!(s.r.is_none(), "the Gram path was not taken");
        // the same minimiser, to the stopping tolerance
        let f = |x: &[f64]| {
            let mut ax = vec![0.0; 30];
            a.apply(x, &mut ax);
            0.5 * y.iter().zip(&ax).map(|(u, v)| (u - v).powi(2)).sum::<f64>()
                + opts.tau * x.iter().map(|v| v.abs()).sum::<f64>()
        };
        let (fi, fg) = (f(&image.x), f(s.x()));
        assert!((fi - fg).abs() <= 1e-9 * fi, "{fi} vs {fg}");
        // the tracked objective is the true one
        assert!((s.objective(opts.tau) - fg).abs() <= 1e-9 * fg);
        let r = s.residual();
        let rr: f64 = r.iter().map(|v| v * v).sum();
        assert!((rr - s.rr).abs() <= 1e-9 * rr.max(1e-300));
    }
}
