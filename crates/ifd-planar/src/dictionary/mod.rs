//! The Mixture-of-Gaussians dictionary of the IFD paper (Eq. 3) as a matrix-free
//! [`LinearOperator`].
//!
//! # Layout
//! Let `D` be the kernel's half-size (`max(R_x, R_y)` px). Level `l = 1..b` has
//! the *nominal spacing* `h_l = D / 2^(l-1)` and the atom width
//! `sigma_l = ratio * h_l` (std dev of the normalised Gaussian `g_sigma`, see the
//! crate conventions). Its atoms sit on the grid `{(m h_l / o, n h_l / o)}`
//! (`o` = oversampling; integer `m, n`) clipped to the kernel's rectangle, so the
//! grid is odd and always has an atom at the kernel centre; level 1 with `o = 1`
//! is the 3 x 3 grid `{-D, 0, D}^2` — the paper's `2^l x 2^l` grid made centred.
//! With `sigmas_per_octave = n > 1`, each level also carries the intermediate
//! widths `sigma_l 2^(j/n)`, `j = 1..n-1`, on the same grid: a scale stack keeps
//! those widths anyway, so they cost no prefiltering.
//!
//! # Separable operator
//! An atom is `g_sigma(d - c) = gx(d_x) gy(d_y)` with 1D factors
//! `gx(u) = exp(-(u - c_x)^2 / (2 sigma^2)) / (sqrt(2 pi) sigma)`. For one group
//! (a width `sigma` and its grid `x_1..x_{n_x}`, `y_1..y_{n_y}`) put the sampled
//! factors into matrices `Gx` (`n_x x W`, row `i` = factor of column `x_i`) and
//! `Gy` (`n_y x H`), and the group's coefficients into `Lambda` (`n_y x n_x`).
//! Then the group's contribution to `A x` is the `H x W` image
//! `Gy^T (Lambda Gx)`, and its block of `A^T r` (with `r` an `H x W` image) is
//! `(Gy r) Gx^T`. Each factor is cut at `6 sigma` (relative value `1.5e-8`),
//! which makes `Gx`, `Gy` banded: a group costs `O(n_y band_y W + n_y n_x band_x)`
//! instead of the `O(n_x n_y H W)` of a dense matrix, and rows of `Lambda`
//! that are zero are skipped in `A x`. The same truncation is used in both
//! products, so they are exact adjoints of each other.
//!
//! Columns are scaled to unit L2 norm (the solver's `x_k` is `w_k ||a_k||`),
//! so that the l1 penalty does not favour narrow atoms, whose sampled norm
//! `~1 / (2 sqrt(pi) sigma)` is larger. Since `||gx gy|| = ||gx|| ||gy||`, it
//! suffices to normalise the 1D factors; [`Dictionary::to_terms`] undoes it.

mod gram;
mod params;

use rayon::prelude::*;

use crate::sparsa::LinearOperator;
use crate::term::Term;

pub use params::{
    DictionaryError, DictionaryOptions, DictionaryParams, MAX_ATOMS, MAX_LEVELS, feature_width,
};

/// Truncation of the 1D factors, in standard deviations.
const CUTOFF_SIGMAS: f64 = 6.0;

/// A sampled, unit-norm 1D Gaussian factor with its band of non-zero samples.
#[derive(Clone, Debug)]
struct Profile {
    start: usize,
    vals: Vec<f64>,
    /// L2 norm of the sampled `exp(-u^2/(2 s^2)) / (sqrt(2 pi) s)` before scaling.
    norm: f64,
}

