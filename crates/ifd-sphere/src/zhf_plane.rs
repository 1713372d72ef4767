//! Rotated zonal harmonics in one plane, for functions even in `y`: `l + 1`
//! lobes per band instead of `2l + 1`.
//!
//! The derivation and conventions are documented on [`PlaneRzhBasis`].

use nalgebra::DMatrix;

use crate::coeffs::ShCoeffs;
use crate::error::{Result, SphereError, check_degree};
use crate::sh::{ShEvaluator, pi_l};
use crate::zhf::{DEFAULT_COND_LIMIT, block_mul, checked_inverse};

/// Number of in-plane weights up to degree `l_max`: `(L + 1)(L + 2) / 2`.
#[must_use]
pub const fn plane_count(l_max: usize) -> usize {
    (l_max + 1) * (l_max + 2) / 2
}

/// Flat index `l (l + 1) / 2 + j` of lobe `j` of band `l`.
#[must_use]
pub const fn plane_index(l: usize, j: usize) -> usize {
    l * (l + 1) / 2 + j
}

/// The default nested lobe angles: `pi` times the base-2 van der Corput
/// sequence, `0, pi/2, pi/4, 3pi/4, pi/8, 5pi/8, ...` (`l_max + 1` of them).
///
/// ```
/// let a = ifd_sphere::default_angles(3);
/// let pi = std::f64::consts::PI;
/// assert_eq!(a, vec![0.0, pi / 2.0, pi / 4.0, 3.0 * pi / 4.0]);
/// ```
#[must_use]
pub fn default_angles(l_max: usize) -> Vec<f64> {
    (0..=l_max)
        .map(|j| {
            let (mut n, mut f, mut v) = (j, 0.5, 0.0);
            while n > 0 {
                if n & 1 == 1 {
                    v += f;
                }
                n >>= 1;
                f *= 0.5;
            }
            std::f64::consts::PI * v
        })
        .collect()
}

