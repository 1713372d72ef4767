//! `A^T A d` for a sparse `d` from the dictionary's separable Gram structure,
//! without the image `A d` (what the solver's coefficient-space iterations
//! use, see [`crate::sparsa::Sparsa`]).
//!
//! # Derivation
//! Atoms are products of unit-norm 1D profiles, `a_k = px_{i(k)} (x) py_{j(k)}`,
//! so `<a_p, a_q> = <px_{i(p)}, px_{i(q)}> <py_{j(p)}, py_{j(q)}>`. With `X` the
//! Gram matrix of every x-profile of every group against every other (and
//! `Y` likewise), the entry of `A^T A d` at atom `(g, jj, ii)` (group `g`,
//! grid row `jj`, column `ii`) is
//!
//! `sum_{(h, j)} Y[(g, jj), (h, j)] sum_{i} X[(g, ii), (h, i)] d_{(h, j, i)}`,
//!
//! the outer sum over the grid rows `(h, j)` that hold a non-zero of `d`.
//! Per such row and target group, the inner sum is one vector `t` over the
//! target's columns (one axpy of a row of `X` per non-zero), and the outer
//! adds `Y[(g, jj), (h, j)] t` to each target row `jj` where that factor is
//! not zero. `X` and `Y` are banded (profiles are cut at 6 sigma), so each
//! row of them is kept with the range of its non-zero entries per group,
//! and the work is proportional to the overlaps, not to the grids: for the
//! few hundred non-zeros of a solver step it is a small fraction of one
//! image-space adjoint.
//!
//! Every target group is summed in one fixed order (rows of `d` in
//! increasing atom order), whatever the threads, so results do not depend
//! on the split.

use rayon::prelude::*;

use super::{Dictionary, Group, Profile, profile_dot};

/// The most entries of the two 1D Gram matrices together (64 MiB); larger
/// dictionaries go through the image.
const MAX_ENTRIES: usize = 1 << 23;

/// One axis' 1D Gram matrix over all groups' profiles.
#[derive(Clone, Debug)]
struct Axis {
    /// Number of profiles (all groups).
    n: usize,
    /// Group `g`'s first profile.
    start: Vec<usize>,
    /// `n x n`, row-major.
    gram: Vec<f64>,
    /// Per profile `a` and group `g` (`a * groups + g`): the range, local to
    /// group `g`, of the non-zero entries of row `a` within group `g`'s
    /// columns (empty when none).
    nz: Vec<(u32, u32)>,
}

impl Axis {
    fn new(groups: &[Group], profiles: impl Fn(&Group) -> &[Profile]) -> Self {
        let mut start = Vec::with_capacity(groups.len());
        let mut all: Vec<&Profile> = Vec::new();
        for g in groups {
            start.push(all.len());
            all.extend(profiles(g));
        }
        let n = all.len();
        // the lower triangle, then its mirror (a profile dot is symmetric
        // bit for bit: the same products summed in the same order)
        let mut gram = vec![0.0; n * n];
        gram.par_chunks_mut(n.max(1))
            .enumerate()
            .for_each(|(a, row)| {
                for (b, v) in row.iter_mut().enumerate().take(a + 1) {
                    *v = profile_dot(all[a], all[b]);
                }
            });
        for a in 0..n {
            for b in 0..a {
                gram[b * n + a] = gram[a * n + b];
            }
        }
        let ng = groups.len();
        let mut nz = vec![(0, 0); n * ng];
        for a in 0..n {
            for g in 0..ng {
                let (s, e) = (start[g], start.get(g + 1).copied().unwrap_or(n));
                let row = &gram[a * n + s..a * n + e];
                let lo = row.iter().position(|v| *v != 0.0);
                let hi = row.iter().rposition(|v| *v != 0.0);
                if let (Some(lo), Some(hi)) = (lo, hi) {
                    nz[a * ng + g] = (lo as u32, hi as u32 + 1);
                }
            }
        }
        Self { n, start, gram, nz }
    }

    /// Row `a`'s entries over group `g`'s profiles, and their non-zero range.
    fn row(&self, a: usize, g: usize, len: usize) -> (&[f64], std::ops::Range<usize>) {
        let s = a * self.n + self.start[g];
        let (lo, hi) = self.nz[a * self.start.len() + g];
        (&self.gram[s..s + len], lo as usize..hi as usize)
    }
}

impl Axis {
    /// `<p_a, p_b>` of profile `i` of group `g` and profile `j` of group `h`.
    fn at(&self, (g, i): (usize, usize), (h, j): (usize, usize)) -> f64 {
        self.gram[(self.start[g] + i) * self.n + self.start[h] + j]
    }
}

/// The two 1D Gram matrices of a dictionary.
#[derive(Clone, Debug)]
pub(super) struct Grams {
    x: Axis,
    y: Axis,
}