impl Profile {
    fn new(centre: f64, sigma: f64, len: usize) -> Self {
        // `centre` is in sample coordinates (0..len).
        let reach = CUTOFF_SIGMAS * sigma;
        let lo = (centre - reach).ceil().max(0.0) as usize;
        let hi = ((centre + reach).floor().max(0.0) as usize).min(len - 1);
        let c = 1.0 / ((2.0 * std::f64::consts::PI).sqrt() * sigma);
        let mut vals: Vec<f64> = (lo..=hi)
            .map(|u| c * (-(u as f64 - centre).powi(2) / (2.0 * sigma * sigma)).exp())
            .collect();
        let norm = vals.iter().map(|v| v * v).sum::<f64>().sqrt();
        for v in &mut vals {
            *v /= norm;
        }
        Self {
            start: lo,
            vals,
            norm,
        }
    }

    fn end(&self) -> usize {
        self.start + self.vals.len()
    }
}

fn profile_dot(a: &Profile, b: &Profile) -> f64 {
    let lo = a.start.max(b.start);
    let hi = a.end().min(b.end());
    if lo >= hi {
        return 0.0;
    }
    a.vals[lo - a.start..hi - a.start]
        .iter()
        .zip(&b.vals[lo - b.start..hi - b.start])
        .map(|(u, v)| u * v)
        .sum()
}

/// One width with its grid.
#[derive(Clone, Debug)]
struct Group {
    level: usize,
    sigma: f64,
    xs: Vec<f64>,
    ys: Vec<f64>,
    px: Vec<Profile>,
    py: Vec<Profile>,
    offset: usize,
}

impl Group {
    fn len(&self) -> usize {
        self.xs.len() * self.ys.len()
    }
}

/// The `MoG` dictionary for one kernel size, as a [`LinearOperator`] from unit-norm
/// atom coefficients to kernel samples (row-major, the kernel's layout).
#[derive(Clone, Debug)]
pub struct Dictionary {
    params: DictionaryParams,
    width: usize,
    height: usize,
    groups: Vec<Group>,
    atoms: usize,
    scratch: Scratch,
    /// The 1D Gram matrices of [`Dictionary::gram_product`], formed on first
    /// use (`None` when too large).
    grams: std::sync::OnceLock<Option<gram::Grams>>,
}

/// [`Dictionary::apply`]'s per-group sums, kept between calls: a solve
/// applies the dictionary a few hundred times, and allocating a kernel-sized
/// buffer per group each time (fresh pages, faulted in and zeroed) was half
/// of a fit's time.
#[derive(Debug, Default)]
struct Scratch(std::sync::Mutex<Vec<Vec<f64>>>);

impl Clone for Scratch {
    /// A clone starts with no buffers of its own.
    fn clone(&self) -> Self {
        Self::default()
    }
}

impl Scratch {
    /// `n` buffers of `len` samples (contents unspecified).
    fn take(&self, n: usize, len: usize) -> Vec<Vec<f64>> {
        let mut pool = self
            .0
            .lock()
            .map(|mut p| std::mem::take(&mut *p))
            .unwrap_or_default();
        pool.truncate(n);
        for b in &mut pool {
            b.resize(len, 0.0);
        }
        pool.resize_with(n, || vec![0.0; len]);
        pool
    }

    /// Keeps `bufs` for the next call.
    fn give(&self, bufs: Vec<Vec<f64>>) {
        if let Ok(mut p) = self.0.lock() {
            *p = bufs;
        }
    }
}

/// One atom of a [`Dictionary`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Atom {
    /// Centre offset along `x`, px.
    pub x: f64,
    /// Centre offset along `y`, px.
    pub y: f64,
    /// Width (std dev), px.
    pub sigma: f64,
    /// Level, 1-based.
    pub level: usize,
    /// L2 norm of the sampled normalised Gaussian `g_sigma(d - c)`: a unit-norm
    /// coefficient `x_k` is the weight `x_k / norm`.
    pub norm: f64,
}

