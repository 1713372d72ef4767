//! Isotropic mother functions and the general ISD matrix (ISD Sec. 5.2, Eq. 15-19).
//!
//! The derivation and conventions are documented on [`IsdBasis`].

use nalgebra::DMatrix;

use crate::coeffs::ShCoeffs;
use crate::error::{Result, SphereError, check_degree};
use crate::legendre::{gauss_legendre, legendre_all, legendre_p};
use crate::sh::{ShEvaluator, pi_l, sh_count};
use crate::zhf::{DirectionSet, RzhCoeffs, condition_number};

/// A family of isotropic mother functions `phi_l`, one per band.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Profile {
    /// `y_l^0`: rotated zonal harmonics (ISD Sec. 5.1).
    Zonal,
    /// `P_l(w . z)` (Fig. 13's "Legendre"; RZH up to a factor `pi_l` per band).
    Legendre,
    /// `max(w . z, 0)^(4l)` (clamped; see the module docs).
    Phong,
    /// `exp(-(1 - w . z) l^2)` (Eq. 19).
    Gauss,
    /// Normalised von Mises-Fisher density with `kappa_l = l (l + 1) / (2 ln 2)`.
    Vmf,
    /// Gauss times Legendre: `exp(-(1 - w . z) l^2) P_l(w . z)`.
    Hybrid,
}

impl Profile {
    /// Every profile, in the order of the Fig. 13 plot.
    pub const ALL: [Self; 6] = [
        Self::Zonal,
        Self::Legendre,
        Self::Phong,
        Self::Gauss,
        Self::Vmf,
        Self::Hybrid,
    ];

    /// Short name (`zonal`, `legendre`, `phong`, `gauss`, `vmf`, `hybrid`).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Zonal => "zonal",
            Self::Legendre => "legendre",
            Self::Phong => "phong",
            Self::Gauss => "gauss",
            Self::Vmf => "vmf",
            Self::Hybrid => "hybrid",
        }
    }

    /// Parses a name (`rzh` is accepted for `zonal`).
    ///
    /// # Errors
    /// [`SphereError::Parse`] for unknown names.
    pub fn parse(s: &str) -> Result<Self> {
        Ok(match s.to_ascii_lowercase().as_str() {
            "zonal" | "rzh" | "zh" => Self::Zonal,
            "legendre" => Self::Legendre,
            "phong" => Self::Phong,
            "gauss" | "gaussian" => Self::Gauss,
            "vmf" => Self::Vmf,
            "hybrid" | "gauss-legendre" => Self::Hybrid,
            _ => {
                return Err(SphereError::Parse {
                    what: "profile",
                    text: s.into(),
                    reason: "expected zonal|rzh|legendre|phong|gauss|vmf|hybrid".into(),
                });
            }
        })
    }

    /// vMF concentration of band `l`.
    #[must_use]
    pub fn vmf_kappa(l: usize) -> f64 {
        (l * (l + 1)) as f64 / (2.0 * std::f64::consts::LN_2)
    }

    /// `g_l(t)`, the profile of band `l` at `t = w . z`.
    #[must_use]
    pub fn eval(self, l: usize, t: f64) -> f64 {
        let lf = l as f64;
        match self {
            Self::Zonal => {
                ((2.0 * lf + 1.0) / (4.0 * std::f64::consts::PI)).sqrt() * legendre_p(l, t)
            }
            Self::Legendre => legendre_p(l, t),
            Self::Phong => t.max(0.0).powi(4 * l as i32),
            Self::Gauss => (-(1.0 - t) * lf * lf).exp(),
            Self::Vmf => {
                let k = Self::vmf_kappa(l);
                if k == 0.0 {
                    1.0 / (4.0 * std::f64::consts::PI)
                } else {
                    // kappa / (4 pi sinh kappa) e^{kappa t}, overflow-free
                    k / (2.0 * std::f64::consts::PI * (1.0 - (-2.0 * k).exp()))
                        * (k * (t - 1.0)).exp()
                }
            }
            Self::Hybrid => (-(1.0 - t) * lf * lf).exp() * legendre_p(l, t),
        }
    }

    /// `beta_{l l'}` for `l, l' <= l_max`, row-major `(L + 1) x (L + 1)` (row `l`).
    ///
    /// # Errors
    /// [`SphereError::DegreeTooHigh`].
    pub fn beta(self, l_max: usize) -> Result<Vec<f64>> {
        check_degree(l_max)?;
        let n = l_max + 1;
        let mut beta = vec![0.0; n * n];
        match self {
            Self::Zonal => (0..n).for_each(|l| beta[l * n + l] = 1.0),
            Self::Legendre => (0..n).for_each(|l| beta[l * n + l] = pi_l(l)),
            _ => {
                let (t, w) = graded_rule(l_max);
                let mut p = vec![0.0; n];
                let k: Vec<f64> = (0..n)
                    .map(|l| {
                        2.0 * std::f64::consts::PI
                            * ((2 * l + 1) as f64 / (4.0 * std::f64::consts::PI)).sqrt()
                    })
                    .collect();
                for (&ti, &wi) in t.iter().zip(&w) {
                    legendre_all(l_max, ti, &mut p);
                    for l in 0..n {
                        let g = wi * self.eval(l, ti);
                        if g == 0.0 {
                            continue;
                        }
                        for lp in 0..n {
                            beta[l * n + lp] += g * k[lp] * p[lp];
                        }
                    }
                }
            }
        }
        Ok(beta)
    }
}

