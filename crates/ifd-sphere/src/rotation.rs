//! 3D rotations and the reference SH rotation (Ivanic-Ruedenberg recurrences).
//!
//! The derivation and conventions are documented on [`ShRotation`].

use crate::coeffs::ShCoeffs;
use crate::error::{Result, SphereError, check_degree};

/// A 3x3 rotation matrix (row-major), `w' = R w`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rotation {
    /// Rows of the matrix.
    pub m: [[f64; 3]; 3],
}

impl Default for Rotation {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl Rotation {
    /// The identity.
    pub const IDENTITY: Self = Self {
        m: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
    };

    /// Rotation by `a` radians about `z`.
    #[must_use]
    pub fn rz(a: f64) -> Self {
        let (s, c) = a.sin_cos();
        Self::rz_cos_sin(c, s)
    }

    /// Rotation about `z` by the angle of cosine `c` and sine `s` (`c^2 +
    /// s^2 = 1`), for callers that have them without the angle.
    ///
    /// ```
    /// use ifd_sphere::Rotation;
    /// let a = Rotation::rz(0.3);
    /// let b = Rotation::rz_cos_sin(0.3f64.cos(), 0.3f64.sin());
    /// assert_eq!(a, b);
    /// ```
    #[must_use]
    pub fn rz_cos_sin(c: f64, s: f64) -> Self {
        Self {
            m: [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]],
        }
    }

