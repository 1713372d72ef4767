//! Zonal lobes: the kernels an IBL prefilter convolves the environment with,
//! and their Legendre (zonal harmonic) coefficients.
//!
//! The derivation and conventions are documented on [`Lobe`].

use std::f64::consts::PI;

use crate::error::{Result, param};

/// A zonal prefilter lobe.
///
/// A lobe is a function `k(t)` of `t = r . l`, the cosine between the lookup
/// direction `r` and the light direction `l`; the prefiltered map is the
/// normalised convolution
///
/// ```text
/// P(r) = int L(l) k(r . l) dl / int k(r . l) dl.
/// ```
///
/// By the Funk-Hecke theorem `P` has SH coefficients `P_lm = lambda_l L_lm`
/// with `lambda_l = c_l / c_0`, `c_l = int_{-1}^{1} k(t) P_l(t) dt` (the `2 pi`
/// cancels; SHRM Eq. 5 with `Lambda_l rho_l`). The lobes:
///
/// - [`Lobe::Ggx`]: the split-sum prefilter lobe `D(h) max(n . l, 0)` with
///   `n = v = r`, so `n . h = cos(theta / 2) = sqrt((1 + t) / 2)` and
///   `k(t) = D(sqrt((1 + t) / 2)) max(t, 0)`,
///   `D(c) = alpha^2 / (pi (c^2 (alpha^2 - 1) + 1)^2)` (GGX/Trowbridge-Reitz,
///   `alpha` = perceptual roughness squared);
/// - [`Lobe::Phong`]: `k(t) = max(t, 0)^s` (Phong about the reflection
///   vector, SHRM Sec. 5.2);
/// - [`Lobe::Lambert`]: `k(t) = max(t, 0)`, whose normalised convolution is
///   `E / pi`, irradiance over pi (what glTF and Bevy diffuse maps hold);
/// - [`Lobe::Mirror`]: the delta (roughness 0), a lookup, no coefficients.
///
/// The coefficients come from composite Gauss-Legendre quadrature in the
/// angle `theta = acos t` on `[0, pi / 2]` (every lobe vanishes beyond): panel
/// edges grow geometrically from an eighth of the lobe's width (so the peak is
/// resolved however sharp) and no panel is wider than `2 pi / (L + 1)` (so
/// `P_l(cos theta)` is resolved up to `L`); 20 nodes per panel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Lobe {
    /// Roughness 0: the map itself, no blur.
    Mirror,
    /// The GGX split-sum lobe with `alpha` (= perceptual roughness squared).
    Ggx {
        /// GGX alpha, `> 0`.
        alpha: f64,
    },
    /// Phong about the reflection vector, `max(t, 0)^s`.
    Phong {
        /// Exponent, `> 0`.
        s: f64,
    },
    /// The clamped cosine (irradiance / pi).
    Lambert,
}

impl Lobe {
    /// The GGX lobe of a perceptual roughness (`alpha = r^2`); roughness 0 is
    /// [`Lobe::Mirror`].
    ///
    /// # Errors
    /// A roughness outside `[0, 1]` or not finite.
    pub fn ggx_from_roughness(r: f64) -> Result<Self> {
        if !(0.0..=1.0).contains(&r) {
            return Err(param("roughness", format!("{r} is outside [0, 1]")));
        }
        let alpha = r * r;
        // below this the lobe is narrower than any texel of a 16k face
        Ok(if alpha < 1e-6 {
            Self::Mirror
        } else {
            Self::Ggx { alpha }
        })
    }

    /// The Phong lobe whose width matches GGX with `alpha`:
    /// `s = 1 / (2 alpha^2) - 1 / 2` (the Blinn-Phong equivalent
    /// `2 / alpha^2 - 2` of the half-vector lobe, over 4 for the reflection
    /// vector, whose angle is twice the half vector's).
    #[must_use]
    pub fn phong_matching_ggx(alpha: f64) -> Self {
        if alpha < 1e-6 {
            Self::Mirror
        } else {
            Self::Phong {
                s: (0.5 / (alpha * alpha) - 0.5).max(1e-3),
            }
        }
    }

    /// The unnormalised kernel at `t = r . l`.
    #[must_use]
    pub fn eval(&self, t: f64) -> f64 {
        if t <= 0.0 {
            return 0.0;
        }
        match *self {
            Self::Mirror => 0.0,
            Self::Ggx { alpha } => {
                let a2 = alpha * alpha;
                let c2 = 0.5 * (1.0 + t);
                let q = c2 * (a2 - 1.0) + 1.0;
                a2 / (PI * q * q) * t
            }
            Self::Phong { s } => t.powf(s),
            Self::Lambert => t,
        }
    }

    /// The lobe's angular width in radians (a scale for quadrature and
    /// sub-sampling, not a precise support): `2 alpha` for GGX (the angle to
    /// `r` is twice the half vector's), `1 / sqrt(s)` for Phong, 1 for
    /// Lambert, 0 for the mirror.
    #[must_use]
    pub fn width(&self) -> f64 {
        match *self {
            Self::Mirror => 0.0,
            Self::Ggx { alpha } => 2.0 * alpha,
            Self::Phong { s } => 1.0 / s.max(1e-9).sqrt(),
            Self::Lambert => 1.0,
        }
    }

