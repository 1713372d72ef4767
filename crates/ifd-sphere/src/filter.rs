//! Filtering a spherical signal with a decomposed kernel (ISD Eq. 6, 13, 14).
//!
//! For a kernel `k ~ sum_{l,j} lambda_l^j phi_l((R_l^j)^-1 w)` and a signal `f`,
//!
//! ```text
//! fhat(R) = int k(R^-1 w) f(w) dw = sum_{l,j} lambda_l^j fhat_l(R z_l^j)       (Eq. 6)
//! fhat_l(d) = (f (x) phi_l)(d) = int g_l(d . w) f(w) dw
//!           = sum_{l'} beta_{l l'} pi_{l'} sum_m f_{l'}^m y_{l'}^m(d)           (Eq. 13-14)
//! ```
//!
//! (for the zonal profile `beta = delta` and this is exactly `pi_l f_l^m`, Eq. 13).
//! [`Prefiltered`] holds the per-band convolved signal; [`Decomposition::filter`]
//! evaluates `fhat(R)` for any rotation with `(L + 1)^2` lookups.

use crate::coeffs::ShCoeffs;
use crate::error::{Result, SphereError};
use crate::profile::{IsdBasis, Profile};
use crate::rotation::Rotation;
use crate::sh::{ShEvaluator, pi_l, sh_count};
use crate::zhf::{DirectionSet, RzhCoeffs, Sharing};

/// A kernel decomposed into rotated copies of a profile's mother functions.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Decomposition {
    /// File-format version (1).
    pub version: u32,
    /// The mother functions.
    pub profile: Profile,
    /// Lobe directions.
    pub directions: DirectionSet,
    /// `beta_{l l'}`, row-major `(L + 1)^2`.
    pub beta: Vec<f64>,
    /// Weights `lambda_l^j` (one channel per kernel channel).
    pub weights: RzhCoeffs,
    /// Condition number of `M`.
    pub condition_number: f64,
}

impl Decomposition {
    /// Decomposes a kernel given by its SH coefficients (truncated/padded to the basis degree).
    ///
    /// ```
    /// use ifd_sphere::filter::{Decomposition, Prefiltered};
    /// use ifd_sphere::kernel::{Kernel, project_function};
    /// use ifd_sphere::profile::{IsdBasis, Profile};
    /// use ifd_sphere::zhf::{Chooser, DirectionSet, Sharing};
    /// use ifd_sphere::{Rotation, ShCoeffs};
    /// let l = 6;
    /// let k = Kernel::parse("aniso-gauss:s1=0.6,s2=0.3")?;
    /// let kc = project_function(l, |w| k.eval(w), 64)?;
    /// let basis = IsdBasis::new(Profile::Zonal, DirectionSet::new(l, Sharing::Shared, Chooser::Fibonacci)?)?;
    /// let dec = Decomposition::new(&basis, &kc)?;
    /// let mut f = ShCoeffs::zeros(l, 1)?;
    /// f.set(2, 1, 0, 1.0);
    /// let pre = Prefiltered::new(&f, &dec)?;
    /// let v = dec.filter(&pre, &Rotation::from_zyz(0.2, 0.5, 0.1))?;
    /// assert_eq!(v.len(), 1);
    /// # Ok::<(), ifd_sphere::SphereError>(())
    /// ```
    ///
    /// # Errors
    /// As [`IsdBasis::decompose`].
    pub fn new(basis: &IsdBasis, kernel: &ShCoeffs) -> Result<Self> {
        Ok(Self {
            version: 1,
            profile: basis.profile(),
            directions: basis.directions().clone(),
            beta: basis.beta().to_vec(),
            weights: basis.decompose(kernel)?,
            condition_number: basis.condition_number(),
        })
    }

    /// Maximum degree.
    #[must_use]
    pub fn l_max(&self) -> usize {
        self.directions.l_max()
    }

    /// Evaluates the decomposed kernel at `w`: `sum lambda_l^j g_l(z_l^j . w)`.
    #[must_use]
    pub fn eval_kernel(&self, w: [f64; 3]) -> Vec<f64> {
        let ch = self.weights.channels;
        let mut out = vec![0.0; ch];
        for l in 0..=self.l_max() {
            for (j, d) in self.directions.band(l).iter().enumerate() {
                let g = self
                    .profile
                    .eval(l, d[0] * w[0] + d[1] * w[1] + d[2] * w[2]);
                for (c, o) in out.iter_mut().enumerate() {
                    *o += self.weights.data[(l * l + j) * ch + c] * g;
                }
            }
        }
        out
    }