/// An in-plane RZH basis: the lobe angles, the matrices `E_l` of the module
/// docs, their inverses and condition numbers.
///
/// ```
/// use ifd_sphere::ShCoeffs;
/// use ifd_sphere::{PlaneRzhBasis, plane_count};
/// let basis = PlaneRzhBasis::new(6)?;
/// assert_eq!(basis.directions().len(), 7);
/// // a function even in y: only the m >= 0 coefficients
/// let mut f = ShCoeffs::zeros(6, 1)?;
/// for l in 0..=6i64 {
///     for m in 0..=l {
///         f.data_mut()[(l * (l + 1) + m) as usize] = ((l + 2 * m) as f64 * 0.37).sin();
///     }
/// }
/// let w = basis.zhf(&f)?;                        // 28 weights, not 49
/// assert_eq!(w.len(), plane_count(6));
/// let back = basis.zhe(&w, 1)?;
/// assert!(back.data().iter().zip(f.data()).all(|(a, b)| (a - b).abs() < 1e-12));
/// # Ok::<(), ifd_sphere::SphereError>(())
/// ```
///
/// # Why
/// An isotropic BRDF's slice taken with the view in the `xz` plane
/// (`phi_o = 0`) is even in `y`: `k(x, -y, z) = k(x, y, z)`. Its SH
/// coefficients with `m < 0` (the `sin(|m| p)` harmonics, odd in `y`) vanish,
/// so band `l` lives in the `(l + 1)`-dimensional space spanned by
/// `y_l^0 .. y_l^l`. Zonal harmonics about directions in the `xz` plane are
/// even in `y` too, and `l + 1` of them span that space, so such a slice needs
/// `sum_l (l + 1) = (L + 1)(L + 2) / 2` weights and `L + 1` lobe directions
/// (band `l` uses the first `l + 1`), about half of the `2L + 1` of a general
/// shared set ([`crate::RzhBasis`]): half the work for a shader that evaluates the
/// environment at each lobe.
///
/// # The matrices
/// With `d_j = (sin a_j, 0, cos a_j)`, ISD Eq. 10 restricted to `m >= 0`:
///
/// ```text
/// c_l^m = sum_{j <= l} (E_l)_{m j} lambda_l^j,   (E_l)_{m j} = pi_l y_l^m(d_j),   m = 0..l
/// ```
///
/// and `c_l^m = 0` for `m < 0`.
///
/// # Why any `l + 1` distinct angles in `[0, pi)` work
/// `E_l` is singular exactly when some non-zero band-`l` function `f`, even in
/// `y`, vanishes at all the `d_j`. On the great circle `y = 0`, `f(a) =
/// f(sin a, 0, cos a)` is a trigonometric polynomial of degree `l` with
/// `f(a + pi) = (-1)^l f(a)` (band `l` has parity `(-1)^l`), so its zeros
/// come in pairs `a, a + pi`; having at most `2l` zeros in `[0, 2 pi)` unless it
/// vanishes identically, it has at most `l` in `[0, pi)`. And it cannot vanish
/// on the whole circle: a harmonic polynomial that vanishes on the plane
/// `y = 0` is odd in `y` (Schwarz reflection), and `f` is even, so `f = 0`.
/// How well conditioned `E_l` is depends on the spacing of the angles (modulo
/// `pi`); the default nested sequence is the van der Corput sequence in base 2
/// (`0, pi/2, pi/4, 3pi/4, pi/8, ...`), whose prefixes keep every gap within a
/// factor of two of every other. Its condition numbers grow slowly (see
/// [`PlaneRzhBasis::condition_numbers`]): the largest is 4.9 up to `L = 10`,
/// 7.6 up to 20, 11 up to 30 and 24.5 up to 100 (checked below 30 in the
/// tests); the golden-ratio sequence does about as well (4.8, 8.4, 11.5, 25).
#[derive(Clone, Debug)]
pub struct PlaneRzhBasis {
    angles: Vec<f64>,
    dirs: Vec<[f64; 3]>,
    /// Per band: `E_l` and `E_l^-1`, row-major `(l + 1)^2`, and cond(`E_l`).
    bands: Vec<(Vec<f64>, Vec<f64>, f64)>,
}

impl PlaneRzhBasis {
    /// The basis of degree `l_max` with the [`default_angles`].
    ///
    /// # Errors
    /// Degrees beyond [`crate::MAX_DEGREE`].
    pub fn new(l_max: usize) -> Result<Self> {
        Self::with_angles(&default_angles(l_max))
    }

    /// The basis with the given `L + 1` lobe angles (radians from `+z` towards
    /// `+x`; band `l` uses the first `l + 1`).
    ///
    /// # Errors
    /// [`SphereError::Parameter`] for no or non-finite angles;
    /// [`SphereError::Degenerate`] when a band's matrix is singular or worse
    /// conditioned than [`DEFAULT_COND_LIMIT`] (two angles equal modulo `pi`).
    pub fn with_angles(angles: &[f64]) -> Result<Self> {
        if angles.is_empty() || angles.iter().any(|a| !a.is_finite()) {
            return Err(SphereError::Parameter {
                name: "in-plane lobe angles",
                value: format!("{angles:?}"),
                reason: "need L + 1 finite angles",
            });
        }
        let l_max = angles.len() - 1;
        check_degree(l_max)?;
        let dirs: Vec<[f64; 3]> = angles.iter().map(|a| [a.sin(), 0.0, a.cos()]).collect();
        let sh = ShEvaluator::new(l_max)?;
        let mut ys = vec![0.0; (l_max + 1) * (l_max + 1)];
        let y_all: Vec<Vec<f64>> = dirs
            .iter()
            .map(|&d| {
                sh.eval_into(d, &mut ys);
                ys.clone()
            })
            .collect();
        let mut bands = Vec::with_capacity(l_max + 1);
        for l in 0..=l_max {
            let n = l + 1;
            let p = pi_l(l);
            let e = DMatrix::from_fn(n, n, |m, j| p * y_all[j][l * (l + 1) + m]);
            let (inv, cond) = checked_inverse(&e, l, DEFAULT_COND_LIMIT)?;
            bands.push((
                e.transpose().as_slice().to_vec(),
                inv.transpose().as_slice().to_vec(),
                cond,
            ));
        }
        Ok(Self {
            angles: angles.to_vec(),
            dirs,
            bands,
        })
    }