impl Dictionary {
    /// The dictionary for a `width x height` kernel (odd sizes).
    ///
    /// ```
    /// use ifd_planar::internals::dictionary::{Dictionary, DictionaryParams};
    /// let p = DictionaryParams { levels: 2, ratio: 0.5, sigmas_per_octave: 1, oversampling: 1, half_width: 8.0, min_width: 0.0 };
    /// let d = Dictionary::new(&p, 17, 17);
    /// assert_eq!(d.len(), 9 + 25); // 3x3 then 5x5 centred grids
    /// ```
    #[must_use]
    pub fn new(params: &DictionaryParams, width: usize, height: usize) -> Self {
        Self::with_margin(params, width, height, 0)
    }

    /// As [`Dictionary::new`] for a `width x height` grid whose outer
    /// `margin` pixels lie outside the kernel's window: the atoms sit on the
    /// window's grid only, and are sampled over the whole grid (so that a
    /// fit sees, and suppresses, what they add outside the window).
    ///
    /// ```
    /// use ifd_planar::internals::dictionary::{Dictionary, DictionaryParams};
    /// let p = DictionaryParams { levels: 2, ratio: 0.5, sigmas_per_octave: 1, oversampling: 1, half_width: 8.0, min_width: 0.0 };
    /// assert_eq!(Dictionary::with_margin(&p, 21, 21, 2).len(), Dictionary::new(&p, 17, 17).len());
    /// ```
    #[must_use]
    pub fn with_margin(
        params: &DictionaryParams,
        width: usize,
        height: usize,
        margin: usize,
    ) -> Self {
        let (rx, ry) = (width / 2, height / 2);
        let mut groups = Vec::new();
        let mut offset = 0;
        for (level, sigma) in params.sigmas() {
            let xs = params.grid(level, rx.saturating_sub(margin));
            let ys = params.grid(level, ry.saturating_sub(margin));
            let px = xs
                .iter()
                .map(|&c| Profile::new(c + rx as f64, sigma, width))
                .collect();
            let py = ys
                .iter()
                .map(|&c| Profile::new(c + ry as f64, sigma, height))
                .collect();
            let g = Group {
                level,
                sigma,
                xs,
                ys,
                px,
                py,
                offset,
            };
            offset += g.len();
            groups.push(g);
        }
        Self {
            params: params.clone(),
            width,
            height,
            groups,
            atoms: offset,
            scratch: Scratch::default(),
            grams: std::sync::OnceLock::new(),
        }
    }

    /// The parameters.
    #[must_use]
    pub fn params(&self) -> &DictionaryParams {
        &self.params
    }

    /// Number of atoms.
    #[must_use]
    pub fn len(&self) -> usize {
        self.atoms
    }

