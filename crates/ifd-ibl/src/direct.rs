//! The direct part of a prefiltered level: the bright texels' sub-texel
//! samples summed against the lobe at each output direction, cells of
//! samples far from the direction through their totals.
//!
//! The cells sit in vector lanes ([`CellLanes`]): per output direction one
//! pass over the lanes takes every cell's dot product, its far-field term
//! and whether it is near (its samples are then summed eight at a time, also
//! in lanes); the lanes' sums are added in a fixed order at the end.

use crate::lobe::Lobe;

/// One bright sub-texel: direction (ifd frame) and `excess x solid angle`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Sample {
    pub(crate) d: [f64; 3],
    pub(crate) w: [f64; 3],
}

/// A group of bright samples with its bounding cone and total.
#[derive(Clone, Debug)]
pub(crate) struct Cell {
    pub(crate) centre: [f64; 3],
    pub(crate) total: [f64; 3],
    pub(crate) samples: std::ops::Range<usize>,
    /// `d . centre` at or below this: the whole cell is behind the lobe
    /// (angle - radius >= pi/2).
    pub(crate) cos_behind: f64,
    /// `d . centre` below this: far enough for the cell's total (angle >
    /// max(16 radius, near)).
    pub(crate) cos_far: f64,
}

/// Cells a vector holds.
const LANES: usize = 8;

/// The cells of a level, structure of arrays in groups of [`LANES`]
/// (padding lanes: behind everything, zero totals), and each cell's samples
/// likewise (padding lanes: zero weight).
pub(crate) struct CellLanes {
    centre: [Vec<[f64; LANES]>; 3],
    total: [Vec<[f64; LANES]>; 3],
    behind: Vec<[f64; LANES]>,
    far: Vec<[f64; LANES]>,
    /// Each cell's groups of samples in `sample_d` and `sample_w`.
    groups: Vec<std::ops::Range<usize>>,
    sample_d: [Vec<[f64; LANES]>; 3],
    sample_w: [Vec<[f64; LANES]>; 3],
}

impl CellLanes {
    pub(crate) fn new(cells: &[Cell], samples: &[Sample]) -> Self {
        let n = cells.len().div_ceil(LANES);
        let zeros = || vec![[0.0; LANES]; n];
        let mut s = Self {
            centre: [zeros(), zeros(), zeros()],
            total: [zeros(), zeros(), zeros()],
            behind: vec![[2.0; LANES]; n],
            far: vec![[2.0; LANES]; n],
            groups: Vec::with_capacity(cells.len()),
            sample_d: [Vec::new(), Vec::new(), Vec::new()],
            sample_w: [Vec::new(), Vec::new(), Vec::new()],
        };
        for c in cells {
            let first = s.sample_d[0].len();
            for chunk in samples[c.samples.clone()].chunks(LANES) {
                for a in 0..3 {
                    s.sample_d[a].push(std::array::from_fn(|k| {
                        chunk.get(k).map_or(0.0, |x| x.d[a])
                    }));
                    s.sample_w[a].push(std::array::from_fn(|k| {
                        chunk.get(k).map_or(0.0, |x| x.w[a])
                    }));
                }
            }
            s.groups.push(first..s.sample_d[0].len());
        }
        for (i, c) in cells.iter().enumerate() {
            let (g, k) = (i / LANES, i % LANES);
            for a in 0..3 {
                s.centre[a][g][k] = c.centre[a];
                s.total[a][g][k] = c.total[a];
            }
            s.behind[g][k] = c.cos_behind;
            s.far[g][k] = c.cos_far;
        }
        s
    }
}

