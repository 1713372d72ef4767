//! Rotated zonal harmonics (RZH), direction sets and zonal harmonic
//! factorisation (ZHF): ISD Eq. 8-12, ZHF Eq. 5-7 and 9-11.
//!
//! The derivation and conventions are documented on [`RzhBasis`].

mod band_matrix;
mod directions;

pub use self::band_matrix::condition_number;
pub(crate) use self::band_matrix::{band_matrix, checked_inverse};
pub use self::directions::{Chooser, DirectionSet, Sharing, check_direction, fibonacci};
use crate::coeffs::ShCoeffs;
use crate::error::{Result, SphereError};
use crate::rotation::Rotation;
use crate::sh::{ShEvaluator, pi_l, sh_count};

/// Default largest accepted condition number of an `M_l`.
pub const DEFAULT_COND_LIMIT: f64 = 1e10;

/// Coefficients in a rotated-zonal-harmonic (or ISD) basis: `Lambda_l^j` for each
/// band `l` and lobe `j` of the band, flat index `l^2 + j`, `C` channels
/// (`((L + 1)^2, C)` row-major, like [`ShCoeffs`]).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RzhCoeffs {
    /// Maximum degree.
    pub l_max: usize,
    /// Channel count.
    pub channels: usize,
    /// Values, `((L + 1)^2, C)` row-major.
    pub data: Vec<f64>,
}

#[derive(Clone)]
struct Band {
    /// `M_l`, row-major `(2l+1)^2`.
    m: Vec<f64>,
    /// `M_l^-1`, row-major.
    minv: Vec<f64>,
    cond: f64,
}

/// An RZH basis: directions with the matrices `M_l`, their inverses and
/// condition numbers (the expensive, reusable setup).
///
/// ```
/// use ifd_sphere::{Chooser, DirectionSet, RzhBasis, Sharing};
/// use ifd_sphere::{Rotation, ShCoeffs, ShRotation};
/// let dirs = DirectionSet::new(6, Sharing::Shared, Chooser::Fibonacci)?;
/// let basis = RzhBasis::new(dirs)?;
/// let mut f = ShCoeffs::zeros(6, 1)?;
/// for (i, v) in f.data_mut().iter_mut().enumerate() { *v = (i as f64 * 0.37).sin(); }
/// let back = basis.zhe(&basis.zhf(&f)?)?;                      // ZHF then ZHE
/// assert!(back.data().iter().zip(f.data()).all(|(a, b)| (a - b).abs() < 1e-12));
/// let r = Rotation::from_zyz(0.3, 1.1, -0.4);
/// let g = basis.rotate(&f, &r)?;                               // ZHF Eq. 10
/// let h = ShRotation::new(&r, 6)?.apply(&f)?;                  // reference
/// assert!(g.data().iter().zip(h.data()).all(|(a, b)| (a - b).abs() < 1e-11));
/// # Ok::<(), ifd_sphere::SphereError>(())
/// ```
///
/// # The basis
/// For band `l` and `2l + 1` directions `z_l^j`, the rotated zonal harmonics
/// `phi_l^j(w) = y_l^0((R_l^j)^-1 w) = K_l^0 P_l(z_l^j . w)` span the same space as
/// the band-`l` SH (for a non-singular set). By the addition theorem
/// (ISD Eq. 9, ZHF Eq. 6) `phi_l^j = pi_l sum_m y_l^m(z_l^j) y_l^m`, hence
///
/// ```text
/// c_l = M_l Lambda_l,   (M_l)_{m j} = pi_l y_l^m(z_l^j)      (ISD Eq. 10)
/// ```
///
/// between the SH coefficients `c_l` and the RZH coefficients `Lambda_l` of a
/// function. [`RzhBasis::zhf`] computes `Lambda = M^-1 c` (ZHF), [`RzhBasis::zhe`]
/// computes `c = M Lambda` (ZHE).
///
/// Note on the ZHF paper: it writes `z = A^T f` with `A = Y^-1`,
/// `Y_{jm} = y_l^m(w_j)`, and `f = Y^T z` (its Sec. 4), which leaves out the factor
/// `n_l* = pi_l` of its own Eq. 6; the two are consistent with each other, so
/// its lobe weights are `pi_l` times ours. We follow ISD Eq. 10-11.
///
/// # Rotation
/// Rotating the function (`g(w) = f(R^T w)`) rotates the lobes and keeps the
/// weights (ZHF Eq. 9), so `c'_l = M_l(R z) Lambda_l` (ZHF Eq. 10, the "standard"
/// algorithm, [`RzhBasis::rotate`]). Sampling the band-`l` part of `f` at the
/// inversely rotated lobe directions gives the "signal-tailored" form (ZHF Eq. 11,
/// [`RzhBasis::rotate_tailored`]): with `Y_l = M_l^T / pi_l`,
/// `g_l(z_j) = f_l(R^T z_j) = (Y_l c'_l)_j`, so `c'_l = pi_l (M_l^-1)^T [f_l(R^T z_j)]_j`.
///
///
/// The direction sets live in `directions.rs`, the band matrices `M_l` in
/// `band_matrix.rs`.
#[derive(Clone)]
pub struct RzhBasis {
    dirs: DirectionSet,
    sh: ShEvaluator,
    bands: Vec<Band>,
}