    /// Whether there are no atoms.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.atoms == 0
    }

    /// The atom behind coefficient `k`.
    ///
    /// # Panics
    /// When `k >= self.len()`.
    #[must_use]
    pub fn atom(&self, k: usize) -> Atom {
        let (g, j, i) = self.locate(k);
        Atom {
            x: g.xs[i],
            y: g.ys[j],
            sigma: g.sigma,
            level: g.level,
            norm: g.px[i].norm * g.py[j].norm,
        }
    }

    /// Atom `k` as (group index, grid row, grid column).
    fn locate_index(&self, k: usize) -> (usize, usize, usize) {
        let gi = self
            .groups
            .iter()
            .rposition(|g| g.offset <= k)
            .expect("atom index below the first group offset");
        let g = &self.groups[gi];
        let local = k - g.offset;
        (gi, local / g.xs.len(), local % g.xs.len())
    }

    fn locate(&self, k: usize) -> (&Group, usize, usize) {
        let (gi, j, i) = self.locate_index(k);
        (&self.groups[gi], j, i)
    }

    /// The Gram matrix `A_S^T A_S` of the (unit-norm) atoms `idx`, row-major
    /// `s x s`. Separable: `<a_p, a_q> = <gx_p, gx_q> <gy_p, gy_q>`, so each
    /// entry costs two 1D dot products over the overlap of the bands.
    ///
    /// # Panics
    /// When an index is out of range.
    #[must_use]
    pub fn gram(&self, idx: &[usize]) -> Vec<f64> {
        let s = idx.len();
        let mut out = vec![0.0; s * s];
        if let Some(Some(grams)) = self.grams.get() {
            // the solver has formed the 1D Gram matrices: the same profile
            // dots, looked up
            let at: Vec<(usize, usize, usize)> =
                idx.iter().map(|&k| self.locate_index(k)).collect();
            out.par_chunks_mut(s.max(1))
                .enumerate()
                .for_each(|(p, row)| {
                    for q in 0..=p {
                        row[q] = grams.atoms(at[p], at[q]);
                    }
                });
        } else {
            let prof: Vec<(&Profile, &Profile)> = idx
                .iter()
                .map(|&k| {
                    let (g, j, i) = self.locate(k);
                    (&g.px[i], &g.py[j])
                })
                .collect();
            out.par_chunks_mut(s.max(1))
                .enumerate()
                .for_each(|(p, row)| {
                    for q in 0..=p {
                        let gx = profile_dot(prof[p].0, prof[q].0);
                        row[q] = if gx == 0.0 {
                            0.0
                        } else {
                            gx * profile_dot(prof[p].1, prof[q].1)
                        };
                    }
                });
        }
        for p in 0..s {
            for q in 0..p {
                out[q * s + p] = out[p * s + q];
            }
        }
        out
    }

    /// The terms (kernel weights) of unit-norm coefficients `x` (zeros dropped).
    #[must_use]
    pub fn to_terms(&self, x: &[f64]) -> Vec<Term> {
        x.iter()
            .enumerate()
            .filter(|(_, v)| **v != 0.0)
            .map(|(k, &v)| {
                let a = self.atom(k);
                Term {
                    weight: v / a.norm,
                    x: a.x,
                    y: a.y,
                    sigma: a.sigma,
                }
            })
            .collect()
    }

    /// Adds group `g`'s rows `j` of `A x` into `out` (`H x W`), compiled for
    /// the CPU's vectors ([`ifd_simd::run_vectorized`]: the row sums are
    /// element-wise, so every instruction set gives the same bits).
    #[inline(always)]
    #[expect(
        clippy::inline_always,
        reason = "compiled into each target of `ifd_simd::run_vectorized`"
    )]
    fn forward_group(&self, g: &Group, x: &[f64], out: &mut [f64], t: &mut Vec<f64>) {
        let w = self.width;
        let nx = g.xs.len();
        t.resize(w, 0.0);
        for (j, py) in g.py.iter().enumerate() {
            let row = &x[g.offset + j * nx..g.offset + (j + 1) * nx];
            if row.iter().all(|v| *v == 0.0) {
                continue;
            }
            // t = Lambda[j] Gx over the touched columns [c0, c1).
            let (mut c0, mut c1) = (w, 0);
            for (i, &lam) in row.iter().enumerate() {
                if lam != 0.0 {
                    let p = &g.px[i];
                    c0 = c0.min(p.start);
                    c1 = c1.max(p.end());
                }
            }
            t[c0..c1].fill(0.0);
            for (i, &lam) in row.iter().enumerate() {
                if lam != 0.0 {
                    let p = &g.px[i];
                    for (tv, pv) in t[p.start..p.end()].iter_mut().zip(&p.vals) {
                        *tv += lam * pv;
                    }
                }
            }
            // out += Gy[j]^T t
            for (r, &gy) in (py.start..py.end()).zip(&py.vals) {
                let o = &mut out[r * w + c0..r * w + c1];
                for (ov, tv) in o.iter_mut().zip(&t[c0..c1]) {
                    *ov += gy * tv;
                }
            }
        }
    }

    /// Group `g`'s row `j` of `A^T r` into `out` (length `n_x`), compiled
    /// for the CPU's vectors as [`Dictionary::forward_group`] is.
    #[inline(always)]
    #[expect(
        clippy::inline_always,
        reason = "compiled into each target of `ifd_simd::run_vectorized`"
    )]
    fn adjoint_row(&self, g: &Group, j: usize, r: &[f64], out: &mut [f64], p: &mut Vec<f64>) {
        let w = self.width;
        let py = &g.py[j];
        // Columns touched by any atom of the row.
        let c0 = g.px.first().map_or(0, |q| q.start);
        let c1 = g.px.last().map_or(0, Profile::end);
        p.resize(w, 0.0);
        p[c0..c1].fill(0.0);
        for (rr, &gy) in (py.start..py.end()).zip(&py.vals) {
            let src = &r[rr * w + c0..rr * w + c1];
            for (pv, rv) in p[c0..c1].iter_mut().zip(src) {
                *pv += gy * rv;
            }
        }
        for (o, px) in out.iter_mut().zip(&g.px) {
            *o = px
                .vals
                .iter()
                .zip(&p[px.start..px.end()])
                .map(|(a, b)| a * b)
                .sum();
        }
    }
}