/// `sum_b w_b k(d . l_b)` over the bright samples, cells far from `d`
/// through their totals (the thresholds are precomputed cosines: one dot
/// product decides per cell). Call inside a [`ifd_simd::VectorKernel`]
/// (it is `#[inline(always)]`).
#[inline(always)]
#[expect(
    clippy::inline_always,
    reason = "compiled into each target of `ifd_simd::run_vectorized`"
)]
pub(crate) fn direct_sum(lobe: &Lobe, lanes: &CellLanes, d: [f64; 3]) -> [f64; 3] {
    match *lobe {
        Lobe::Ggx { alpha } => {
            // Lobe::eval's formula, operation for operation
            let a2 = alpha * alpha;
            lane_sum(lanes, d, |t| {
                let c2 = 0.5 * (1.0 + t);
                let q = c2 * (a2 - 1.0) + 1.0;
                a2 / (std::f64::consts::PI * q * q) * t
            })
        }
        Lobe::Lambert => lane_sum(lanes, d, |t| t),
        Lobe::Phong { s } => lane_sum(lanes, d, |t| t.max(0.0).powf(s)),
        Lobe::Mirror => [0.0; 3],
    }
}

/// [`direct_sum`] with the lobe's value `k(t)` for `t > 0` as `eval` (the
/// lanes zero `t <= 0`), for the cells' totals and the near cells' samples.
#[inline(always)]
#[expect(
    clippy::inline_always,
    reason = "compiled into each target of `ifd_simd::run_vectorized`"
)]
#[allow(
    clippy::needless_bitwise_bool,
    clippy::needless_range_loop,
    reason = "straight-line lane loops with non-short-circuit masks vectorise"
)]
fn lane_sum(lanes: &CellLanes, d: [f64; 3], eval: impl Fn(f64) -> f64) -> [f64; 3] {
    let mut acc = [[0.0; LANES]; 3];
    let mut near = [[0.0; LANES]; 3];
    let [cx, cy, cz] = &lanes.centre;
    for g in 0..lanes.behind.len() {
        let (behind, far) = (&lanes.behind[g], &lanes.far[g]);
        // straight-line lane loops (non-short-circuit masks): they vectorise
        let mut c = [0.0; LANES];
        for k in 0..LANES {
            c[k] = d[0] * cx[g][k] + d[1] * cy[g][k] + d[2] * cz[g][k];
        }
        let mut kf = [0.0; LANES];
        let mut any_near = false;
        for k in 0..LANES {
            let v = eval(c[k]);
            let ahead = c[k] > behind[k];
            kf[k] = if ahead & (c[k] < far[k]) & (c[k] > 0.0) {
                v
            } else {
                0.0
            };
            any_near |= ahead & (c[k] >= far[k]);
        }
        for a in 0..3 {
            let t = &lanes.total[a][g];
            for k in 0..LANES {
                acc[a][k] += kf[k] * t[k];
            }
        }
        if any_near {
            for k in 0..LANES {
                if c[k] > behind[k] && c[k] >= far[k] {
                    // the near cell's samples, in lanes
                    let [sx, sy, sz] = &lanes.sample_d;
                    for q in lanes.groups[g * LANES + k].clone() {
                        let mut kv = [0.0; LANES];
                        for i in 0..LANES {
                            let t = d[0] * sx[q][i] + d[1] * sy[q][i] + d[2] * sz[q][i];
                            let v = eval(t);
                            kv[i] = if t > 0.0 { v } else { 0.0 };
                        }
                        for a in 0..3 {
                            let w = &lanes.sample_w[a][q];
                            for i in 0..LANES {
                                near[a][i] += kv[i] * w[i];
                            }
                        }
                    }
                }
            }
        }
    }
    std::array::from_fn(|a| acc[a].iter().sum::<f64>() + near[a].iter().sum::<f64>())
}

/// [`direct_sum`] at each direction of `dirs` into `out`, compiled for the
/// CPU's vectors.
pub(crate) struct DirectRow<'a> {
    pub(crate) lobe: &'a Lobe,
    pub(crate) lanes: &'a CellLanes,
    pub(crate) dirs: &'a [[f64; 3]],
    pub(crate) out: &'a mut [[f64; 3]],
}