impl std::fmt::Debug for RzhBasis {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RzhBasis")
            .field("dirs", &self.dirs)
            .field("conds", &self.condition_numbers())
            .finish_non_exhaustive()
    }
}

impl RzhBasis {
    /// Builds `M_l` and `M_l^-1` for every band, refusing condition numbers above
    /// [`DEFAULT_COND_LIMIT`].
    ///
    /// # Errors
    /// [`SphereError::Degenerate`] naming the band and its condition number.
    pub fn new(dirs: DirectionSet) -> Result<Self> {
        Self::with_limit(dirs, DEFAULT_COND_LIMIT)
    }

    /// [`Self::new`] with a custom condition-number limit.
    ///
    /// # Errors
    /// [`SphereError::Degenerate`].
    pub fn with_limit(dirs: DirectionSet, cond_limit: f64) -> Result<Self> {
        let sh = ShEvaluator::new(dirs.l_max())?;
        let mut bands = Vec::with_capacity(dirs.l_max() + 1);
        for l in 0..=dirs.l_max() {
            let m = band_matrix(&sh, l, dirs.band(l));
            let (inv, cond) = checked_inverse(&m, l, cond_limit)?;
            bands.push(Band {
                m: m.transpose().as_slice().to_vec(),
                minv: inv.transpose().as_slice().to_vec(),
                cond,
            });
        }
        Ok(Self { dirs, sh, bands })
    }

    /// The directions.
    #[must_use]
    pub fn directions(&self) -> &DirectionSet {
        &self.dirs
    }

    /// Maximum degree.
    #[must_use]
    pub fn l_max(&self) -> usize {
        self.dirs.l_max()
    }

    /// Condition number of each `M_l`.
    #[must_use]
    pub fn condition_numbers(&self) -> Vec<f64> {
        self.bands.iter().map(|b| b.cond).collect()
    }

    /// `M_l` as a row-major `(2l + 1)^2` slice (rows `m`, columns lobes).
    ///
    /// # Panics
    /// If `l > L`.
    #[must_use]
    pub fn m_band(&self, l: usize) -> &[f64] {
        &self.bands[l].m
    }

    /// `M_l^-1`, row-major.
    ///
    /// # Panics
    /// If `l > L`.
    #[must_use]
    pub fn m_inv_band(&self, l: usize) -> &[f64] {
        &self.bands[l].minv
    }

    fn check(&self, l_max: usize) -> Result<()> {
        if l_max != self.l_max() {
            return Err(SphereError::Mismatch(format!(
                "coefficients of degree {l_max} with an RZH basis of degree {}",
                self.l_max()
            )));
        }
        Ok(())
    }