/// [`Dictionary::forward_group`]'s arguments, run as an
/// [`ifd_simd::VectorKernel`].
struct Forward<'a> {
    dict: &'a Dictionary,
    g: &'a Group,
    x: &'a [f64],
    out: &'a mut [f64],
    t: &'a mut Vec<f64>,
}

impl ifd_simd::VectorKernel for Forward<'_> {
    type Output = ();
    #[inline(always)]
    #[expect(
        clippy::inline_always,
        reason = "the kernel is compiled into each target of `run_vectorized`"
    )]
    fn run(self) {
        self.dict.forward_group(self.g, self.x, self.out, self.t);
    }
}

/// [`Dictionary::adjoint_row`]'s arguments, run as an
/// [`ifd_simd::VectorKernel`].
struct Adjoint<'a> {
    dict: &'a Dictionary,
    g: &'a Group,
    j: usize,
    r: &'a [f64],
    out: &'a mut [f64],
    p: &'a mut Vec<f64>,
}

impl ifd_simd::VectorKernel for Adjoint<'_> {
    type Output = ();
    #[inline(always)]
    #[expect(
        clippy::inline_always,
        reason = "the kernel is compiled into each target of `run_vectorized`"
    )]
    fn run(self) {
        self.dict
            .adjoint_row(self.g, self.j, self.r, self.out, self.p);
    }
}

impl LinearOperator for Dictionary {
    fn rows(&self) -> usize {
        self.width * self.height
    }

    fn cols(&self) -> usize {
        self.atoms
    }

    fn apply(&self, x: &[f64], out: &mut [f64]) {
        // One buffer per group with non-zero coefficients, computed in
        // parallel, then summed in group order: the result does not depend on
        // how the work was split (a parallel reduction made fits differ from
        // run to run, 320 or 369 terms for `disk:r=6`). Each group writes,
        // and is summed over, only the rows its non-zero atoms reach (adding
        // the zeros elsewhere changed no bit: a sum that starts at +0 is
        // never -0).
        let (n, w) = (self.rows(), self.width);
        let active: Vec<(&Group, std::ops::Range<usize>)> = self
            .groups
            .iter()
            .filter_map(|g| {
                let nx = g.xs.len();
                let rows =
                    g.py.iter()
                        .enumerate()
                        .filter(|(j, _)| {
                            x[g.offset + j * nx..g.offset + (j + 1) * nx]
                                .iter()
                                .any(|v| *v != 0.0)
                        })
                        .fold(None, |r: Option<(usize, usize)>, (_, py)| {
                            let (a, b) = r.unwrap_or((py.start, py.end()));
                            Some((a.min(py.start), b.max(py.end())))
                        })?;
                Some((g, rows.0 * w..rows.1 * w))
            })
            .collect();
        let mut parts = self.scratch.take(active.len(), n);
        parts
            .par_iter_mut()
            .zip(&active)
            .for_each_init(Vec::new, |t, (acc, (g, range))| {
                acc[range.clone()].fill(0.0);
                ifd_simd::run_vectorized(Forward {
                    dict: self,
                    g,
                    x,
                    out: acc,
                    t,
                });
            });
        out.par_chunks_mut(4096).enumerate().for_each(|(c, chunk)| {
            chunk.fill(0.0);
            let start = c * 4096;
            let end = start + chunk.len();
            for (part, (_, range)) in parts.iter().zip(&active) {
                let (a, b) = (range.start.max(start), range.end.min(end));
                if a < b {
                    for (o, v) in chunk[a - start..b - start].iter_mut().zip(&part[a..b]) {
                        *o += v;
                    }
                }
            }
        });
        self.scratch.give(parts);
    }