impl Grams {
    /// The Gram matrices of `groups`, `None` past [`MAX_ENTRIES`].
    pub(super) fn new(groups: &[Group]) -> Option<Self> {
        let nx: usize = groups.iter().map(|g| g.px.len()).sum();
        let ny: usize = groups.iter().map(|g| g.py.len()).sum();
        if nx.saturating_mul(nx).saturating_add(ny.saturating_mul(ny)) > MAX_ENTRIES {
            return None;
        }
        Some(Self {
            x: Axis::new(groups, |g| &g.px),
            y: Axis::new(groups, |g| &g.py),
        })
    }
}

impl Grams {
    /// `<a_p, a_q>` of two atoms given as (group, grid row, grid column):
    /// the product of their profiles' dots, zero where the x profiles do not
    /// overlap ([`Dictionary::gram`]'s rule).
    pub(super) fn atoms(&self, p: (usize, usize, usize), q: (usize, usize, usize)) -> f64 {
        let gx = self.x.at((p.0, p.2), (q.0, q.2));
        if gx == 0.0 {
            0.0
        } else {
            gx * self.y.at((p.0, p.1), (q.0, q.1))
        }
    }
}

/// A grid row of `d` with non-zeros: its group, row and the span of its
/// entries in `idx`/`vals`.
struct SourceRow {
    h: usize,
    j: usize,
    span: std::ops::Range<usize>,
}

impl Dictionary {
    /// `out = A^T A d` for `d`'s non-zeros `vals` at increasing `idx`
    /// (see the module documentation); `false` when the Gram matrices
    /// would be too large.
    pub(super) fn gram_product(&self, idx: &[usize], vals: &[f64], out: &mut [f64]) -> bool {
        let Some(grams) = self.grams.get_or_init(|| Grams::new(&self.groups)) else {
            return false;
        };
        // The rows of d, in atom order.
        let mut rows: Vec<SourceRow> = Vec::new();
        let mut h = 0;
        debug_assert!(
            idx.windows(2).all(|w| w[0] < w[1]) && idx.last().is_none_or(|&k| k < self.atoms),
            "gram_product: indices increasing and in range"
        );
        for (p, &k) in idx.iter().enumerate() {
            while h + 1 < self.groups.len() && self.groups[h + 1].offset <= k {
                h += 1;
            }
            let g = &self.groups[h];
            let j = (k - g.offset) / g.xs.len();
            match rows.last_mut() {
                Some(r) if r.h == h && r.j == j => r.span.end = p + 1,
                _ => rows.push(SourceRow {
                    h,
                    j,
                    span: p..p + 1,
                }),
            }
        }
        // Each target group's block of `out`.
        let mut blocks: Vec<(&Group, &mut [f64])> = Vec::with_capacity(self.groups.len());
        let mut rest = out;
        for g in &self.groups {
            let (head, tail) = rest.split_at_mut(g.len());
            blocks.push((g, head));
            rest = tail;
        }
        blocks.into_par_iter().enumerate().for_each_init(
            Vec::new,
            |t: &mut Vec<f64>, (gi, (g, block))| {
                block.fill(0.0);
                let (nx, ny) = (g.px.len(), g.py.len());
                t.resize(nx, 0.0);
                for r in &rows {
                    let src = &self.groups[r.h];
                    let (yrow, ys) = grams.y.row(grams.y.start[r.h] + r.j, gi, ny);
                    if ys.is_empty() {
                        continue;
                    }
                    // t = sum_i d_i X[(g, .), (h, i)] over the columns touched
                    let (mut c0, mut c1) = (nx, 0);
                    for p in r.span.clone() {
                        let i = idx[p] - src.offset - r.j * src.xs.len();
                        let (_, cs) = grams.x.row(grams.x.start[r.h] + i, gi, nx);
                        if !cs.is_empty() {
                            c0 = c0.min(cs.start);
                            c1 = c1.max(cs.end);
                        }
                    }
                    if c0 >= c1 {
                        continue;
                    }
                    t[c0..c1].fill(0.0);
                    for p in r.span.clone() {
                        let i = idx[p] - src.offset - r.j * src.xs.len();
                        let (xrow, _) = grams.x.row(grams.x.start[r.h] + i, gi, nx);
                        let v = vals[p];
                        for (tv, xv) in t[c0..c1].iter_mut().zip(&xrow[c0..c1]) {
                            *tv += v * xv;
                        }
                    }
                    for jj in ys {
                        let c = yrow[jj];
                        let o = &mut block[jj * nx + c0..jj * nx + c1];
                        for (ov, tv) in o.iter_mut().zip(&t[c0..c1]) {
                            *ov += c * tv;
                        }
                    }
                }
            },
        );
        true
    }
}