    /// Rotation by `b` radians about `y`.
    #[must_use]
    pub fn ry(b: f64) -> Self {
        let (s, c) = b.sin_cos();
        Self {
            m: [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]],
        }
    }

    /// `R = Rz(a) Ry(b) Rz(c)`.
    ///
    /// ```
    /// use ifd_sphere::Rotation;
    /// let r = Rotation::from_zyz(0.0, std::f64::consts::FRAC_PI_2, 0.0);
    /// let d = r.apply([0.0, 0.0, 1.0]); // z is tilted onto x
    /// assert!((d[0] - 1.0).abs() < 1e-15);
    /// ```
    #[must_use]
    pub fn from_zyz(a: f64, b: f64, c: f64) -> Self {
        Self::rz(a).mul(&Self::ry(b)).mul(&Self::rz(c))
    }

    /// Euler angles `(a, b, c)` with `R = Rz(a) Ry(b) Rz(c)`, `b` in `[0, pi]`.
    #[must_use]
    pub fn to_zyz(&self) -> (f64, f64, f64) {
        let m = &self.m;
        let b = m[2][2].clamp(-1.0, 1.0).acos();
        if b.sin() > 1e-12 {
            (m[1][2].atan2(m[0][2]), b, m[2][1].atan2(-m[2][0]))
        } else if m[2][2] > 0.0 {
            (m[1][0].atan2(m[0][0]), 0.0, 0.0)
        } else {
            ((-m[1][0]).atan2(-m[0][0]), std::f64::consts::PI, 0.0)
        }
    }

    /// Rotation of `angle` radians about a (normalised here) axis; the
    /// identity for a zero axis.
    #[must_use]
    pub fn from_axis_angle(axis: [f64; 3], angle: f64) -> Self {
        let n = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
        if n.is_nan() || n <= 0.0 || !n.is_finite() {
            return Self::IDENTITY;
        }
        let [x, y, z] = [axis[0] / n, axis[1] / n, axis[2] / n];
        let (s, c) = angle.sin_cos();
        let t = 1.0 - c;
        Self {
            m: [
                [t * x * x + c, t * x * y - s * z, t * x * z + s * y],
                [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
                [t * x * z - s * y, t * y * z + s * x, t * z * z + c],
            ],
        }
    }

    /// A rotation taking `z` onto the direction `d` (the frame of ISD's
    /// footnote 1, built from `z x d`); the identity (or a half-turn about `x`)
    /// when `d` is (anti)parallel to `z`.
    #[must_use]
    pub fn aligning_z_to(d: [f64; 3]) -> Self {
        let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        if n.is_nan() || n <= 0.0 {
            return Self::IDENTITY;
        }
        let d = [d[0] / n, d[1] / n, d[2] / n];
        let axis = [-d[1], d[0], 0.0];
        let s = (axis[0] * axis[0] + axis[1] * axis[1]).sqrt();
        if s < 1e-300 {
            return if d[2] > 0.0 {
                Self::IDENTITY
            } else {
                Self::from_axis_angle([1.0, 0.0, 0.0], std::f64::consts::PI)
            };
        }
        Self::from_axis_angle(axis, s.atan2(d[2]))
    }

    /// A uniformly distributed random rotation from three numbers in `[0, 1)`
    /// (Shoemake's quaternion method).
    #[must_use]
    pub fn from_uniform(u1: f64, u2: f64, u3: f64) -> Self {
        use std::f64::consts::TAU;
        let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
        let q = [
            a * (TAU * u2).sin(),
            a * (TAU * u2).cos(),
            b * (TAU * u3).sin(),
            b * (TAU * u3).cos(),
        ];
        let [x, y, z, w] = q;
        Self {
            m: [
                [
                    1.0 - 2.0 * (y * y + z * z),
                    2.0 * (x * y - z * w),
                    2.0 * (x * z + y * w),
                ],
                [
                    2.0 * (x * y + z * w),
                    1.0 - 2.0 * (x * x + z * z),
                    2.0 * (y * z - x * w),
                ],
                [
                    2.0 * (x * z - y * w),
                    2.0 * (y * z + x * w),
                    1.0 - 2.0 * (x * x + y * y),
                ],
            ],
        }
    }

    /// `self * other` (apply `other` first).
    #[must_use]
    pub fn mul(&self, other: &Self) -> Self {
        let mut m = [[0.0; 3]; 3];
        for (i, row) in m.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = (0..3).map(|k| self.m[i][k] * other.m[k][j]).sum();
            }
        }
        Self { m }
    }

    /// The inverse `R^T`.
    #[must_use]
    pub fn transpose(&self) -> Self {
        let m = &self.m;
        Self {
            m: [
                [m[0][0], m[1][0], m[2][0]],
                [m[0][1], m[1][1], m[2][1]],
                [m[0][2], m[1][2], m[2][2]],
            ],
        }
    }

    /// `R d`.
    #[must_use]
    pub fn apply(&self, d: [f64; 3]) -> [f64; 3] {
        let m = &self.m;
        [
            m[0][0] * d[0] + m[0][1] * d[1] + m[0][2] * d[2],
            m[1][0] * d[0] + m[1][1] * d[1] + m[1][2] * d[2],
            m[2][0] * d[0] + m[2][1] * d[1] + m[2][2] * d[2],
        ]
    }

    /// `R^T d`.
    #[must_use]
    pub fn apply_inverse(&self, d: [f64; 3]) -> [f64; 3] {
        self.transpose().apply(d)
    }

    /// Largest deviation of `R^T R` from the identity and of `det R` from 1.
    #[must_use]
    pub fn orthogonality_error(&self) -> f64 {
        let p = self.transpose().mul(self);
        let mut e: f64 = 0.0;
        for (i, row) in p.m.iter().enumerate() {
            for (j, v) in row.iter().enumerate() {
                e = e.max((v - if i == j { 1.0 } else { 0.0 }).abs());
            }
        }
        let m = &self.m;
        let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
        e.max((det - 1.0).abs())
    }
}