/// Composite Gauss-Legendre rule on `[-1, 1]`, intervals halving towards 1.
fn graded_rule(l_max: usize) -> (Vec<f64>, Vec<f64>) {
    let npts = (5 * l_max) / 2 + 24;
    let (x, w) = gauss_legendre(npts);
    let mut edges = vec![-1.0, 0.0];
    let mut h = 0.5;
    while h > 1e-13 {
        edges.push(1.0 - h);
        h *= 0.5;
    }
    edges.push(1.0);
    let mut t = Vec::new();
    let mut wt = Vec::new();
    for e in edges.windows(2) {
        let (a, b) = (e[0], e[1]);
        let (c, r) = (0.5 * (a + b), 0.5 * (b - a));
        for (xi, wi) in x.iter().zip(&w) {
            t.push(c + r * xi);
            wt.push(r * wi);
        }
    }
    (t, wt)
}

/// A general isotropic spherical decomposition basis: a profile, its
/// `beta_{l l'}`, lobe directions, the full matrix `M` (Eq. 17), its LU
/// factorisation and its condition number.
///
/// ```
/// use ifd_sphere::{IsdBasis, Profile};
/// use ifd_sphere::{Chooser, DirectionSet, Sharing};
/// let dirs = DirectionSet::new(4, Sharing::PerBand, Chooser::Fibonacci)?;
/// let isd = IsdBasis::new(Profile::Gauss, dirs)?;
/// assert!(isd.condition_number() < 1e6);
/// # Ok::<(), ifd_sphere::SphereError>(())
/// ```
///
/// A mother function of band `l` is circularly symmetric about `z`:
/// `phi_l(w) = g_l(w . z)`. Its ZH projections are
///
/// ```text
/// beta_{l l'} = <phi_l, y_{l'}^0> = 2 pi K_{l'}^0 int_{-1}^{1} g_l(t) P_{l'}(t) dt   (Eq. 16)
/// ```
///
/// and, by the addition theorem, the lobe `phi_l^j(w) = phi_l((R_l^j)^-1 w)` has
/// the SH coefficients `beta_{l l'} pi_{l'} y_{l'}^{m'}(z_l^j)`, so
///
/// ```text
/// M_{(l', m'), (l, j)} = beta_{l l'} pi_{l'} y_{l'}^{m'}(z_l^j)              (Eq. 17)
/// ```
///
/// (The paper's Eq. 15 goes through Wigner coefficients; this direct route gives
/// the same Eq. 17.) `M` is `(L + 1)^2 x (L + 1)^2`, block-diagonal for the zonal
/// profile (`beta = delta`, Eq. 18). Profiles (ISD Sec. 7.2, Fig. 13):
///
/// | profile | `g_l(t)` | `beta_{l l'}` |
/// |---|---|---|
/// | [`Profile::Zonal`] (RZH) | `K_l^0 P_l(t)` (`= y_l^0`) | `delta_{l l'}` |
/// | [`Profile::Legendre`] | `P_l(t)` | `pi_l delta_{l l'}` |
/// | [`Profile::Phong`] | `max(t, 0)^(4l)` | quadrature |
/// | [`Profile::Gauss`] | `exp(-(1 - t) l^2)` (Eq. 19) | quadrature |
/// | [`Profile::Vmf`] | `kappa / (4 pi sinh kappa) exp(kappa t)`, `kappa_l = l (l + 1) / (2 ln 2)` | quadrature |
/// | [`Profile::Hybrid`] | `exp(-(1 - t) l^2) P_l(t)` | quadrature |
///
/// Phong is clamped to the upper hemisphere: the unclamped `t^(4l)` of the
/// paper's text is even in `t`, has no odd-degree ZH component, and would make
/// `M` exactly singular (no odd band could be represented).
/// The vMF concentration is chosen so that the SH spectrum of `phi_l`
/// (about `exp(-l'(l'+1) / (2 kappa))`) has dropped to one half at `l' = l`;
/// for `l = 0` it is the uniform density `1 / (4 pi)`.
/// Quadrature: composite Gauss-Legendre on `[-1, 1]` with intervals halving
/// towards `t = 1` (where the peaked profiles live), exact for the polynomial
/// profiles.
pub struct IsdBasis {
    profile: Profile,
    dirs: DirectionSet,
    beta: Vec<f64>,
    m: DMatrix<f64>,
    lu: nalgebra::LU<f64, nalgebra::Dyn, nalgebra::Dyn>,
    cond: f64,
}