    /// Maximum degree.
    #[must_use]
    pub fn l_max(&self) -> usize {
        self.angles.len() - 1
    }

    /// The lobe angles.
    #[must_use]
    pub fn angles(&self) -> &[f64] {
        &self.angles
    }

    /// The lobe directions `(sin a_j, 0, cos a_j)`; lobe `j` serves the bands
    /// `l >= j`.
    #[must_use]
    pub fn directions(&self) -> &[[f64; 3]] {
        &self.dirs
    }

    /// The condition number of each `E_l`.
    #[must_use]
    pub fn condition_numbers(&self) -> Vec<f64> {
        self.bands.iter().map(|b| b.2).collect()
    }

    fn check(&self, l_max: usize) -> Result<()> {
        if l_max != self.l_max() {
            return Err(SphereError::Mismatch(format!(
                "coefficients of degree {l_max} with an in-plane RZH basis of degree {}",
                self.l_max()
            )));
        }
        Ok(())
    }

    /// The weights `lambda_l = E_l^-1 c_l` of the `m >= 0` part of `f`
    /// (`((L + 1)(L + 2) / 2, C)` row-major, index [`plane_index`]); the
    /// `m < 0` coefficients, zero for a function even in `y`, are ignored
    /// (measure them with [`odd_part_norm`]).
    ///
    /// # Errors
    /// [`SphereError::Mismatch`] when the degrees differ.
    pub fn zhf(&self, f: &ShCoeffs) -> Result<Vec<f64>> {
        self.check(f.l_max())?;
        let ch = f.channels();
        let mut out = vec![0.0; plane_count(self.l_max()) * ch];
        for (l, (_, inv, _)) in self.bands.iter().enumerate() {
            block_mul(
                inv,
                l + 1,
                &f.data()[l * (l + 1) * ch..],
                &mut out[plane_index(l, 0) * ch..],
                ch,
            );
        }
        Ok(out)
    }

    /// The SH coefficients `c_l = E_l lambda_l` (`m >= 0`; zero for `m < 0`)
    /// of in-plane weights with `channels` channels.
    ///
    /// # Errors
    /// [`SphereError::Length`] for a buffer of another length.
    pub fn zhe(&self, weights: &[f64], channels: usize) -> Result<ShCoeffs> {
        let l_max = self.l_max();
        let expected = plane_count(l_max) * channels;
        if weights.len() != expected || channels == 0 {
            return Err(SphereError::Length {
                what: "in-plane RZH weights",
                got: weights.len(),
                expected,
            });
        }
        let ch = channels;
        let mut out = ShCoeffs::zeros(l_max, ch)?;
        for (l, (e, _, _)) in self.bands.iter().enumerate() {
            block_mul(
                e,
                l + 1,
                &weights[plane_index(l, 0) * ch..],
                &mut out.data_mut()[l * (l + 1) * ch..],
                ch,
            );
        }
        Ok(out)
    }
}

