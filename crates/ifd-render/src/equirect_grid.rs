//! Which texel of an equirectangular grid a direction falls in, without an
//! `acos` or an `atan2` per lookup.
//!
//! Texel `(u, v)` of a `W x H` map rotated by `a` about `+z` covers the polar
//! angles `[v pi / H, (v + 1) pi / H)` and the azimuths `[a + 2 pi u / W,
//! a + 2 pi (u + 1) / W)`. In terms of the direction `d = (x, y, z)` that is
//!
//! - row `v`: `cos((v + 1) pi / H) < z <= cos(v pi / H)`, a comparison of `z`
//!   with the table of the rows' edge cosines;
//! - column `u`: `(x, y)` lies counter-clockwise of (or on) edge `u` and
//!   clockwise of edge `u + 1`, where edge `k` is the unit vector `e_k` at
//!   azimuth `a + 2 pi k / W`; "`(x, y)` counter-clockwise of `e`" is the
//!   sign of the cross product `e_x y - e_y x` (exact for neighbouring edges,
//!   less than half a turn apart).
//!
//! A polynomial `atan2` (error below `1e-7` rad, far below a texel) guesses
//! the texel; the comparisons with the edge tables then move the guess to
//! the texel the definition gives. The result is what `floor(acos(z) H /
//! pi)` and `floor(((atan2(y, x) - a) mod 2 pi) W / 2 pi)` give with
//! exact arithmetic; libm's rounded results can differ from it only for
//! directions within a few ulps of an edge.

use std::f64::consts::{FRAC_PI_2, PI, TAU};

/// The edge tables of a `W x H` equirectangular grid rotated by `a` about
/// `+z`.
#[derive(Clone, Debug)]
pub(crate) struct EquirectGrid {
    w: usize,
    h: usize,
    rotation: f64,
    /// `cos(k pi / H)`, `k = 0..=H` (decreasing).
    row_cos: Vec<f64>,
    /// The unit vector at azimuth `a + 2 pi k / W`, `k = 0..=W` (the last
    /// is the first again).
    col_edge: Vec<[f64; 2]>,
}

impl EquirectGrid {
    /// The tables of a `w x h` grid (`w, h >= 1`) rotated by `rotation`
    /// radians about `+z`.
    pub(crate) fn new(w: usize, h: usize, rotation: f64) -> Self {
        let row_cos = (0..=h).map(|k| (k as f64 * PI / h as f64).cos()).collect();
        let col_edge = (0..=w)
            .map(|k| {
                let (s, c) = (rotation + TAU * (k % w) as f64 / w as f64).sin_cos();
                [c, s]
            })
            .collect();
        Self {
            w,
            h,
            rotation,
            row_cos,
            col_edge,
        }
    }

    /// The index `v W + u` of the texel seen in direction `d` (unit).
    /// Non-unit directions are read by their `z` (clamped to `[-1, 1]`) and
    /// their azimuth; the poles' axis (`x = y = 0`) and non-finite
    /// directions fall back to the inverse trigonometric formula.
    pub(crate) fn texel(&self, d: [f64; 3]) -> usize {
        self.texel_near(d, None)
    }

    /// [`Self::texel`], starting from `near`, the texel of a nearby
    /// direction (the pixel before on a row), when given: a step or two
    /// from it instead of a guess from the angles, which stays the answer's
    /// fallback when `near` is more than two texels away.
    pub(crate) fn texel_near(&self, d: [f64; 3], near: Option<usize>) -> usize {
        let [x, y, z] = d;
        let rho2 = x * x + y * y;
        if !(rho2 > 0.0 && rho2.is_finite() && z.is_finite()) {
            return self.texel_trig(d);
        }
        let (w, h) = (self.w, self.h);
        let z = z.clamp(-1.0, 1.0);
        if let Some(t) = near.filter(|&t| t < w * h)
            && let (Some(v), Some(u)) = (self.walk_row(z, t / w, 2), self.walk_col(x, y, t % w, 2))
        {
            return v * w + u;
        }
        // guesses from the angles, then z and (x, y) against the edges
        let theta = atan2_approx(rho2.sqrt(), z);
        let v = ((theta * (h as f64 / PI)) as usize).min(h - 1);
        let p = atan2_approx(y, x) - self.rotation;
        let p = p - TAU * (p / TAU).floor();
        let u = ((p * (w as f64 / TAU)) as usize).min(w - 1);
        // at most a turn of steps (a guess is off by one or none)
        let v = self.walk_row(z, v, h).unwrap_or(v);
        let u = self.walk_col(x, y, u, w).unwrap_or(u);
        v * w + u
    }

    /// The row holding `z` (clamped), at most `steps` rows from `v`.
    fn walk_row(&self, z: f64, mut v: usize, steps: usize) -> Option<usize> {
        let h = self.h;
        for _ in 0..=steps {
            if v > 0 && z > self.row_cos[v] {
                v -= 1;
            } else if v + 1 < h && z <= self.row_cos[v + 1] {
                v += 1;
            } else {
                return Some(v);
            }
        }
        None
    }

    /// The column holding the azimuth of `(x, y)`, at most `steps` columns
    /// from `u` (either way round).
    fn walk_col(&self, x: f64, y: f64, mut u: usize, steps: usize) -> Option<usize> {
        let w = self.w;
        let ccw = |k: usize| {
            let [ex, ey] = self.col_edge[k];
            ex * y - ey * x >= 0.0
        };
        for _ in 0..=steps {
            if !ccw(u) {
                u = if u == 0 { w - 1 } else { u - 1 };
            } else if ccw(u + 1) {
                u = if u + 1 == w { 0 } else { u + 1 };
            } else {
                return Some(u);
            }
        }
        None
    }