    /// `c_l = int_{-1}^{1} k(t) P_l(t) dt` for `l = 0..=l_max` (see the module
    /// docs); the mirror has none (all `c_l = 1`, the delta's normalised
    /// coefficients).
    #[must_use]
    pub fn legendre_moments(&self, l_max: usize) -> Vec<f64> {
        if *self == Self::Mirror {
            return vec![1.0; l_max + 1];
        }
        let (nodes, weights) = self.quadrature(l_max);
        // f(theta) sin(theta) w per node, in lanes; unused lanes weigh 0
        let n = nodes.len().div_ceil(MOMENT_LANES);
        let mut t = vec![[0.0; MOMENT_LANES]; n];
        let mut f = vec![[0.0; MOMENT_LANES]; n];
        for (i, (&th, &w)) in nodes.iter().zip(&weights).enumerate() {
            let (s, ct) = th.sin_cos();
            t[i / MOMENT_LANES][i % MOMENT_LANES] = ct;
            f[i / MOMENT_LANES][i % MOMENT_LANES] = self.eval(ct) * s * w;
        }
        ifd_simd::run_vectorized(Moments {
            l_max,
            t: &t,
            f: &f,
        })
    }

    /// `lambda_l = c_l / c_0`, the factors a convolution with the normalised
    /// lobe applies to band `l` (`lambda_0 = 1`).
    ///
    /// ```
    /// use ifd_ibl::Lobe;
    /// // Lambert: lambda_1 = 2/3, lambda_2 = 1/4 (Ramamoorthi-Hanrahan's
    /// // A_l / pi), odd bands above 1 vanish
    /// let lam = Lobe::Lambert.zonal(4);
    /// assert!((lam[1] - 2.0 / 3.0).abs() < 1e-12);
    /// assert!((lam[2] - 0.25).abs() < 1e-12);
    /// assert!(lam[3].abs() < 1e-12);
    /// ```
    #[must_use]
    pub fn zonal(&self, l_max: usize) -> Vec<f64> {
        let c = self.legendre_moments(l_max);
        let c0 = c[0];
        c.into_iter().map(|x| x / c0).collect()
    }

    /// `int_S2 k(r . l) dl = 2 pi c_0` (0 for the mirror).
    #[must_use]
    pub fn integral(&self) -> f64 {
        if *self == Self::Mirror {
            return 0.0;
        }
        2.0 * PI * self.legendre_moments(0)[0]
    }

    /// The smallest `L <= cap` with `|lambda_l| < eps` for every
    /// `L < l <= cap`, and whether the cap was reached (the lobe needs more
    /// bands than `cap` for this `eps`).
    ///
    /// ```
    /// use ifd_ibl::Lobe;
    /// let (l, capped) = Lobe::Lambert.band_limit(1e-2, 100);
    /// // lambda_l of the clamped cosine falls as l^-2.5 for even l
    /// assert!((6..=14).contains(&l) && !capped);
    /// ```
    #[must_use]
    pub fn band_limit(&self, eps: f64, cap: usize) -> (usize, bool) {
        if *self == Self::Mirror {
            return (cap, true);
        }
        band_limit_of(&self.zonal(cap), eps)
    }

    /// Composite Gauss-Legendre nodes and weights in `theta` on `[0, pi/2]`.
    fn quadrature(&self, l_max: usize) -> (Vec<f64>, Vec<f64>) {
        let (gx, gw) = ifd_sphere::gauss_legendre(20);
        let half = 0.5 * PI;
        let mut edges = vec![0.0];
        let mut e = (self.width() / 8.0).clamp(1e-9, half);
        while e < half {
            edges.push(e);
            e *= 2.0;
        }
        edges.push(half);
        let dmax = 2.0 * PI / (l_max + 1) as f64;
        let mut nodes = Vec::new();
        let mut weights = Vec::new();
        for pair in edges.windows(2) {
            let (a, b) = (pair[0], pair[1]);
            let n = ((b - a) / dmax).ceil().max(1.0) as usize;
            let h = (b - a) / n as f64;
            for k in 0..n {
                let lo = a + h * k as f64;
                for (x, w) in gx.iter().zip(&gw) {
                    nodes.push(lo + 0.5 * h * (1.0 + x));
                    weights.push(0.5 * h * w);
                }
            }
        }
        (nodes, weights)
    }
}

/// Quadrature nodes whose Legendre recurrences run together.
const MOMENT_LANES: usize = 8;

/// [`Lobe::legendre_moments`]' sums: `c_l = sum_nodes f P_l(t)` by Bonnet's
/// recurrence `P_{l+1} = ((2l + 1) t P_l - l P_{l-1}) / (l + 1)`, its factors
/// precomputed (a division per step was the latency of a long dependent
/// chain) and the nodes in lanes (independent chains), each lane summing its
/// nodes in order, the lanes added in order at the end.
struct Moments<'a> {
    l_max: usize,
    t: &'a [[f64; MOMENT_LANES]],
    f: &'a [[f64; MOMENT_LANES]],
}