    fn apply_adjoint(&self, r: &[f64], out: &mut [f64]) {
        // One task per (group, grid row): each writes a disjoint slice of `out`.
        let mut tasks: Vec<(&Group, usize, &mut [f64])> = Vec::new();
        let mut rest = out;
        for g in &self.groups {
            for j in 0..g.ys.len() {
                let (head, tail) = rest.split_at_mut(g.xs.len());
                tasks.push((g, j, head));
                rest = tail;
            }
        }
        tasks
            .into_par_iter()
            .for_each_init(Vec::new, |p, (g, j, o)| {
                ifd_simd::run_vectorized(Adjoint {
                    dict: self,
                    g,
                    j,
                    r,
                    out: o,
                    p,
                });
            });
    }

    fn gram_apply(&self, idx: &[usize], vals: &[f64], out: &mut [f64]) -> bool {
        self.gram_product(idx, vals, out)
    }

    fn apply_adjoint_subset(&self, r: &[f64], idx: &[usize], out: &mut [f64]) {
        let w = self.width;
        out.par_iter_mut().zip(idx).for_each(|(o, &k)| {
            let (g, j, i) = self.locate(k);
            let (px, py) = (&g.px[i], &g.py[j]);
            let mut s = 0.0;
            for (rr, &gy) in (py.start..py.end()).zip(&py.vals) {
                let row = &r[rr * w + px.start..rr * w + px.end()];
                s += gy * row.iter().zip(&px.vals).map(|(a, b)| a * b).sum::<f64>();
            }
            *o = s;
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn small() -> Dictionary {
        let p = DictionaryParams {
            levels: 3,
            ratio: 0.5,
            sigmas_per_octave: 2,
            oversampling: 1,
            half_width: 10.0,
            min_width: 0.0,
        };
        Dictionary::new(&p, 21, 15)
    }

    #[test]
    fn adjoint_matches_forward() {
        let d = small();
        let x: Vec<f64> = (0..d.len())
            .map(|k| ((k * 37 % 11) as f64 - 5.0) * f64::from(u8::from(k % 3 == 0)))
            .collect();
        let r: Vec<f64> = (0..d.rows())
            .map(|k| ((k * 13 % 7) as f64 - 3.0) / 3.0)
            .collect();
        let mut ax = vec![0.0; d.rows()];
        d.apply(&x, &mut ax);
        let mut atr = vec![0.0; d.len()];
        d.apply_adjoint(&r, &mut atr);
        let lhs: f64 = ax.iter().zip(&r).map(|(a, b)| a * b).sum();
        let rhs: f64 = x.iter().zip(&atr).map(|(a, b)| a * b).sum();
        assert!(
            (lhs - rhs).abs() < 1e-10 * lhs.abs().max(1.0),
            "{lhs} vs {rhs}"
        );
        let idx = [0, 5, d.len() - 1];
        let mut sub = [0.0; 3];
        d.apply_adjoint_subset(&r, &idx, &mut sub);
        for (s, &k) in sub.iter().zip(&idx) {
            assert!((s - atr[k]).abs() < 1e-12);
        }
        // Gram entries against explicit columns.
        let cols: Vec<Vec<f64>> = idx
            .iter()
            .map(|&k| {
                let mut e = vec![0.0; d.len()];
                e[k] = 1.0;
                let mut c = vec![0.0; d.rows()];
                d.apply(&e, &mut c);
                c
            })
            .collect();
        let g = d.gram(&idx);
        for p in 0..3 {
            for q in 0..3 {
                let dot: f64 = cols[p].iter().zip(&cols[q]).map(|(a, b)| a * b).sum();
                assert!((g[p * 3 + q] - dot).abs() < 1e-12, "{p} {q}");
            }
        }
    }

    #[test]
    fn columns_are_sampled_gaussians_with_unit_norm() {
        let d = small();
        let k = d.len() - 7;
        let mut e = vec![0.0; d.len()];
        e[k] = 1.0;
        let mut col = vec![0.0; d.rows()];
        d.apply(&e, &mut col);
        let norm: f64 = col.iter().map(|v| v * v).sum::<f64>().sqrt();
        assert!((norm - 1.0).abs() < 1e-12);
        let t = d.to_terms(&e)[0];
        let dec = crate::Decomposition::from_terms(vec![t]);
        for row in 0..15 {
            for c in 0..21 {
                let v = dec.eval(c as f64 - 10.0, row as f64 - 7.0);
                assert!((v - col[row * 21 + c]).abs() < 1e-7 * t.weight.abs().max(1.0));
            }
        }
    }

    #[test]
    fn grids_are_centred_and_levels_resolve() {
        let d = small();
        let a = d.atom(4); // the centre of the 3x3 level-1 grid
        assert_eq!((a.x, a.y, a.level), (0.0, 0.0, 1));
        let p = d.params();
        assert_eq!(p.level_of(p.sigma(2)), 2);
        assert_eq!(p.level_of(p.sigma(2) * 1.5), 2);
        assert_eq!(p.level_of(p.sigma(3)), 3);
    }

    #[test]
    fn gram_product_is_the_adjoint_of_the_forward_image() {
        // A^T A d through the Gram structure against A^T (A d) through the
        // image, for a sparse d spread over every group and a dense one.
        let d = small();
        for every in [7, 1] {
            let x: Vec<f64> = (0..d.len())
                .map(|k| {
                    if k % every == 0 {
                        ((k * 29 % 13) as f64 - 6.0) / 6.0
                    } else {
                        0.0
                    }
                })
                .collect();
            let mut ax = vec![0.0; d.rows()];
            d.apply(&x, &mut ax);
            let mut want = vec![0.0; d.len()];
            d.apply_adjoint(&ax, &mut want);
            let idx: Vec<usize> = (0..d.len()).filter(|&k| x[k] != 0.0).collect();
            let vals: Vec<f64> = idx.iter().map(|&k| x[k]).collect();
            let mut got = vec![f64::NAN; d.len()];
            assert!(d.gram_apply(&idx, &vals, &mut got));
            let scale = want.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
            for (k, (g, w)) in got.iter().zip(&want).enumerate() {
                assert!((g - w).abs() <= 1e-12 * scale, "atom {k}: {g} vs {w}");
            }
        }
        // The support Gram from the formed 1D Gram matrices is the one from
        // the profiles, bit for bit.
        let fresh = small();
        let idx: Vec<usize> = (0..fresh.len()).step_by(3).collect();
        let from_profiles = fresh.gram(&idx);
        assert!(fresh.gram_apply(&[], &[], &mut vec![0.0; fresh.len()]));
        assert_eq!(fresh.gram(&idx), from_profiles);
        // An empty step gives zeros.
        let mut out = vec![1.0; d.len()];
        assert!(d.gram_apply(&[], &[], &mut out));
        assert!(out.iter().all(|v| *v == 0.0));
    }
}
