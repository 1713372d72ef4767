//! Spherical filters (kernels) given as functions, and their SH projection.
//!
//! Text specs (for the CLI and tests), all centred on `+z`:
//!
//! | spec | `k(w)`, `t = w . z`, `(a, b) = theta (cos p, sin p)` |
//! |---|---|
//! | `phong:s=32` | `max(t, 0)^s` |
//! | `vmf:kappa=50` | `exp(kappa (t - 1))` |
//! | `gauss:s=0.2` | `exp(-theta^2 / (2 s^2))` (radians) |
//! | `aniso-gauss:s1=0.3,s2=0.05` | `exp(-a^2 / (2 s1^2) - b^2 / (2 s2^2))` (radians, `a` along `x`) |
//!
//! `(a, b)` are azimuthal-equidistant coordinates around `z` (`theta` = angle to `z`).

use std::f64::consts::PI;

use crate::coeffs::ShCoeffs;
use crate::error::{Result, SphereError};
use crate::legendre::gauss_legendre;
use crate::sh::{ShEvaluator, sh_count};

/// A spherical filter given in closed form.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Kernel {
    /// `max(w . z, 0)^s`.
    Phong {
        /// Exponent.
        s: f64,
    },
    /// `exp(kappa (w . z - 1))`.
    Vmf {
        /// Concentration.
        kappa: f64,
    },
    /// Isotropic Gaussian in the angle to `z`.
    Gauss {
        /// Standard deviation in radians.
        s: f64,
    },
    /// Anisotropic Gaussian, `s1` along `x`, `s2` along `y` (radians).
    AnisoGauss {
        /// Standard deviation along `x`.
        s1: f64,
        /// Standard deviation along `y`.
        s2: f64,
    },
}

impl Kernel {
    /// Parses `name:key=value,...` (see the module docs).
    ///
    /// # Errors
    /// [`SphereError::Parse`] naming the text.
    pub fn parse(text: &str) -> Result<Self> {
        const KERNELS: [&str; 4] = ["phong", "vmf", "gauss", "aniso-gauss"];
        let perr = |reason: &str| SphereError::Parse {
            what: "kernel spec",
            text: text.into(),
            reason: reason.into(),
        };
        let (name, args) = text.split_once(':').unwrap_or((text, ""));
        // the name first: an unknown kernel is reported as such, whatever its values
        if !KERNELS.contains(&name.trim()) {
            return Err(perr("unknown kernel (phong, vmf, gauss, aniso-gauss)"));
        }
        let mut kv = std::collections::BTreeMap::new();
        for part in args.split(',').filter(|s| !s.trim().is_empty()) {
            let (k, v) = part
                .split_once('=')
                .ok_or_else(|| perr("expected key=value"))?;
            let v: f64 = v
                .trim()
                .parse()
                .map_err(|_| perr("a value is not a number"))?;
            if !v.is_finite() || v <= 0.0 {
                return Err(perr("values must be finite and positive"));
            }
            kv.insert(k.trim().to_string(), v);
        }
        let get = |k: &str| {
            kv.get(k)
                .copied()
                .ok_or_else(|| perr(&format!("missing {k}=")))
        };
        let kernel = match name.trim() {
            "phong" => Self::Phong { s: get("s")? },
            "vmf" => Self::Vmf {
                kappa: get("kappa")?,
            },
            "gauss" => Self::Gauss { s: get("s")? },
            "aniso-gauss" => Self::AnisoGauss {
                s1: get("s1")?,
                s2: get("s2")?,
            },
            _ => return Err(perr("unknown kernel (phong, vmf, gauss, aniso-gauss)")),
        };
        Ok(kernel)
    }

    /// `k(w)` for a unit vector `w`.
    #[must_use]
    pub fn eval(&self, w: [f64; 3]) -> f64 {
        let t = w[2].clamp(-1.0, 1.0);
        match *self {
            Self::Phong { s } => t.max(0.0).powf(s),
            Self::Vmf { kappa } => (kappa * (t - 1.0)).exp(),
            Self::Gauss { s } => {
                let th = t.acos();
                (-th * th / (2.0 * s * s)).exp()
            }
            Self::AnisoGauss { s1, s2 } => {
                let th = t.acos();
                let r = w[0].hypot(w[1]);
                let (c, sn) = if r > 0.0 {
                    (w[0] / r, w[1] / r)
                } else {
                    (1.0, 0.0)
                };
                let (a, b) = (th * c, th * sn);
                (-a * a / (2.0 * s1 * s1) - b * b / (2.0 * s2 * s2)).exp()
            }
        }
    }