    /// ZHF: RZH coefficients `Lambda_l = M_l^-1 c_l` of an SH expansion.
    ///
    /// # Errors
    /// [`SphereError::Mismatch`] when the degrees differ.
    pub fn zhf(&self, f: &ShCoeffs) -> Result<RzhCoeffs> {
        self.check(f.l_max())?;
        let ch = f.channels();
        let mut out = vec![0.0; f.data().len()];
        for (l, b) in self.bands.iter().enumerate() {
            block_mul(
                &b.minv,
                2 * l + 1,
                &f.data()[l * l * ch..],
                &mut out[l * l * ch..],
                ch,
            );
        }
        Ok(RzhCoeffs {
            l_max: f.l_max(),
            channels: ch,
            data: out,
        })
    }

    /// ZHE: SH coefficients `c_l = M_l Lambda_l` of an RZH expansion.
    ///
    /// # Errors
    /// [`SphereError::Mismatch`] when the degrees differ.
    pub fn zhe(&self, z: &RzhCoeffs) -> Result<ShCoeffs> {
        self.check(z.l_max)?;
        let ch = z.channels;
        let mut out = ShCoeffs::zeros(z.l_max, ch)?;
        for (l, b) in self.bands.iter().enumerate() {
            block_mul(
                &b.m,
                2 * l + 1,
                &z.data[l * l * ch..],
                &mut out.data_mut()[l * l * ch..],
                ch,
            );
        }
        Ok(out)
    }

    /// Evaluates an RZH expansion directly: `sum_lj Lambda_l^j K_l^0 P_l(z_l^j . w)`
    /// (independent of the SH machinery; for checks).
    ///
    /// # Errors
    /// [`SphereError::Mismatch`] when the degrees differ.
    pub fn eval_rzh(&self, z: &RzhCoeffs, w: [f64; 3]) -> Result<Vec<f64>> {
        self.check(z.l_max)?;
        let w = check_direction(0, w)?;
        let mut out = vec![0.0; z.channels];
        let mut p = vec![0.0; self.l_max() + 1];
        for l in 0..=self.l_max() {
            let k = (((2 * l + 1) as f64) / (4.0 * std::f64::consts::PI)).sqrt();
            for (j, d) in self.dirs.band(l).iter().enumerate() {
                let t = d[0] * w[0] + d[1] * w[1] + d[2] * w[2];
                crate::legendre::legendre_all(l, t, &mut p);
                let v = k * p[l];
                for (c, o) in out.iter_mut().enumerate() {
                    *o += z.data[(l * l + j) * z.channels + c] * v;
                }
            }
        }
        Ok(out)
    }

    /// Rotates an SH expansion by ZHF (ZHF Eq. 10): `c'_l = M_l(R z) M_l^-1 c_l`,
    /// giving the coefficients of `g(w) = f(R^T w)`.
    ///
    /// # Errors
    /// [`SphereError::Mismatch`] when the degrees differ.
    pub fn rotate(&self, f: &ShCoeffs, rot: &Rotation) -> Result<ShCoeffs> {
        let z = self.zhf(f)?;
        self.rotate_rzh(&z, rot)
    }

    /// SH coefficients of an RZH expansion whose lobes are rotated by `rot`
    /// (the second half of ZHF Eq. 10: `[Y^R]^T z`).
    ///
    /// # Errors
    /// [`SphereError::Mismatch`] when the degrees differ.
    pub fn rotate_rzh(&self, z: &RzhCoeffs, rot: &Rotation) -> Result<ShCoeffs> {
        self.check(z.l_max)?;
        let ch = z.channels;
        let l_max = self.l_max();
        let mut out = ShCoeffs::zeros(l_max, ch)?;
        let o = out.data_mut();
        let mut y = vec![0.0; sh_count(l_max)];
        let mut acc = |l0: usize, l1: usize, j: usize, y: &[f64]| {
            // lobe j contributes to bands l0..=l1
            for l in l0..=l1 {
                let p = pi_l(l);
                for i in 0..=2 * l {
                    let yi = p * y[l * l + i];
                    for c in 0..ch {
                        o[(l * l + i) * ch + c] += yi * z.data[(l * l + j) * ch + c];
                    }
                }
            }
        };
        match self.dirs.sharing() {
            Sharing::Shared => {
                for (j, d) in self.dirs.all().iter().enumerate() {
                    self.sh.eval_into(rot.apply(*d), &mut y);
                    acc(j.div_ceil(2), l_max, j, &y);
                }
            }
            Sharing::PerBand => {
                for l in 0..=l_max {
                    for (j, d) in self.dirs.band(l).iter().enumerate() {
                        self.sh.eval_into(rot.apply(*d), &mut y);
                        acc(l, l, j, &y);
                    }
                }
            }
        }
        Ok(out)
    }