/// Block-diagonal rotation matrices of real SH up to degree `L`, built with the
/// Ivanic-Ruedenberg recurrences: the reference SH rotation.
///
/// ```
/// use ifd_sphere::{Rotation, ShCoeffs, ShRotation};
/// let mut f = ShCoeffs::zeros(1, 1)?;
/// f.set(1, 0, 0, 1.0); // a lobe along z
/// let r = ShRotation::new(&Rotation::from_zyz(0.0, std::f64::consts::FRAC_PI_2, 0.0), 1)?;
/// let g = r.apply(&f)?; // now along x: y_1^1 = -0.4886 x, so the coefficient is -1
/// assert!((g.get(1, 1, 0) + 1.0).abs() < 1e-14);
/// # Ok::<(), ifd_sphere::SphereError>(())
/// ```
///
/// # Convention
/// [`Rotation::from_zyz`]`(a, b, c)` is `R = Rz(a) Ry(b) Rz(c)` (radians, right
/// handed, active). Rotating a function means `g(w) = f(R^T w)`: the function's
/// features move with `R` (a lobe pointing along `d` ends up pointing along `R d`).
/// This is what `ducc0.sht.rotate_alm(alm, lmax, psi=c, theta=b, phi=a)` computes.
///
/// # Reference rotation
/// [`ShRotation`] builds the block-diagonal real-SH rotation matrices with the
/// recurrences of Ivanic and Ruedenberg (J. Phys. Chem. 1996, with the 1998
/// erratum), which work in the real basis *without* the Condon-Shortley phase.
/// Our basis (Sloan, with the phase) differs by `(-1)^m` on every function, so
/// the band matrices are conjugated by `D_l = diag((-1)^m)`.
/// Band 1 of the phase-free basis is proportional to `(y, z, x)`; a linear
/// function `a . w` becomes `a . (R^T w) = (R a) . w`, so `R^1 = P R P^T` with
/// the permutation `(y, z, x)`, and `c'_l = R^l c_l`.
#[derive(Clone, Debug)]
pub struct ShRotation {
    l_max: usize,
    /// Band `l` block, `(2l + 1)^2` row-major, rows/cols `m = -l..=l`.
    blocks: Vec<Vec<f64>>,
}

impl ShRotation {
    /// Builds the band matrices of `rot` for `l <= l_max`.
    ///
    /// # Errors
    /// [`SphereError::DegreeTooHigh`]; [`SphereError::Parameter`] when `rot` is
    /// not orthonormal to `1e-6`.
    pub fn new(rot: &Rotation, l_max: usize) -> Result<Self> {
        check_degree(l_max)?;
        let err = rot.orthogonality_error();
        if err.is_nan() || err >= 1e-6 {
            return Err(SphereError::Parameter {
                name: "rotation",
                value: format!("{:?}", rot.m),
                reason: "not a rotation matrix (R^T R != I or det != 1)",
            });
        }
        let mut blocks: Vec<Vec<f64>> = Vec::with_capacity(l_max + 1);
        blocks.push(vec![1.0]);
        if l_max >= 1 {
            // Phase-free basis: band 1 ~ (y, z, x).
            let p = [1usize, 2, 0];
            let mut b1 = vec![0.0; 9];
            for i in 0..3 {
                for j in 0..3 {
                    b1[i * 3 + j] = rot.m[p[i]][p[j]];
                }
            }
            blocks.push(b1);
        }
        for l in 2..=l_max {
            let b = ir_band(l, &blocks[1], &blocks[l - 1]);
            blocks.push(b);
        }
        // Conjugate by diag((-1)^m) for the Condon-Shortley phase.
        for (l, b) in blocks.iter_mut().enumerate() {
            let n = 2 * l + 1;
            for i in 0..n {
                for j in 0..n {
                    if (i + j) % 2 == 1 {
                        b[i * n + j] = -b[i * n + j];
                    }
                }
            }
        }
        Ok(Self { l_max, blocks })
    }

    /// Maximum degree.
    #[must_use]
    pub fn l_max(&self) -> usize {
        self.l_max
    }

    /// The `(2l + 1) x (2l + 1)` block of band `l` (row-major, `m = -l..=l`).
    ///
    /// # Panics
    /// If `l > L`.
    #[must_use]
    pub fn band(&self, l: usize) -> &[f64] {
        &self.blocks[l]
    }

