//! Filtering a spherical signal with a decomposed kernel (ISD Eq. 6, 13, 14).
//!
//! The derivation and conventions are documented on [`Decomposition`].

use ifd_image::Image;
use rayon::prelude::*;

use crate::coeffs::ShCoeffs;
use crate::error::{Result, SphereError};
use crate::profile::{IsdBasis, Profile};
use crate::rotation::Rotation;
use crate::sh::{ShEvaluator, pi_l, sh_count};
use crate::transform::cube_texel;
use crate::zhf::{DirectionSet, RzhCoeffs, Sharing};

/// A kernel decomposed into rotated copies of a profile's mother functions.
///
/// For a kernel `k ~ sum_{l,j} lambda_l^j phi_l((R_l^j)^-1 w)` and a signal `f`,
///
/// ```text
/// fhat(R) = int k(R^-1 w) f(w) dw = sum_{l,j} lambda_l^j fhat_l(R z_l^j)       (Eq. 6)
/// fhat_l(d) = (f (x) phi_l)(d) = int g_l(d . w) f(w) dw
///           = sum_{l'} beta_{l l'} pi_{l'} sum_m f_{l'}^m y_{l'}^m(d)           (Eq. 13-14)
/// ```
///
/// (for the zonal profile `beta = delta` and this is exactly `pi_l f_l^m`, Eq. 13).
/// [`Prefiltered`] holds the per-band convolved signal; [`Decomposition::filter`]
/// evaluates `fhat(R)` for any rotation with `(L + 1)^2` lookups.
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
    /// use ifd_sphere::{Decomposition, Prefiltered};
    /// use ifd_sphere::{Kernel, project_function};
    /// use ifd_sphere::{IsdBasis, Profile};
    /// use ifd_sphere::{Chooser, DirectionSet, Sharing};
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
    /// Every structural invariant is checked ([`Self::validate`]): a file
    /// that parses but is inconsistent is refused, never evaluated.
    pub fn from_json(text: &str) -> Result<Self> {
        let bad = |reason: String| SphereError::Parse {
            what: "spherical decomposition JSON",
            text: String::new(),
            reason,
        };
        let dec: Self = serde_json::from_str(text).map_err(|e| {
            // Only on failure: is it a planar decomposition file?
            let planar = serde_json::from_str::<serde_json::Value>(text)
                .ok()
                .is_some_and(|v| {
                    v.get("format").and_then(serde_json::Value::as_str) == Some("ifd-decomposition")
                });
            bad(if planar {
                "this is a planar decomposition (from `ifd decompose`, used by `ifd filter`), \
                 not a spherical one from `ifd sphere decompose`"
                    .into()
            } else {
                e.to_string()
            })
        })?;
        dec.validate()?;
        Ok(dec)
    }

    /// Checks the invariants a decomposition read from a file must hold:
    /// version 1, a valid direction set, `beta` of `(L + 1)^2` finite values,
    /// weights of degree `L` with `(L + 1)^2 C` finite values, `C >= 1`.
    ///
    /// # Errors
    /// [`SphereError::Parse`] naming the inconsistent field.
    pub fn validate(&self) -> Result<()> {
        let bad = |reason: String| SphereError::Parse {
            what: "spherical decomposition",
            text: String::new(),
            reason,
        };
        if self.version != 1 {
            return Err(bad(format!(
                "version {} is not supported (this build reads version 1)",
                self.version
            )));
        }
        self.directions.check().map_err(|e| bad(e.to_string()))?;
        let l = self.l_max();
        let nb = (l + 1) * (l + 1);
        if self.beta.len() != nb || self.beta.iter().any(|b| !b.is_finite()) {
            return Err(bad(format!(
                "beta must hold {nb} finite values for L = {l}, got {} values",
                self.beta.len()
            )));
        }
        let want = self.profile.beta(l)?;
        if let Some(i) =
            (0..nb).find(|&i| (self.beta[i] - want[i]).abs() > 1e-9 * (1.0 + want[i].abs()))
        {
            return Err(bad(format!(
                "beta[{i}] = {} does not belong to the {} profile ({} expected)",
                ifd_image::short_number(self.beta[i]),
                self.profile.name(),
                ifd_image::short_number(want[i])
            )));
        }
        let w = &self.weights;
        if w.l_max != l || w.channels == 0 || w.data.len() != nb * w.channels {
            return Err(bad(format!(
                "weights of degree {} with {} channel(s) and {} values do not fit lobe \
                 directions of degree {l} ({nb} values per channel expected)",
                w.l_max,
                w.channels,
                w.data.len()
            )));
        }
        if let Some(i) = w.data.iter().position(|v| !v.is_finite()) {
            return Err(bad(format!("weight {i} is not finite")));
        }
        Ok(())
    }

    /// `int k(w) dw` of the decomposed (band-limited) kernel, channel 0: the
    /// filter of the constant signal 1 (`f_0^0 = sqrt(4 pi)`), exact for every
    /// profile.
    ///
    /// ```
    /// use ifd_sphere::Decomposition;
    /// use ifd_sphere::{Kernel, project_function};
    /// use ifd_sphere::{IsdBasis, Profile};
    /// use ifd_sphere::{Chooser, DirectionSet, Sharing};
    /// // vmf:kappa=10 integrates to 2 pi (1 - exp(-2 kappa)) / kappa
    /// let k = Kernel::parse("vmf:kappa=10")?;
    /// let kc = project_function(8, |w| k.eval(w), 64)?;
    /// let basis = IsdBasis::new(Profile::Zonal, DirectionSet::new(8, Sharing::Shared, Chooser::Fibonacci)?)?;
    /// let dec = Decomposition::new(&basis, &kc)?;
    /// let exact = 2.0 * std::f64::consts::PI * (1.0 - (-20.0f64).exp()) / 10.0;
    /// assert!((dec.kernel_integral()? - exact).abs() < 1e-9);
    /// # Ok::<(), ifd_sphere::SphereError>(())
    /// ```
    ///
    /// # Errors
    /// As [`Prefiltered::new`].
    pub fn kernel_integral(&self) -> Result<f64> {
        let mut one = ShCoeffs::zeros(self.l_max(), 1)?;
        one.set(0, 0, 0, (4.0 * std::f64::consts::PI).sqrt());
        let pre = Prefiltered::new(&one, self)?;
        Ok(self.filter(&pre, &Rotation::IDENTITY)?[0])
    }

    /// Filters a whole map: every output texel gets `scale * fhat(R(w))`, with
    /// `w` the texel's direction and `R(w)` its [`meridian_frame`].
    ///
    /// The layout follows the size: `W = 2H` equirectangular (texel centres as
    /// in [`crate::EquirectTransform`]), `W = 6H` a cubemap strip
    /// ([`crate::transform::cube_texel`]). Rows run in parallel (rayon); the
    /// result does not depend on the thread count. `progress(done, total)` is
    /// called after each row (from any thread).
    ///
    /// # Errors
    /// [`SphereError::NotEquirect`] for other sizes; [`SphereError::Mismatch`]
    /// when `pre` was prefiltered for another degree.
    pub fn filter_map(
        &self,
        pre: &Prefiltered,
        width: usize,
        height: usize,
        scale: f64,
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<Image> {
        let layout = MapLayout::from_size(width, height)?;
        if pre.l_max != self.l_max() {
            return Err(SphereError::Mismatch(format!(
                "signal prefiltered to degree {} for a decomposition of degree {}",
                pre.l_max,
                self.l_max()
            )));
        }
        let ch = pre.channels;
        let mut img = Image::new(width, height, ch)?;
        let done = std::sync::atomic::AtomicUsize::new(0);
        img.data_mut()
            .par_chunks_mut(width * ch)
            .enumerate()
            .try_for_each(|(v, row)| -> Result<()> {
                for (u, px) in row.chunks_mut(ch).enumerate() {
                    let d = layout.direction(u, v, width, height);
                    let out = self.filter(pre, &meridian_frame(d))?;
                    for (o, x) in px.iter_mut().zip(&out) {
                        *o = (scale * x) as f32;
                    }
                }
                let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                progress(n, height);
                Ok(())
            })?;
        Ok(img)
    }
}