    /// The inverse trigonometric formula (libm's rounding).
    pub(crate) fn texel_trig(&self, d: [f64; 3]) -> usize {
        let (w, h) = (self.w, self.h);
        let t = d[2].clamp(-1.0, 1.0).acos();
        let p = (d[1].atan2(d[0]) - self.rotation).rem_euclid(TAU);
        let u = ((p / TAU * w as f64) as usize).min(w - 1);
        let v = ((t / PI * h as f64) as usize).min(h - 1);
        v * w + u
    }
}

/// `atan2(y, x)` for finite `(x, y) != (0, 0)` within `1e-7` rad: the
/// octant's reduction to `atan(r)`, `0 <= r <= 1`, and Hastings' degree-17
/// odd polynomial for it (Abramowitz and Stegun 4.4.49, `|error| <= 2e-8`).
pub(crate) fn atan2_approx(y: f64, x: f64) -> f64 {
    let (ax, ay) = (x.abs(), y.abs());
    let swap = ay > ax;
    let r = if swap { ax / ay } else { ay / ax };
    let r2 = r * r;
    let mut a = 0.002_866_225_7;
    for c in [
        -0.016_165_736_7,
        0.042_909_613_8,
        -0.075_289_640_0,
        0.106_562_639_3,
        -0.142_088_994_4,
        0.199_935_508_5,
        -0.333_331_452_8,
        1.0,
    ] {
        a = a * r2 + c;
    }
    let mut a = a * r;
    if swap {
        a = FRAC_PI_2 - a;
    }
    if x < 0.0 {
        a = PI - a;
    }
    if y < 0.0 { -a } else { a }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic stream of uniform numbers in [0, 1).
    fn uniforms(seed: u64) -> impl Iterator<Item = f64> {
        let mut s = seed;
        std::iter::repeat_with(move || {
            s = s
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        })
    }

    #[test]
    fn atan2_approx_is_within_1e7_of_libm() {
        let mut worst = 0.0f64;
        let mut r = uniforms(1);
        for _ in 0..200_000 {
            let (x, y) = (2.0 * r.next().unwrap() - 1.0, 2.0 * r.next().unwrap() - 1.0);
            worst = worst.max((atan2_approx(y, x) - y.atan2(x)).abs());
        }
        for (y, x) in [(0.0, 1.0), (1.0, 0.0), (0.0, -1.0), (-1.0, 0.0), (1.0, 1.0)] {
            worst = worst.max((atan2_approx(y, x) - f64::atan2(y, x)).abs());
        }
        assert!(worst < 1e-7, "{worst}");
    }

    /// Random directions on every grid size and rotation tried land in the
    /// texel the inverse trigonometric formula gives (edges are a measure
    /// zero set), and directions just either side of every edge in the
    /// texel on their side.
    #[test]
    fn texels_match_the_trigonometric_formula() {
        let mut r = uniforms(7);
        for (w, h, rot) in [
            (2, 1, 0.0),
            (4, 2, 0.3),
            (128, 64, 0.0),
            (256, 128, -2.5),
            (2048, 1024, 1.0),
        ] {
            let g = EquirectGrid::new(w, h, rot);
            for _ in 0..50_000 {
                let z = 2.0 * r.next().unwrap() - 1.0;
                let phi = TAU * r.next().unwrap();
                let s = (1.0 - z * z).sqrt();
                let d = [s * phi.cos(), s * phi.sin(), z];
                assert_eq!(g.texel(d), g.texel_trig(d), "{w}x{h} rot {rot} d {d:?}");
            }
            // either side of each edge, by 1e-9 rad
            for v in 0..h {
                let t = (v as f64 + 0.5) * PI / h as f64;
                for k in 0..w {
                    let edge = rot + TAU * k as f64 / w as f64;
                    for (off, want) in [(1e-9, k), (-1e-9, (k + w - 1) % w)] {
                        let phi = edge + off;
                        let d = [t.sin() * phi.cos(), t.sin() * phi.sin(), t.cos()];
                        assert_eq!(g.texel(d), v * w + want, "{w}x{h} v {v} edge {k} {off}");
                    }
                }
            }
            for v in 1..h {
                let edge = v as f64 * PI / h as f64;
                for (off, want) in [(1e-9, v), (-1e-9, v - 1)] {
                    let t = edge + off;
                    let d = [t.sin(), 0.0, t.cos()];
                    assert_eq!(g.texel(d) / w, want, "{w}x{h} row edge {v} {off}");
                }
            }
        }
    }

    #[test]
    fn poles_and_bad_directions_take_the_formula() {
        let g = EquirectGrid::new(8, 4, 0.5);
        for d in [
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
            [f64::NAN, 0.0, 1.0],
            [f64::INFINITY, 1.0, 0.0],
            [0.0, 0.0, 0.0],
        ] {
            assert_eq!(g.texel(d), g.texel_trig(d), "{d:?}");
            assert!(g.texel(d) < 32);
        }
        // a direction that is not unit reads as its z and azimuth
        assert_eq!(g.texel([3.0, 4.0, 0.2]), g.texel_trig([3.0, 4.0, 0.2]));
    }
}
