//! Pre-tabulated band expansions for the signal-tailored rotation (ZHF Eq.
//! 11): each band's function `f_l(w) = sum_m c_l^m y_l^m(w)` of a static
//! signal tabulated once on an equirectangular grid, so that a rotation is
//! lookups at the inversely rotated lobe directions and the fixed map
//! `pi_l (M_l^-1)^T` ([`crate::zhf::RzhBasis::tailored_from_samples`]), with no
//! SH evaluation at all, as the paper intends for its GPU path (it used
//! cubemaps of `6 x 1024^2`).
//!
//! The derivation and conventions are documented on [`BandTables`].

use std::f64::consts::PI;

use crate::coeffs::ShCoeffs;
use crate::error::{Result, SphereError};
use crate::rotation::Rotation;
use crate::sh::ShEvaluator;
use crate::zhf::{RzhBasis, Sharing};

/// Every band's expansion of a signal on an equirectangular grid.
///
/// Lookups are bilinear between texel centres (wrapping in azimuth), and
/// between the first (last) row and the pole's own value within half a row of
/// a pole (clamping there would make the error first order); one set of four
/// taps and weights per lobe serves every band. The interpolation error of a band-`l` function on a grid of
/// height `H` is about `(pi l / H)^2 / 8` of its amplitude: the tables trade
/// memory (`(L + 1) x 2H^2` values per channel) for accuracy
/// ([`BandTables::new`]'s `height`).
///
/// ```
/// use ifd_sphere::{Rotation, ShCoeffs};
/// use ifd_sphere::BandTables;
/// use ifd_sphere::{Chooser, DirectionSet, RzhBasis, Sharing};
/// let f = ShCoeffs::from_vec(3, 1, (0..16).map(|i| (i as f64 * 0.7).sin()).collect())?;
/// let basis = RzhBasis::new(DirectionSet::new(3, Sharing::Shared, Chooser::Fibonacci)?)?;
/// let tables = BandTables::new(&f, 512)?;
/// let r = Rotation::from_zyz(0.3, 1.1, -0.7);
/// let a = basis.rotate_tailored(&f, &r)?;
/// let b = tables.rotate(&basis, &r)?;
/// for (x, y) in a.data().iter().zip(b.data()) {
///     assert!((x - y).abs() < 1e-3);
/// }
/// # Ok::<(), ifd_sphere::SphereError>(())
/// ```
#[derive(Clone, Debug)]
pub struct BandTables {
    l_max: usize,
    channels: usize,
    height: usize,
    /// `[((l (H W + 2) + k) C + c]`, `k = v W + u` for texels (`W = 2H`),
    /// `H W` the north pole, `H W + 1` the south pole.
    data: Vec<f64>,
}

impl BandTables {
    /// Tabulates `f`'s bands at the centres of a `2H x H` grid (row 0 at the
    /// north pole, column `u` at azimuth `2 pi (u + 0.5) / W`).
    ///
    /// # Errors
    /// [`SphereError::Parameter`] for `height` outside `4..=8192` or a table
    /// above `2^30` values.
    pub fn new(f: &ShCoeffs, height: usize) -> Result<Self> {
        let (l_max, ch) = (f.l_max(), f.channels());
        let w = 2 * height;
        let total = (l_max + 1)
            .checked_mul(w * height + 2)
            .and_then(|x| x.checked_mul(ch));
        if !(4..=8192).contains(&height) || total.is_none_or(|t| t > 1 << 30) {
            return Err(SphereError::Parameter {
                name: "table height",
                value: height.to_string(),
                reason: "use 4..=8192 rows and at most 2^30 values in all",
            });
        }
        let sh = ShEvaluator::new(l_max)?;
        let mut data = vec![0.0f64; total.unwrap_or(0)];
        let mut y = vec![0.0; (l_max + 1) * (l_max + 1)];
        let src = f.data();
        let block = height * w + 2;
        let mut put = |k: usize, d: [f64; 3], y: &mut [f64]| {
            sh.eval_into(d, y);
            for l in 0..=l_max {
                for c in 0..ch {
                    let mut acc = 0.0;
                    for i in l * l..(l + 1) * (l + 1) {
                        acc += y[i] * src[i * ch + c];
                    }
                    data[(l * block + k) * ch + c] = acc;
                }
            }
        };
        for v in 0..height {
            let t = PI * (v as f64 + 0.5) / height as f64;
            for u in 0..w {
                let p = 2.0 * PI * (u as f64 + 0.5) / w as f64;
                put(v * w + u, crate::sh::direction(t, p), &mut y);
            }
        }
        put(height * w, [0.0, 0.0, 1.0], &mut y);
        put(height * w + 1, [0.0, 0.0, -1.0], &mut y);
        Ok(Self {
            l_max,
            channels: ch,
            height,
            data,
        })
    }

    /// Bytes of the tables (`f64`: with `f32` the rounding, amplified by the
    /// condition number of `M_l`, floored the error near 1e-2 for per-band
    /// Fibonacci sets at `L = 8`).
    #[must_use]
    pub fn bytes(&self) -> usize {
        self.data.len() * 8
    }

