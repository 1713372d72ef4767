//! The spherical half of ifd: real spherical harmonics, fast SH transforms of
//! environment maps, rotated zonal harmonics (RZH) and zonal harmonic
//! factorisation (ZHF) rotation, isotropic spherical decomposition (ISD) with
//! arbitrary mother functions, and filtering of spherical signals with it.
//!
//! ```
//! use ifd_sphere::{EquirectTransform, Rotation, ShRotation};
//! use ifd_sphere::zhf::{Chooser, DirectionSet, RzhBasis, Sharing};
//! // A 64x32 map, projected to degree 4 with the FFT + Legendre transform.
//! let t = EquirectTransform::new(4, 64, 32)?;
//! let img = ifd_image::Image::from_vec(64, 32, 1, (0..64 * 32).map(|i| (i % 7) as f32).collect())?;
//! let c = t.analyze(&img, ifd_sphere::Negatives::Clamp)?.coeffs;
//! // Rotate it by ZHF (Eq. 10) and by the Ivanic-Ruedenberg reference.
//! let r = Rotation::from_zyz(0.1, 0.7, -0.3);
//! let basis = RzhBasis::new(DirectionSet::new(4, Sharing::Shared, Chooser::Fibonacci)?)?;
//! let a = basis.rotate(&c, &r)?;
//! let b = ShRotation::new(&r, 4)?.apply(&c)?;
//! assert!(a.data().iter().zip(b.data()).all(|(x, y)| (x - y).abs() < 1e-10));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # Conventions (tests and tools rely on them)
//! - **Real SH**: the graphics convention of Sloan's "Stupid SH tricks":
//!   `y_1^-1 = -0.488603 y`, `y_1^0 = 0.488603 z`, `y_1^1 = -0.488603 x`,
//!   orthonormal, flat index `l (l + 1) + m`. This equals pyshtools
//!   `spharm_lm(l, m, theta, phi, normalization='ortho', kind='real', csphase=-1)`.
//!   To ducc0/healpy complex `alm` (`m >= 0`): `a_l0 = c_l0`,
//!   `a_lm = (c_lm - i c_l,-m) / sqrt 2`; back: `c_lm = sqrt 2 Re a_lm`,
//!   `c_l,-m = -sqrt 2 Im a_lm`.
//! - **Directions**: `w = (sin t cos p, sin t sin p, cos t)`, `z` up.
//!   Equirectangular maps: column `u` gives `p = 2 pi (u + 0.5) / W`, row `v`
//!   (row 0 at the top) gives `t = pi (v + 0.5) / H`; maps must be 2:1.
//! - **Rotations**: `--zyz a,b,c` means `R = Rz(a) Ry(b) Rz(c)` (radians);
//!   rotating a function means `g(w) = f(R^T w)` (same as
//!   `ducc0.sht.rotate_alm(alm, lmax, psi=c, theta=b, phi=a)`).
//! - **RZH**: `c_l = M_l Lambda_l` with `(M_l)_{mj} = pi_l y_l^m(z_l^j)`,
//!   `pi_l = sqrt(4 pi / (2l + 1))` (ISD Eq. 10).
//! - **Filtering**: `fhat(R) = int k(R^-1 w) f(w) dw` (ISD Eq. 1).
//!
//! # Modules
//! - [`sh`]: evaluation (stable recurrences, `f64` and an `f32` fast path).
//! - [`transform`]: equirectangular analysis/synthesis (FFT + Legendre),
//!   cubemap and sample projection.
//! - [`rotation`]: rotations and the Ivanic-Ruedenberg reference SH rotation.
//! - [`zhf`]: direction sets, `M_l`, ZHF/ZHE, ZHF rotation (Eq. 10, 11).
//! - [`tabulated`]: pre-tabulated band expansions for the signal-tailored
//!   rotation (ZHF Eq. 11 with lookups).
//! - [`zhf_plane`]: `l + 1` in-plane lobes per band for functions even in
//!   `y` (isotropic BRDF slices).
//! - [`profile`]: mother functions, `beta_{l l'}`, the general `M` (Eq. 15-19).
//! - [`kernel`]: closed-form spherical filters and their projection.
//! - [`filter`]: prefiltering (Eq. 13) and evaluation of `fhat(R)` (Eq. 6, 14).
//! - [`coeffs`]: [`ShCoeffs`] and their `.npy` format.

mod error;

pub mod coeffs;
pub mod filter;
pub mod kernel;
pub mod profile;
pub mod rotation;
pub mod sh;
pub mod tabulated;
pub mod transform;
pub mod zhf;
pub mod zhf_plane;

pub use crate::coeffs::ShCoeffs;
pub use crate::error::{MAX_DEGREE, Result, SphereError};
pub use crate::rotation::{Rotation, ShRotation};
pub use crate::sh::ShEvaluator;
pub use crate::transform::{Analysis, EquirectTransform, Negatives};