    /// A quadrature resolution (polar nodes) that resolves the kernel's width.
    #[must_use]
    pub fn suggested_nodes(&self, l_max: usize) -> usize {
        let width = match *self {
            Self::Phong { s } => 1.0 / (s + 1.0).sqrt(),
            Self::Vmf { kappa } => 1.0 / kappa.sqrt(),
            Self::Gauss { s } => s,
            Self::AnisoGauss { s1, s2 } => s1.min(s2),
        };
        let n = (12.0 * PI / width.max(1e-4)).ceil() as usize;
        n.clamp(2 * l_max + 8, 4096)
    }
}

/// Projects a function on SH up to `l_max` with a product rule: `n_theta`
/// Gauss-Legendre nodes in `cos theta` times `2 n_theta` uniform azimuths
/// (exact for band-limited functions of degree below `n_theta - l_max`).
///
/// ```
/// use ifd_sphere::project_function;
/// let c = project_function(2, |w| w[2], 8)?; // z = y_1^0 / 0.4886
/// assert!((c.get(1, 0, 0) - 1.0 / 0.488_602_511_902_919_9).abs() < 1e-12);
/// # Ok::<(), ifd_sphere::SphereError>(())
/// ```
///
/// # Errors
/// [`SphereError::NonFinite`] when the function returns NaN or infinity;
/// [`SphereError::DegreeTooHigh`].
pub fn project_function(
    l_max: usize,
    f: impl Fn([f64; 3]) -> f64,
    n_theta: usize,
) -> Result<ShCoeffs> {
    let n_theta = n_theta.max(l_max + 1);
    let n_phi = 2 * n_theta;
    let sh = ShEvaluator::new(l_max)?;
    let (x, w) = gauss_legendre(n_theta);
    let mut out = ShCoeffs::zeros(l_max, 1)?;
    let o = out.data_mut();
    let mut y = vec![0.0; sh_count(l_max)];
    let dphi = 2.0 * PI / n_phi as f64;
    let mut bad = 0usize;
    let mut first = None;
    for (i, (&z, &wz)) in x.iter().zip(&w).enumerate() {
        let s = (1.0 - z * z).max(0.0).sqrt();
        for k in 0..n_phi {
            let p = (k as f64 + 0.5) * dphi;
            let d = [s * p.cos(), s * p.sin(), z];
            let v = f(d);
            if !v.is_finite() {
                bad += 1;
                first.get_or_insert(i * n_phi + k);
                continue;
            }
            sh.eval_into(d, &mut y);
            let wv = wz * dphi * v;
            for (oi, yi) in o.iter_mut().zip(&y) {
                *oi += wv * yi;
            }
        }
    }
    if let Some(first) = first {
        return Err(SphereError::NonFinite {
            what: "kernel function values",
            count: bad,
            first,
        });
    }
    Ok(out)
}