/// How the texels of a map are laid out on the sphere.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MapLayout {
    /// `W = 2H`: column `u` at azimuth `2 pi (u + 0.5) / W`, row `v` at polar
    /// angle `pi (v + 0.5) / H` (row 0 at the zenith).
    Equirect,
    /// `W = 6H`: a strip of six square faces `+X, -X, +Y, -Y, +Z, -Z` in
    /// OpenGL's orientation ([`crate::transform::cube_texel`]).
    CubemapStrip,
}

impl MapLayout {
    /// The layout a size implies.
    ///
    /// # Errors
    /// [`SphereError::NotEquirect`] (which names both accepted shapes in the CLI)
    /// for sizes that are neither 2:1 with `H >= 2` nor 6:1.
    pub fn from_size(width: usize, height: usize) -> Result<Self> {
        if height >= 2 && width == 2 * height {
            Ok(Self::Equirect)
        } else if height >= 1 && width == 6 * height {
            Ok(Self::CubemapStrip)
        } else {
            Err(SphereError::NotEquirect { width, height })
        }
    }

    /// Direction of the centre of texel `(u, v)` of a `width x height` map.
    #[must_use]
    pub fn direction(self, u: usize, v: usize, width: usize, height: usize) -> [f64; 3] {
        match self {
            Self::Equirect => {
                let p = 2.0 * std::f64::consts::PI * (u as f64 + 0.5) / width as f64;
                let t = std::f64::consts::PI * (v as f64 + 0.5) / height as f64;
                crate::sh::direction(t, p)
            }
            Self::CubemapStrip => {
                let (face, i) = (u / height, u % height);
                let (d, _) = cube_texel(face, i, v, height);
                let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                [d[0] / n, d[1] / n, d[2] / n]
            }
        }
    }
}