impl std::fmt::Debug for IsdBasis {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("IsdBasis")
            .field("profile", &self.profile)
            .field("l_max", &self.dirs.l_max())
            .field("cond", &self.cond)
            .finish_non_exhaustive()
    }
}

/// The largest degree of a general ISD basis ([`isd_matrix`], [`IsdBasis`]).
///
/// `M` is dense, `(L + 1)^2` square, and its condition number takes a full
/// SVD (`O((L + 1)^6)`): at the limit `M` is `1681 x 1681` (22 MiB) and
/// `ifd sphere decompose` takes about 4.5 s (measured, L = 40, Gauss profile;
/// 1.8 s at L = 32).
/// Beyond it the cost grows with `L^6`. (RZH bases, [`crate::zhf::RzhBasis`],
/// are block-diagonal and go to [`crate::MAX_DEGREE`].)
pub const MAX_ISD_DEGREE: usize = 40;

/// Refuses degrees above [`MAX_ISD_DEGREE`], naming the size and cost of `M`.
///
/// ```
/// use ifd_sphere::{MAX_ISD_DEGREE, check_isd_degree};
/// assert!(check_isd_degree(MAX_ISD_DEGREE).is_ok());
/// let e = check_isd_degree(5000).unwrap_err().to_string();
/// assert!(e.contains("at most L = 40"), "{e}");
/// ```
///
/// # Errors
/// [`SphereError::IsdTooLarge`].
pub fn check_isd_degree(l_max: usize) -> Result<()> {
    if l_max > MAX_ISD_DEGREE {
        let n = l_max
            .saturating_add(1)
            .saturating_mul(l_max.saturating_add(1));
        let nf = (l_max as f64 + 1.0).powi(2);
        return Err(SphereError::IsdTooLarge {
            l_max,
            max: MAX_ISD_DEGREE,
            n,
            mib: nf * nf * 8.0 / f64::from(1u32 << 20),
            gflop: 10.0 * nf * nf * nf / 1e9,
        });
    }
    Ok(())
}

/// Builds `M` of Eq. 17 (rows `(l', m')`, columns `(l, j)`).
///
/// # Errors
/// [`SphereError::IsdTooLarge`] above [`MAX_ISD_DEGREE`].
pub fn isd_matrix(profile: Profile, dirs: &DirectionSet) -> Result<(DMatrix<f64>, Vec<f64>)> {
    let l_max = dirs.l_max();
    check_isd_degree(l_max)?;
    let n = sh_count(l_max);
    let beta = profile.beta(l_max)?;
    let sh = ShEvaluator::new(l_max)?;
    let mut m = DMatrix::zeros(n, n);
    let mut y = vec![0.0; n];
    let nb = l_max + 1;
    for l in 0..=l_max {
        for (j, d) in dirs.band(l).iter().enumerate() {
            sh.eval_into(*d, &mut y);
            let col = l * l + j;
            for lp in 0..=l_max {
                let b = beta[l * nb + lp] * pi_l(lp);
                if b == 0.0 {
                    continue;
                }
                for i in lp * lp..(lp + 1) * (lp + 1) {
                    m[(i, col)] = b * y[i];
                }
            }
        }
    }
    Ok((m, beta))
}