/// Projects a multi-channel function that vanishes outside the band
/// `z0 <= w_z <= z1` (a hemisphere, say) onto SH up to `l_max`.
///
/// The rule is `n_theta` Gauss-Legendre nodes in `z` over `[z0, z1]` times
/// `n_phi = max(2 n_theta, 2 l_max + 2)` uniform azimuths `(k + 1/2) 2 pi /
/// n_phi`; per ring, the azimuthal Fourier sums of every order `m <= L` meet
/// `y_l^|m|(theta, 0)` (`y_l^m = y_l^|m|(theta, 0) cos(m phi)`, `sin(|m| phi)`
/// for `m < 0`), so a ring costs `O(n_phi L + L^2)` rather than
/// `O(n_phi L^2)`. Exact for band-limited functions of degree below
/// `2 n_theta - l_max` when `[z0, z1] = [-1, 1]`; splitting the sphere where
/// the function has a kink (the horizon of a cosine-weighted BRDF) keeps the
/// rule spectrally accurate on each side. `f(w, out)` writes `channels` values.
/// Rings run in parallel; the sum is taken in ring order, so the result does
/// not depend on the thread count.
///
/// ```
/// use ifd_sphere::{project_band, project_function};
/// // max(z, 0) projected over the upper hemisphere only, against the full rule
/// let a = project_band(6, 1, (0.0, 1.0), 24, |w, o| o[0] = w[2].max(0.0))?;
/// let b = project_function(6, |w| w[2].max(0.0), 400)?;
/// assert!(a.data().iter().zip(b.data()).all(|(x, y)| (x - y).abs() < 1e-5));
/// # Ok::<(), ifd_sphere::SphereError>(())
/// ```
///
/// # Errors
/// [`SphereError::NonFinite`] when `f` returns NaN or infinity;
/// [`SphereError::DegreeTooHigh`]; [`SphereError::Parameter`] for a band
/// outside `[-1, 1]` or empty.
pub fn project_band(
    l_max: usize,
    channels: usize,
    z_range: (f64, f64),
    n_theta: usize,
    f: impl Fn([f64; 3], &mut [f64]) + Sync,
) -> Result<ShCoeffs> {
    use rayon::prelude::*;
    let (z0, z1) = z_range;
    if !(-1.0..=1.0).contains(&z0) || !(-1.0..=1.0).contains(&z1) || z0 >= z1 {
        return Err(SphereError::Parameter {
            name: "z range",
            value: format!("[{z0}, {z1}]"),
            reason: "must be a non-empty part of [-1, 1]",
        });
    }
    let sh = ShEvaluator::new(l_max)?;
    let ch = channels.max(1);
    let n_theta = n_theta.max(l_max + 1);
    let n_phi = (2 * n_theta).max(2 * l_max + 2);
    let dphi = 2.0 * PI / n_phi as f64;
    // cos(m phi_k), sin(m phi_k) for every order and azimuth
    let trig: Vec<(f64, f64)> = (0..=l_max)
        .flat_map(|m| {
            (0..n_phi).map(move |k| {
                let (s, c) = (m as f64 * (k as f64 + 0.5) * dphi).sin_cos();
                (c, s)
            })
        })
        .collect();
    let (x, w) = gauss_legendre(n_theta);
    let (mid, half) = (0.5 * (z0 + z1), 0.5 * (z1 - z0));
    let rings: Vec<Result<Vec<f64>>> = x
        .par_iter()
        .zip(&w)
        .enumerate()
        .map(|(i, (&xi, &wi))| {
            let z = mid + half * xi;
            let s = (1.0 - z * z).max(0.0).sqrt();
            let mut vals = vec![0.0; n_phi * ch];
            for k in 0..n_phi {
                let p = (k as f64 + 0.5) * dphi;
                let v = &mut vals[k * ch..(k + 1) * ch];
                f([s * p.cos(), s * p.sin(), z], v);
                if let Some(c) = v.iter().position(|x| !x.is_finite()) {
                    return Err(SphereError::NonFinite {
                        what: "function values",
                        count: 1,
                        first: (i * n_phi + k) * ch + c,
                    });
                }
            }
            // Fourier sums per order and channel: (cos part, sin part)
            let mut fa = vec![0.0; (l_max + 1) * ch];
            let mut fb = vec![0.0; (l_max + 1) * ch];
            for m in 0..=l_max {
                let t = &trig[m * n_phi..(m + 1) * n_phi];
                for c in 0..ch {
                    let (mut a, mut b) = (0.0, 0.0);
                    for (k, (cs, sn)) in t.iter().enumerate() {
                        let v = vals[k * ch + c];
                        a += v * cs;
                        b += v * sn;
                    }
                    fa[m * ch + c] = a * dphi;
                    fb[m * ch + c] = b * dphi;
                }
            }
            let mut y = vec![0.0; sh_count(l_max)];
            sh.eval_into([s, 0.0, z], &mut y);
            let wz = wi * half;
            let mut out = vec![0.0; sh_count(l_max) * ch];
            for l in 0..=l_max {
                let base = l * (l + 1);
                for m in 0..=l {
                    let ym = wz * y[base + m];
                    for c in 0..ch {
                        out[(base + m) * ch + c] += ym * fa[m * ch + c];
                        if m > 0 {
                            out[(base - m) * ch + c] += ym * fb[m * ch + c];
                        }
                    }
                }
            }
            Ok(out)
        })
        .collect();
    let mut coeffs = ShCoeffs::zeros(l_max, ch)?;
    let o = coeffs.data_mut();
    for r in rings {
        for (a, b) in o.iter_mut().zip(r?) {
            *a += b;
        }
    }
    Ok(coeffs)
}