    /// The bilinear taps of direction `d`: four texel offsets (within a band)
    /// and their weights.
    fn taps(&self, d: [f64; 3]) -> ([usize; 4], [f64; 4]) {
        let (h, w) = (self.height, 2 * self.height);
        let t = d[2].clamp(-1.0, 1.0).acos();
        let p = d[1].atan2(d[0]).rem_euclid(2.0 * PI);
        let fu = p / (2.0 * PI) * w as f64 - 0.5;
        let fv = t / PI * h as f64 - 0.5;
        let u0f = fu.floor();
        let a = fu - u0f;
        let u0 = (u0f as i64).rem_euclid(w as i64) as usize;
        let u1 = (u0 + 1) % w;
        if fv < 0.0 || fv > (h - 1) as f64 {
            // within half a row of a pole: the row, then the pole's value
            let (v, pole, b) = if fv < 0.0 {
                (0, h * w, fv + 0.5)
            } else {
                (h - 1, h * w + 1, h as f64 - 0.5 - fv)
            };
            let b = 2.0 * b.clamp(0.0, 0.5);
            return (
                [v * w + u0, v * w + u1, pole, pole],
                [(1.0 - a) * b, a * b, 1.0 - b, 0.0],
            );
        }
        let v0f = fv.floor();
        let b = fv - v0f;
        let v0 = v0f as usize;
        let v1 = (v0 + 1).min(h - 1);
        (
            [v0 * w + u0, v0 * w + u1, v1 * w + u0, v1 * w + u1],
            [(1.0 - a) * (1.0 - b), a * (1.0 - b), (1.0 - a) * b, a * b],
        )
    }

    /// ZHF Eq. 11 with lookups: the samples `f_l(R^T z_l^j)` from the tables,
    /// then `pi_l (M_l^-1)^T`. The basis must have the tables' degree.
    ///
    /// # Errors
    /// [`SphereError::Mismatch`] for a basis of another degree.
    pub fn rotate(&self, basis: &RzhBasis, rot: &Rotation) -> Result<ShCoeffs> {
        let l_max = self.l_max;
        if basis.l_max() != l_max {
            return Err(SphereError::Mismatch(format!(
                "tables of degree {l_max} for a basis of degree {}",
                basis.l_max()
            )));
        }
        let ch = self.channels;
        let plane = 2 * self.height * self.height + 2;
        let mut s = vec![0.0; (l_max + 1) * (l_max + 1) * ch];
        let rt = rot.transpose();
        let mut sample = |l0: usize, l1: usize, j: usize, d: [f64; 3]| {
            let (idx, wt) = self.taps(rt.apply(d));
            for l in l0..=l1 {
                let band = &self.data[l * plane * ch..(l + 1) * plane * ch];
                for c in 0..ch {
                    let mut acc = 0.0;
                    for k in 0..4 {
                        acc += wt[k] * band[idx[k] * ch + c];
                    }
                    s[(l * l + j) * ch + c] = acc;
                }
            }
        };
        match basis.directions().sharing() {
            Sharing::Shared => {
                for (j, d) in basis.directions().all().iter().enumerate() {
                    sample(j.div_ceil(2), l_max, j, *d);
                }
            }
            Sharing::PerBand => {
                for l in 0..=l_max {
                    for (j, d) in basis.directions().band(l).iter().enumerate() {
                        sample(l, l, j, *d);
                    }
                }
            }
        }
        basis.tailored_from_samples(&s, ch)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SplitMix64;
    use crate::zhf::{Chooser, DirectionSet};

    /// Lookups converge to the on-the-fly rotation as the grid grows (second
    /// order: bilinear), per-band and shared sets alike.
    #[test]
    fn tabulated_rotation_converges_to_the_exact_one() {
        let l = 8;
        let mut rng = SplitMix64::new(5);
        let f =
            ShCoeffs::from_vec(l, 2, (0..2 * 81).map(|_| rng.uniform() - 0.5).collect()).unwrap();
        let r = Rotation::from_zyz(0.4, 2.0, -1.3);
        for sharing in [Sharing::Shared, Sharing::PerBand] {
            let basis =
                RzhBasis::new(DirectionSet::new(l, sharing, Chooser::Fibonacci).unwrap()).unwrap();
            let exact = basis.rotate_tailored(&f, &r).unwrap();
            let err = |h: usize| {
                let t = BandTables::new(&f, h).unwrap();
                let g = t.rotate(&basis, &r).unwrap();
                g.data()
                    .iter()
                    .zip(exact.data())
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0f64, f64::max)
            };
            // the largest coefficient error depends on where the few lobes
            // fall between texels, so compare three doublings: second order
            // gives 1/64 (measured 1/50-1/48), first order 1/8
            let (e1, e2) = (err(32), err(256));
            assert!(e2 < 0.06 * e1, "{sharing:?}: {e1} then {e2}");
            assert!(e2 < 5e-3, "{sharing:?}: {e2}");
        }
        let basis =
            RzhBasis::new(DirectionSet::new(3, Sharing::Shared, Chooser::Fibonacci).unwrap())
                .unwrap();
        let t = BandTables::new(&f, 16).unwrap();
        assert!(t.rotate(&basis, &r).is_err());
        assert!(BandTables::new(&f, 2).is_err());
    }
}