/// The frame in which a filtered map evaluates the kernel at direction `w`:
/// `R(w) = Rz(phi) Ry(theta)`, with `(theta, phi)` the polar angles of `w`.
///
/// `R(w)` maps the kernel's axis `+z` onto `w` and its `+x` axis onto the
/// meridian tangent pointing south (towards growing `theta`), its `+y` axis
/// onto the parallel pointing east (towards growing `phi`). An isotropic kernel
/// does not see the frame. For an anisotropic one the frame is singular at the
/// poles: there every azimuth is a meridian, and this function takes `phi =
/// atan2(y, x)`, which is `0` exactly at the poles.
///
/// ```
/// use ifd_sphere::meridian_frame;
/// let w = [0.0, 1.0, 0.0]; // theta = pi/2, phi = pi/2
/// let r = meridian_frame(w);
/// let z = r.apply([0.0, 0.0, 1.0]);
/// let x = r.apply([1.0, 0.0, 0.0]);
/// assert!((z[1] - 1.0).abs() < 1e-15);
/// assert!((x[2] + 1.0).abs() < 1e-15); // south on the equator is -z
/// ```
#[must_use]
pub fn meridian_frame(w: [f64; 3]) -> Rotation {
    let theta = w[2].clamp(-1.0, 1.0).acos();
    // atan2(+-0, -0) would be +-pi: the poles get phi = 0 as documented
    let phi = if w[0] == 0.0 && w[1] == 0.0 {
        0.0
    } else {
        w[1].atan2(w[0])
    };
    Rotation::from_zyz(phi, theta, 0.0)
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