    /// `fhat(R) = int k(R^-1 w) f(w) dw` by Eq. 6, for kernel channel 0 and every
    /// signal channel.
    ///
    /// # Errors
    /// [`SphereError::Mismatch`] when the prefiltered signal has another degree.
    pub fn filter(&self, pre: &Prefiltered, rot: &Rotation) -> Result<Vec<f64>> {
        if pre.l_max != self.l_max() {
            return Err(SphereError::Mismatch(format!(
                "signal prefiltered to degree {} for a decomposition of degree {}",
                pre.l_max,
                self.l_max()
            )));
        }
        let l_max = self.l_max();
        let ch = pre.channels;
        let kc = self.weights.channels;
        let mut out = vec![0.0; ch];
        let mut vals = vec![0.0; (l_max + 1) * ch];
        let mut y = vec![0.0; sh_count(l_max)];
        let mut add = |l0: usize, j: usize, vals: &[f64]| {
            for l in l0..=l_max {
                let lam = self.weights.data[(l * l + j) * kc];
                for c in 0..ch {
                    out[c] += lam * vals[l * ch + c];
                }
            }
        };
        match self.directions.sharing() {
            Sharing::Shared => {
                for (j, d) in self.directions.all().iter().enumerate() {
                    pre.eval_bands_with(rot.apply(*d), &mut y, &mut vals);
                    add(j.div_ceil(2), j, &vals);
                }
            }
            Sharing::PerBand => {
                for l in 0..=l_max {
                    for (j, d) in self.directions.band(l).iter().enumerate() {
                        pre.eval_bands_with(rot.apply(*d), &mut y, &mut vals);
                        for c in 0..ch {
                            out[c] += self.weights.data[(l * l + j) * kc] * vals[l * ch + c];
                        }
                    }
                }
            }
        }
        Ok(out)
    }

    /// JSON text of the decomposition.
    ///
    /// # Errors
    /// Never in practice (serialisation of plain data).
    pub fn to_json(&self) -> Result<String> {
        serde_json::to_string_pretty(self).map_err(|e| SphereError::Parse {
            what: "decomposition",
            text: String::new(),
            reason: e.to_string(),
        })
    }

    /// Parses JSON written by [`Self::to_json`].
    ///
    /// # Errors
    /// [`SphereError::Parse`].
    pub fn from_json(text: &str) -> Result<Self> {
        serde_json::from_str(text).map_err(|e| SphereError::Parse {
            what: "decomposition JSON",
            text: text.chars().take(40).collect(),
            reason: e.to_string(),
        })
    }
}

/// A signal convolved with every band's mother function (Eq. 13), kept as SH
/// coefficients and evaluated on the fly (Eq. 14).
#[derive(Clone, Debug)]
pub struct Prefiltered {
    l_max: usize,
    channels: usize,
    /// `beta_{l l'} pi_{l'}`, row-major.
    scale: Vec<f64>,
    signal: ShCoeffs,
    sh: ShEvaluator,
}

impl Prefiltered {
    /// Prefilters `signal` (truncated/padded to the decomposition's degree) for
    /// the decomposition's profile.
    ///
    /// # Errors
    /// [`SphereError::DegreeTooHigh`].
    pub fn new(signal: &ShCoeffs, dec: &Decomposition) -> Result<Self> {
        let l_max = dec.l_max();
        let nb = l_max + 1;
        let scale = (0..nb * nb).map(|i| dec.beta[i] * pi_l(i % nb)).collect();
        Ok(Self {
            l_max,
            channels: signal.channels(),
            scale,
            signal: signal.resized(l_max)?,
            sh: ShEvaluator::new(l_max)?,
        })
    }

    /// SH coefficients of `fhat_l` (Eq. 13): `beta_{l l'} pi_{l'} f_{l'}^m`.
    ///
    /// # Errors
    /// [`SphereError::Parameter`] when `l > L`.
    pub fn band_coeffs(&self, l: usize) -> Result<ShCoeffs> {
        if l > self.l_max {
            return Err(SphereError::Parameter {
                name: "band",
                value: l.to_string(),
                reason: "beyond the prefiltered degree",
            });
        }
        let mut out = self.signal.clone();
        let ch = self.channels;
        let nb = self.l_max + 1;
        for lp in 0..=self.l_max {
            let s = self.scale[l * nb + lp];
            for v in &mut out.data_mut()[lp * lp * ch..(lp + 1) * (lp + 1) * ch] {
                *v *= s;
            }
        }
        Ok(out)
    }

    /// `fhat_l(d)` for all bands: `out[l * C + c]`.
    #[must_use]
    pub fn eval_bands(&self, d: [f64; 3]) -> Vec<f64> {
        let mut y = vec![0.0; sh_count(self.l_max)];
        let mut out = vec![0.0; (self.l_max + 1) * self.channels];
        self.eval_bands_with(d, &mut y, &mut out);
        out
    }

    fn eval_bands_with(&self, d: [f64; 3], y: &mut [f64], out: &mut [f64]) {
        let ch = self.channels;
        let nb = self.l_max + 1;
        self.sh.eval_into(d, y);
        // per-band signal values F_{l'}(d)
        let mut band = vec![0.0; nb * ch];
        let s = self.signal.data();
        for lp in 0..nb {
            for i in lp * lp..(lp + 1) * (lp + 1) {
                for c in 0..ch {
                    band[lp * ch + c] += y[i] * s[i * ch + c];
                }
            }
        }
        for l in 0..nb {
            for c in 0..ch {
                let mut acc = 0.0;
                for lp in 0..nb {
                    let sc = self.scale[l * nb + lp];
                    if sc != 0.0 {
                        acc += sc * band[lp * ch + c];
                    }
                }
                out[l * ch + c] = acc;
            }
        }
    }
}