impl IsdBasis {
    /// Builds `M` and factorises it; refuses condition numbers above
    /// [`crate::zhf::DEFAULT_COND_LIMIT`] (use [`Self::with_limit`] for Fig. 13-style studies).
    ///
    /// # Errors
    /// [`SphereError::IllConditioned`] with the condition number;
    /// [`SphereError::IsdTooLarge`] above [`MAX_ISD_DEGREE`].
    pub fn new(profile: Profile, dirs: DirectionSet) -> Result<Self> {
        Self::with_limit(profile, dirs, crate::zhf::DEFAULT_COND_LIMIT)
    }

    /// [`Self::new`] with a custom limit.
    ///
    /// # Errors
    /// [`SphereError::IllConditioned`], [`SphereError::IsdTooLarge`].
    pub fn with_limit(profile: Profile, dirs: DirectionSet, cond_limit: f64) -> Result<Self> {
        let (m, beta) = isd_matrix(profile, &dirs)?;
        let cond = condition_number(&m);
        if cond.is_nan() || cond > cond_limit {
            return Err(SphereError::IllConditioned {
                l_max: dirs.l_max(),
                profile: profile.name(),
                cond,
                limit: cond_limit,
            });
        }
        let lu = m.clone().lu();
        Ok(Self {
            profile,
            dirs,
            beta,
            m,
            lu,
            cond,
        })
    }

    /// The profile.
    #[must_use]
    pub fn profile(&self) -> Profile {
        self.profile
    }

    /// The directions.
    #[must_use]
    pub fn directions(&self) -> &DirectionSet {
        &self.dirs
    }

    /// `beta_{l l'}`, row-major `(L + 1)^2` (row `l`).
    #[must_use]
    pub fn beta(&self) -> &[f64] {
        &self.beta
    }

    /// The matrix `M`.
    #[must_use]
    pub fn matrix(&self) -> &DMatrix<f64> {
        &self.m
    }

    /// 2-norm condition number of `M`.
    #[must_use]
    pub fn condition_number(&self) -> f64 {
        self.cond
    }

    /// Maximum degree.
    #[must_use]
    pub fn l_max(&self) -> usize {
        self.dirs.l_max()
    }

    /// Decomposition weights `Lambda = M^-1 c` of a filter with SH coefficients `c`
    /// (one column per channel; the coefficients are truncated or zero-padded to `L`).
    ///
    /// # Errors
    /// [`SphereError::IllConditioned`] if the solve fails.
    pub fn decompose(&self, k: &ShCoeffs) -> Result<RzhCoeffs> {
        let k = k.resized(self.l_max())?;
        let n = sh_count(self.l_max());
        let ch = k.channels();
        let mut data = vec![0.0; n * ch];
        for c in 0..ch {
            let b = nalgebra::DVector::from_vec(k.channel(c));
            let x = self.lu.solve(&b).ok_or(SphereError::IllConditioned {
                l_max: self.l_max(),
                profile: self.profile.name(),
                cond: self.cond,
                limit: crate::zhf::DEFAULT_COND_LIMIT,
            })?;
            for (i, v) in x.iter().enumerate() {
                data[i * ch + c] = *v;
            }
        }
        Ok(RzhCoeffs {
            l_max: self.l_max(),
            channels: ch,
            data,
        })
    }

    /// SH coefficients `M Lambda` of a decomposition (its band-limited reconstruction).
    ///
    /// # Errors
    /// [`SphereError::Mismatch`] for another degree.
    pub fn reconstruct(&self, z: &RzhCoeffs) -> Result<ShCoeffs> {
        if z.l_max != self.l_max() {
            return Err(SphereError::Mismatch(format!(
                "weights of degree {} for a basis of degree {}",
                z.l_max,
                self.l_max()
            )));
        }
        let n = sh_count(self.l_max());
        let mut out = ShCoeffs::zeros(self.l_max(), z.channels)?;
        for c in 0..z.channels {
            let x = nalgebra::DVector::from_iterator(n, (0..n).map(|i| z.data[i * z.channels + c]));
            let y = &self.m * x;
            for (i, v) in y.iter().enumerate() {
                out.data_mut()[i * z.channels + c] = *v;
            }
        }
        Ok(out)
    }
}