impl ifd_simd::VectorKernel for Moments<'_> {
    type Output = Vec<f64>;
    #[inline(always)]
    #[allow(
        clippy::inline_always,
        reason = "the kernel is compiled into each target of `run_vectorized`"
    )]
    fn run(self) -> Vec<f64> {
        const N: usize = MOMENT_LANES;
        let l_max = self.l_max;
        let ab: Vec<(f64, f64)> = (0..l_max.max(1))
            .map(|l| {
                let lf = l as f64;
                ((2.0 * lf + 1.0) / (lf + 1.0), lf / (lf + 1.0))
            })
            .collect();
        // degree by degree over all nodes: each degree's lane sums stay in
        // registers, the recurrence's two previous degrees stream per group
        let mut acc = vec![[0.0; N]; l_max + 1];
        let mut p0 = vec![[1.0; N]; self.t.len()];
        let mut p1 = self.t.to_vec();
        for (t, f) in self.t.iter().zip(self.f) {
            for k in 0..N {
                acc[0][k] += f[k];
            }
            if l_max >= 1 {
                for k in 0..N {
                    acc[1][k] += f[k] * t[k];
                }
            }
        }
        for l in 1..l_max {
            let (a, b) = ab[l];
            let mut s = [0.0; N];
            for (((t, f), q0), q1) in self.t.iter().zip(self.f).zip(&mut p0).zip(&mut p1) {
                let p: [f64; N] = std::array::from_fn(|k| a * t[k] * q1[k] - b * q0[k]);
                *q0 = *q1;
                *q1 = p;
                for k in 0..N {
                    s[k] += f[k] * p[k];
                }
            }
            acc[l + 1] = s;
        }
        acc.iter().map(|a| a.iter().sum()).collect()
    }
}

/// [`Lobe::band_limit`] of zonal factors already at hand (`lam[l]` for
/// `l = 0..=cap`): the last `l` with `|lambda_l| >= eps`, and whether it is
/// the last one given.
#[must_use]
pub fn band_limit_of(lam: &[f64], eps: f64) -> (usize, bool) {
    let cap = lam.len().saturating_sub(1);
    match lam.iter().rposition(|x| x.abs() >= eps) {
        Some(l) if l == cap => (cap, true),
        Some(l) => (l, false),
        None => (0, false),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Brute force: the midpoint rule on a fine uniform grid in `t`.
    fn brute(lobe: &Lobe, l: usize) -> f64 {
        let n = 2_000_000;
        let mut c = [0.0, 0.0];
        for i in 0..n {
            let t = -1.0 + 2.0 * (i as f64 + 0.5) / n as f64;
            let k = lobe.eval(t) * 2.0 / n as f64;
            c[0] += k;
            c[1] += k * ifd_sphere::legendre_p(l, t);
        }
        c[1] / c[0]
    }

    #[test]
    fn zonal_factors_match_brute_force() {
        for lobe in [
            Lobe::Ggx { alpha: 0.1 },
            Lobe::Ggx { alpha: 0.6 },
            Lobe::Phong { s: 40.0 },
            Lobe::Lambert,
        ] {
            let lam = lobe.zonal(30);
            for l in [1, 2, 5, 17, 30] {
                let b = brute(&lobe, l);
                assert!(
                    (lam[l] - b).abs() < 2e-6,
                    "{lobe:?} l={l}: {} vs {b}",
                    lam[l]
                );
            }
        }
    }

    #[test]
    fn phong_zonal_factors_have_a_closed_form() {
        // ratios of int_0^1 t^s P_l(t) dt: lambda_1 = (s+1)/(s+2),
        // lambda_2 = (s+1) (3/(s+3) - 1/(s+1)) / 2 = s/(s+3)
        let s = 12.5;
        let lam = Lobe::Phong { s }.zonal(2);
        assert!((lam[1] - (s + 1.0) / (s + 2.0)).abs() < 1e-12);
        assert!((lam[2] - s / (s + 3.0)).abs() < 1e-12);
    }

    #[test]
    fn ggx_lobe_integrates_to_its_half_vector_normalisation() {
        // int D(h) (n.h) dh = 1 and dl = 4 (v.h) dh with v = n: with the
        // cosine n.l folded in, int k dl = int D 4 (n.h) (n.l) dh < 4 * 1
        for alpha in [0.02, 0.1, 0.5, 1.0] {
            let k = Lobe::Ggx { alpha }.integral();
            assert!(k > 0.0 && k < 4.0, "{alpha}: {k}");
        }
        // and it is 4 (n.l -> 1) in the narrow limit
        let k = Lobe::Ggx { alpha: 0.005 }.integral();
        assert!((k - 4.0).abs() < 0.01, "{k}");
    }
}