    /// Coefficients of `g(w) = f(R^T w)`.
    ///
    /// # Errors
    /// [`SphereError::Mismatch`] when `f` has a higher degree than this rotation.
    pub fn apply(&self, f: &ShCoeffs) -> Result<ShCoeffs> {
        if f.l_max() > self.l_max {
            return Err(SphereError::Mismatch(format!(
                "coefficients of degree {} rotated with matrices of degree {}",
                f.l_max(),
                self.l_max
            )));
        }
        let ch = f.channels();
        let mut out = ShCoeffs::zeros(f.l_max(), ch)?;
        let src = f.data();
        let dst = out.data_mut();
        for l in 0..=f.l_max() {
            let n = 2 * l + 1;
            let off = l * l;
            let b = &self.blocks[l];
            for i in 0..n {
                for c in 0..ch {
                    let mut acc = 0.0;
                    for j in 0..n {
                        acc += b[i * n + j] * src[(off + j) * ch + c];
                    }
                    dst[(off + i) * ch + c] = acc;
                }
            }
        }
        Ok(out)
    }
}

/// One Ivanic-Ruedenberg step: band `l` from band 1 and band `l - 1`.
fn ir_band(l: usize, r1: &[f64], prev: &[f64]) -> Vec<f64> {
    let li = l as i64;
    let n = 2 * l + 1;
    let np = 2 * l - 1;
    let r1 = |i: i64, j: i64| r1[((i + 1) * 3 + (j + 1)) as usize];
    let rp = |a: i64, b: i64| prev[((a + li - 1) * np as i64 + (b + li - 1)) as usize];
    let p = |i: i64, a: i64, b: i64| -> f64 {
        if b == li {
            r1(i, 1) * rp(a, li - 1) - r1(i, -1) * rp(a, -li + 1)
        } else if b == -li {
            r1(i, 1) * rp(a, -li + 1) + r1(i, -1) * rp(a, li - 1)
        } else {
            r1(i, 0) * rp(a, b)
        }
    };
    let mut out = vec![0.0; n * n];
    for m in -li..=li {
        for nn in -li..=li {
            let d = if m == 0 { 1.0 } else { 0.0 };
            let denom = if nn.abs() < li {
                ((li + nn) * (li - nn)) as f64
            } else {
                (2 * li * (2 * li - 1)) as f64
            };
            let am = m.abs();
            let u = (((li + m) * (li - m)) as f64 / denom).sqrt();
            let v = 0.5
                * ((1.0 + d) * ((li + am - 1) * (li + am)) as f64 / denom).sqrt()
                * (1.0 - 2.0 * d);
            let w = -0.5 * (((li - am - 1) * (li - am)) as f64 / denom).sqrt() * (1.0 - d);
            let mut val = 0.0;
            if u != 0.0 {
                val += u * p(0, m, nn);
            }
            if v != 0.0 {
                let vv = match m.cmp(&0) {
                    std::cmp::Ordering::Equal => p(1, 1, nn) + p(-1, -1, nn),
                    std::cmp::Ordering::Greater => {
                        let d1: f64 = if m == 1 { 1.0 } else { 0.0 };
                        p(1, m - 1, nn) * (1.0 + d1).sqrt() - p(-1, -m + 1, nn) * (1.0 - d1)
                    }
                    std::cmp::Ordering::Less => {
                        let d1: f64 = if m == -1 { 1.0 } else { 0.0 };
                        p(1, m + 1, nn) * (1.0 - d1) + p(-1, -m - 1, nn) * (1.0 + d1).sqrt()
                    }
                };
                val += v * vv;
            }
            if w != 0.0 {
                let ww = if m > 0 {
                    p(1, m + 1, nn) + p(-1, -m - 1, nn)
                } else {
                    p(1, m - 1, nn) - p(-1, -m + 1, nn)
                };
                val += w * ww;
            }
            out[((m + li) * n as i64 + (nn + li)) as usize] = val;
        }
    }
    out
}