    /// Signal-tailored rotation (ZHF Eq. 11): samples the band-`l` expansion of
    /// `f` at the inversely rotated lobe directions `R^T z_l^j` and maps the
    /// samples back with `pi_l (M_l^-1)^T`. Same result as [`Self::rotate`].
    ///
    /// # Errors
    /// [`SphereError::Mismatch`] when the degrees differ.
    pub fn rotate_tailored(&self, f: &ShCoeffs, rot: &Rotation) -> Result<ShCoeffs> {
        self.check(f.l_max())?;
        let ch = f.channels();
        let l_max = self.l_max();
        let src = f.data();
        let mut y = vec![0.0; sh_count(l_max)];
        // samples s[l^2 + j][c] = f_l(R^T z_l^j)
        let mut s = vec![0.0; src.len()];
        let mut sample_bands = |l0: usize, l1: usize, j: usize, y: &[f64]| {
            for l in l0..=l1 {
                for i in 0..=2 * l {
                    let yi = y[l * l + i];
                    for c in 0..ch {
                        s[(l * l + j) * ch + c] += yi * src[(l * l + i) * ch + c];
                    }
                }
            }
        };
        let rt = rot.transpose();
        match self.dirs.sharing() {
            Sharing::Shared => {
                for (j, d) in self.dirs.all().iter().enumerate() {
                    self.sh.eval_into(rt.apply(*d), &mut y);
                    sample_bands(j.div_ceil(2), l_max, j, &y);
                }
            }
            Sharing::PerBand => {
                for l in 0..=l_max {
                    for (j, d) in self.dirs.band(l).iter().enumerate() {
                        self.sh.eval_into(rt.apply(*d), &mut y);
                        sample_bands(l, l, j, &y);
                    }
                }
            }
        }
        self.tailored_from_samples(&s, ch)
    }

    /// The last step of [`Self::rotate_tailored`] for pre-tabulated band
    /// expansions: `samples[(l^2 + j) * C + c] = f_l(R^T z_l^j)` of channel `c`.
    ///
    /// # Errors
    /// [`SphereError::Length`] when `samples` is not `(L + 1)^2 x C`.
    pub fn tailored_from_samples(&self, samples: &[f64], channels: usize) -> Result<ShCoeffs> {
        let l_max = self.l_max();
        let mut out = ShCoeffs::zeros(l_max, channels)?;
        if samples.len() != sh_count(l_max) * channels {
            return Err(SphereError::Length {
                what: "band samples",
                got: samples.len(),
                expected: sh_count(l_max) * channels,
            });
        }
        let o = out.data_mut();
        for (l, b) in self.bands.iter().enumerate() {
            let n = 2 * l + 1;
            let p = pi_l(l);
            for i in 0..n {
                for c in 0..channels {
                    let mut a = 0.0;
                    for j in 0..n {
                        // (M^-1)^T[i][j] = M^-1[j][i]
                        a += b.minv[j * n + i] * samples[(l * l + j) * channels + c];
                    }
                    o[(l * l + i) * channels + c] = p * a;
                }
            }
        }
        Ok(out)
    }
}

/// `out[i][c] = sum_j a[i][j] x[j][c]` for an `n x n` row-major block.
pub(crate) fn block_mul(a: &[f64], n: usize, x: &[f64], out: &mut [f64], ch: usize) {
    for i in 0..n {
        for c in 0..ch {
            let mut s = 0.0;
            for j in 0..n {
                s += a[i * n + j] * x[j * ch + c];
            }
            out[i * ch + c] = s;
        }
    }
}