/// The SH convolution factors `Lambda_l = I_{l+1/2}(kappa) / I_{1/2}(kappa)`,
/// `l = 0..=l_max`, of the normalised von Mises-Fisher density
/// `kappa / (4 pi sinh kappa) exp(kappa t)`: convolving `f` with it scales
/// `f_l^m` by `Lambda_l` (`Lambda_0 = 1`; about `exp(-l (l + 1) / (2
/// kappa))` for large `kappa`, the spherical Gaussian of variance `1 / kappa`
/// per axis).
///
/// The ratios `r_l = I_{l+1/2} / I_{l-1/2}` come from the continued fraction
/// `r_l = 1 / ((2l + 1) / kappa + r_{l+1})` (the recurrence `I_{v-1} -
/// I_{v+1} = (2v / kappa) I_v`) run backwards from far beyond `l_max` and
/// `sqrt(kappa)`, stable where the forward recurrence is not; `Lambda_l =
/// r_1 ... r_l`. `kappa = 0` gives the constant kernel (`Lambda_l = 0` for
/// `l > 0`).
///
/// ```
/// let a = ifd_sphere::vmf_factors(50.0, 4);
/// // Lambda_1 = coth(kappa) - 1 / kappa, the mean cosine of the density
/// let exact = 1.0 / 50f64.tanh() - 1.0 / 50.0;
/// assert!((a[1] - exact).abs() < 1e-14);
/// ```
#[must_use]
pub fn vmf_factors(kappa: f64, l_max: usize) -> Vec<f64> {
    let mut out = vec![0.0; l_max + 1];
    out[0] = 1.0;
    if l_max == 0 || kappa.is_nan() || kappa <= 0.0 {
        return out;
    }
    let kappa = kappa.min(1e12);
    // the tail r_n for n > l_max: far enough that truncation is invisible
    let start = l_max + 40 + (8.0 * kappa.sqrt()).min(1e6) as usize;
    let mut r = 0.0;
    let mut ratios = vec![0.0; l_max + 1];
    for l in (1..=start).rev() {
        r = 1.0 / ((2 * l + 1) as f64 / kappa + r);
        if l <= l_max {
            ratios[l] = r;
        }
    }
    for l in 1..=l_max {
        out[l] = out[l - 1] * ratios[l];
    }
    out
}

#[cfg(test)]
mod vmf_tests {
    use super::vmf_factors;

    /// Against quadrature of the normalised density with Legendre polynomials.
    #[test]
    fn vmf_factors_match_quadrature() {
        for kappa in [0.5, 4.0, 80.0, 900.0] {
            let a = vmf_factors(kappa, 30);
            let (x, w) = crate::legendre::gauss_legendre(2000);
            let mut p = vec![0.0; 31];
            let mut num = vec![0.0; 31];
            for (t, wt) in x.iter().zip(&w) {
                crate::legendre::legendre_all(30, *t, &mut p);
                // exp(kappa (t - 1)) normalised below by the l = 0 integral
                let f = (kappa * (t - 1.0)).exp();
                for l in 0..=30 {
                    num[l] += wt * f * p[l];
                }
            }
            for l in 0..=30 {
                let q = num[l] / num[0];
                assert!(
                    (a[l] - q).abs() < 1e-9,
                    "kappa {kappa} l {l}: {} vs {q}",
                    a[l]
                );
            }
        }
    }
}