/// The L2 norm of the `m < 0` part of `f` (all channels): the part, odd in
/// `y`, that an in-plane basis cannot hold.
#[must_use]
pub fn odd_part_norm(f: &ShCoeffs) -> f64 {
    let ch = f.channels();
    let mut s = 0.0;
    for l in 0..=f.l_max() {
        for i in l * l..l * (l + 1) {
            for c in 0..ch {
                s += f.data()[i * ch + c].powi(2);
            }
        }
    }
    s.sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Rotation;
    use crate::rng::SplitMix64;

    #[test]
    fn default_angles_are_well_conditioned_to_degree_100() {
        let b = PlaneRzhBasis::new(100).unwrap();
        let worst = b.condition_numbers().into_iter().fold(0.0f64, f64::max);
        assert!(worst < 30.0, "worst condition number {worst}");
    }

    #[test]
    fn equal_angles_modulo_pi_are_refused() {
        let pi = std::f64::consts::PI;
        let e = PlaneRzhBasis::with_angles(&[0.0, 0.3, 0.3 + pi]).unwrap_err();
        assert!(matches!(e, SphereError::Degenerate { band: 2, .. }), "{e}");
        assert!(PlaneRzhBasis::with_angles(&[0.0, f64::NAN]).is_err());
        assert!(PlaneRzhBasis::with_angles(&[]).is_err());
    }

    /// A y-even function built independently: the sum of zonal lobes about
    /// random axes and their mirror images in the `xz` plane, whose SH
    /// coefficients come from the addition theorem. ZHF then ZHE gives it
    /// back, and the lobe sum evaluated directly (Legendre polynomials about
    /// the in-plane directions) equals the SH expansion at random points.
    #[test]
    fn mirrored_lobes_round_trip_and_evaluate() {
        let l_max = 9;
        let sh = ShEvaluator::new(l_max).unwrap();
        let mut rng = SplitMix64::new(7);
        let mut f = ShCoeffs::zeros(l_max, 1).unwrap();
        let mut y = vec![0.0; (l_max + 1) * (l_max + 1)];
        for _ in 0..5 {
            let a = rng.direction();
            let w = rng.uniform() - 0.5;
            for d in [a, [a[0], -a[1], a[2]]] {
                sh.eval_into(d, &mut y);
                for l in 0..=l_max {
                    let k = w * (l as f64 + 1.0).recip();
                    let band = l * l..(l + 1) * (l + 1);
                    for (o, yv) in f.data_mut()[band.clone()].iter_mut().zip(&y[band]) {
                        *o += k * pi_l(l) * yv;
                    }
                }
            }
        }
        assert!(odd_part_norm(&f) < 1e-13, "{}", odd_part_norm(&f));
        let basis = PlaneRzhBasis::new(l_max).unwrap();
        let lam = basis.zhf(&f).unwrap();
        let back = basis.zhe(&lam, 1).unwrap();
        for (a, b) in back.data().iter().zip(f.data()) {
            assert!((a - b).abs() < 1e-12, "{a} vs {b}");
        }
        // direct evaluation: sum_lj lambda K_l P_l(d_j . w)
        let mut p = vec![0.0; l_max + 1];
        for _ in 0..20 {
            let w = rng.direction();
            sh.eval_into(w, &mut y);
            let via_sh: f64 = y.iter().zip(f.data()).map(|(a, b)| a * b).sum();
            let mut direct = 0.0;
            for l in 0..=l_max {
                let k = ((2 * l + 1) as f64 / (4.0 * std::f64::consts::PI)).sqrt();
                for (j, d) in basis.directions()[..=l].iter().enumerate() {
                    let t = d[0] * w[0] + d[1] * w[1] + d[2] * w[2];
                    crate::legendre::legendre_all(l, t, &mut p);
                    direct += lam[plane_index(l, j)] * k * p[l];
                }
            }
            assert!((via_sh - direct).abs() < 1e-11, "{via_sh} vs {direct}");
        }
        // a rotation about y keeps the xz plane: the rotated function is
        // still even, and its weights give the rotated coefficients
        let r = Rotation::from_zyz(0.0, 0.7, 0.0);
        let g = crate::ShRotation::new(&r, l_max)
            .unwrap()
            .apply(&f)
            .unwrap();
        assert!(odd_part_norm(&g) < 1e-12);
        assert!(basis.zhf(&ShCoeffs::zeros(3, 1).unwrap()).is_err());
        assert!(basis.zhe(&lam[1..], 1).is_err());
    }
}