impl ifd_simd::VectorKernel for DirectRow<'_> {
    type Output = ();
    #[inline(always)]
    #[allow(
        clippy::inline_always,
        reason = "the kernel is compiled into each target of `run_vectorized`"
    )]
    fn run(self) {
        for (o, &d) in self.out.iter_mut().zip(self.dirs) {
            *o = direct_sum(self.lobe, self.lanes, d);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    /// The old scalar loop, cell by cell and sample by sample.
    fn reference(lobe: &Lobe, samples: &[Sample], cells: &[Cell], d: [f64; 3]) -> [f64; 3] {
        let mut acc = [0.0; 3];
        for cell in cells {
            let c = DVec3::from(d).dot(DVec3::from(cell.centre));
            if c <= cell.cos_behind {
                continue;
            }
            if c < cell.cos_far {
                let k = lobe.eval(c);
                for (a, t) in acc.iter_mut().zip(cell.total) {
                    *a += k * t;
                }
            } else {
                for s in &samples[cell.samples.clone()] {
                    let k = lobe.eval(DVec3::from(d).dot(DVec3::from(s.d)));
                    for (a, w) in acc.iter_mut().zip(s.w) {
                        *a += k * w;
                    }
                }
            }
        }
        acc
    }

    fn unit(rng: &mut u64) -> [f64; 3] {
        let mut next = || {
            *rng = rng
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (*rng >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        let v = DVec3::new(next(), next(), next()).normalize();
        v.to_array()
    }

    /// The lanes give the scalar loop's sums (to rounding: the order of the
    /// additions differs) for every lobe kind, with cells of 1 to 19 samples
    /// (partial lane groups), cells ahead, behind and near, and a cell count
    /// that is not a multiple of the lanes.
    #[test]
    fn lanes_match_the_scalar_loop() {
        let mut rng = 7u64;
        let mut samples = Vec::new();
        let mut cells = Vec::new();
        for i in 0..29 {
            let centre = unit(&mut rng);
            let first = samples.len();
            let mut total = [0.0; 3];
            for k in 0..=(i * 7) % 19 {
                let jitter = unit(&mut rng);
                let d = (DVec3::from(centre) + 0.05 * DVec3::from(jitter)).normalize();
                let w = [0.1 + k as f64 * 0.01, 0.2, 0.05 * (i % 3) as f64];
                for (t, x) in total.iter_mut().zip(w) {
                    *t += x;
                }
                samples.push(Sample { d: d.to_array(), w });
            }
            let radius = 0.06;
            cells.push(Cell {
                centre,
                total,
                samples: first..samples.len(),
                cos_behind: -f64::sin(radius),
                cos_far: (0.1 + 0.05 * (i % 5) as f64).cos(),
            });
        }
        let lanes = CellLanes::new(&cells, &samples);
        for lobe in [
            Lobe::Ggx { alpha: 0.05 },
            Lobe::Ggx { alpha: 0.6 },
            Lobe::Lambert,
            Lobe::Phong { s: 20.0 },
        ] {
            let (mut near, mut far) = (0, 0);
            for _ in 0..300 {
                let d = unit(&mut rng);
                let want = reference(&lobe, &samples, &cells, d);
                let got = direct_sum(&lobe, &lanes, d);
                for c in 0..3 {
                    assert!(
                        (got[c] - want[c]).abs() <= 1e-12 * want[c].abs().max(1e-300),
                        "{lobe:?} channel {c}: {} vs {}",
                        got[c],
                        want[c]
                    );
                }
                for cell in &cells {
                    let c = DVec3::from(d).dot(DVec3::from(cell.centre));
                    near += usize::from(c >= cell.cos_far);
                    far += usize::from(c > cell.cos_behind && c < cell.cos_far);
                }
            }
            assert!(near > 20 && far > 1000, "{lobe:?}: {near} near, {far} far");
        }
        // no cells: nothing
        let empty = CellLanes::new(&[], &[]);
        assert_eq!(
            direct_sum(&Lobe::Lambert, &empty, [0.0, 0.0, 1.0]),
            [0.0; 3]
        );
    }
}
