//! The split-sum DFG table (Karis 2013): for `x = n . v` and `y` =
//! perceptual roughness (`alpha = y^2`), the scale `A` and bias `B` with
//! `int f_spec(l, v) (n . l) dl = F0 A + B` for Schlick's Fresnel:
//!
//! The derivation and conventions are documented on [`dfg_table`].

use rayon::prelude::*;

/// `(A, B)` at `n . v = nv` and perceptual roughness `r`.
///
/// ```
/// // a mirror-like surface seen head-on reflects everything: A + B = 1, B = 0
/// let (a, b) = ifd_ibl::dfg(1.0, 0.02);
/// assert!((a + b - 1.0).abs() < 1e-3 && b < 1e-3);
/// ```
#[must_use]
pub fn dfg(nv: f64, r: f64) -> (f64, f64) {
    const NX: usize = 192;
    const NP: usize = 48;
    let nv = nv.clamp(1e-4, 1.0);
    let alpha = (r * r).max(1e-6);
    let a2 = alpha * alpha;
    let v = [(1.0 - nv * nv).max(0.0).sqrt(), 0.0, nv];
    let (gx, gw) = ifd_sphere::gauss_legendre(NX);
    let (mut sa, mut sb) = (0.0, 0.0);
    for (x, w) in gx.iter().zip(&gw) {
        let xi = 0.5 * (1.0 + x);
        let ch = ((1.0 - xi) / (1.0 + (a2 - 1.0) * xi)).sqrt();
        let sh = (1.0 - ch * ch).max(0.0).sqrt();
        for p in 0..NP {
            let phi = std::f64::consts::PI * (p as f64 + 0.5) / NP as f64;
            let h = [sh * phi.cos(), sh * phi.sin(), ch];
            let vh = v[0] * h[0] + v[2] * h[2];
            let nl = 2.0 * vh * h[2] - v[2];
            if nl <= 0.0 || vh <= 0.0 {
                continue;
            }
            let gv = nl * (nv * nv * (1.0 - a2) + a2).sqrt();
            let gl = nv * (nl * nl * (1.0 - a2) + a2).sqrt();
            let vis = 0.5 / (gv + gl);
            let g = 4.0 * vis * vh * nl / ch;
            let fc = (1.0 - vh).powi(5);
            // weight: 0.5 w (xi on [0, 1]) x 1 / NP (phi)
            let wt = 0.5 * w / NP as f64;
            sa += wt * (1.0 - fc) * g;
            sb += wt * fc * g;
        }
    }
    (sa, sb)
}

/// The `size x size` table, row-major, `(A, B)` per texel.
///
/// ```text
/// A = int (1 - Fc) Vis D (n.l) 4 (v.h) / ... = E[(1 - Fc) 4 Vis (v.h)(n.l) / (n.h)]
/// B = E[Fc 4 Vis (v.h) (n.l) / (n.h)],   Fc = (1 - v.h)^5,
/// Vis = 0.5 / (n.l sqrt((n.v)^2 (1 - a^2) + a^2) + n.v sqrt((n.l)^2 (1 - a^2) + a^2))
/// ```
///
/// (height-correlated Smith visibility, `a = alpha`), the expectation over
/// half vectors drawn from `D(h) (n . h)`. Instead of random samples the
/// expectation runs on a deterministic rule over the sampling square
/// `(xi, phi)`: `cos theta_h = sqrt((1 - xi) / (1 + (alpha^2 - 1) xi))`
/// maps `xi` uniformly to that density, Gauss-Legendre in `xi`, the midpoint
/// rule in `phi` (periodic, and symmetric about the plane of `v`, so half the
/// circle suffices). Texel `(i, j)` holds `x = (i + 0.5) / size`,
/// `y = (j + 0.5) / size` (row 0 at the top is the smoothest), as
/// glTF-IBL-Sampler's table.
#[must_use]
pub fn dfg_table(size: usize) -> Vec<[f32; 2]> {
    dfg_table_with_progress(size, &|| {})
}

/// [`dfg_table`], calling `row_done` after each row (from rayon's threads,
/// in any order): for a progress bar on large tables (each texel is a
/// quadrature; 1024 x 1024 takes minutes).
#[must_use]
pub fn dfg_table_with_progress(size: usize, row_done: &(dyn Fn() + Sync)) -> Vec<[f32; 2]> {
    (0..size)
        .into_par_iter()
        .flat_map_iter(|j| {
            let row: Vec<[f32; 2]> = (0..size)
                .map(|i| {
                    let (a, b) = dfg(
                        (i as f64 + 0.5) / size as f64,
                        (j as f64 + 0.5) / size as f64,
                    );
                    [a as f32, b as f32]
                })
                .collect();
            row_done();
            row
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Independent brute force: the integral over light directions on a
    /// fine (theta, phi) grid of `f_spec (n . l)` with `D`, `Vis` and
    /// Schlick's `Fc` written out.
    fn brute(nv: f64, r: f64) -> (f64, f64) {
        let alpha = r * r;
        let a2 = alpha * alpha;
        let v = [(1.0 - nv * nv).sqrt(), 0.0, nv];
        let (nt, np) = (3000, 1200);
        let (mut sa, mut sb) = (0.0, 0.0);
        for it in 0..nt {
            let th = 0.5 * std::f64::consts::PI * (it as f64 + 0.5) / nt as f64;
            let dth = 0.5 * std::f64::consts::PI / nt as f64;
            for ip in 0..np {
                let ph = 2.0 * std::f64::consts::PI * (ip as f64 + 0.5) / np as f64;
                let dph = 2.0 * std::f64::consts::PI / np as f64;
                let l = [th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()];
                let hs = [v[0] + l[0], v[1] + l[1], v[2] + l[2]];
                let hn = (hs[0] * hs[0] + hs[1] * hs[1] + hs[2] * hs[2]).sqrt();
                let h = [hs[0] / hn, hs[1] / hn, hs[2] / hn];
                let nh = h[2];
                let nl = l[2];
                let vh = v[0] * h[0] + v[2] * h[2];
                let q = nh * nh * (a2 - 1.0) + 1.0;
                let d = a2 / (std::f64::consts::PI * q * q);
                let vis = 0.5
                    / (nl * (nv * nv * (1.0 - a2) + a2).sqrt()
                        + nv * (nl * nl * (1.0 - a2) + a2).sqrt());
                let f = d * vis * nl * th.sin() * dth * dph;
                let fc = (1.0 - vh).powi(5);
                sa += (1.0 - fc) * f;
                sb += fc * f;
            }
        }
        (sa, sb)
    }

    #[test]
    fn table_matches_brute_force_integration() {
        for (nv, r) in [(0.9, 0.5), (0.3, 0.7), (0.5, 0.3), (0.1, 1.0)] {
            let (a, b) = dfg(nv, r);
            let (ea, eb) = brute(nv, r);
            assert!((a - ea).abs() < 2e-3, "A({nv}, {r}) = {a} vs {ea}");
            assert!((b - eb).abs() < 2e-3, "B({nv}, {r}) = {b} vs {eb}");
        }
    }
}
