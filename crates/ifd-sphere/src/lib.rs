//! The spherical half of ifd: real spherical harmonics, fast SH transforms of
//! environment maps, rotated zonal harmonics (RZH) and zonal harmonic
//! factorisation (ZHF) rotation, isotropic spherical decomposition (ISD) with
//! arbitrary mother functions, and filtering of spherical signals with it.
//!
//! ```
//! use ifd_sphere::{
//!     Chooser, DirectionSet, EquirectTransform, Rotation, RzhBasis, ShRotation, Sharing,
//! };
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
//! # The API, by topic (the modules are private; everything is here)
//! - **SH evaluation** (`sh.rs`, stable recurrences, `f64` and an `f32`
//!   fast path): [`ShEvaluator`], [`eval_sh`], [`direction`], [`pi_l`],
//!   [`sh_count`], [`sh_index`]; Legendre polynomials and quadrature
//!   (`legendre.rs`): [`legendre_p`], [`legendre_all`],
//!   [`gauss_legendre`]; coefficients [`ShCoeffs`] and their `.npy`
//!   format ([`read_npy_f64`]; arrays are written with
//!   `ifd_image::write_npy_f64`).
//! - **Map transforms** (`transform/`): [`EquirectTransform`] (FFT +
//!   Legendre analysis at pixel centres or texel-exact, synthesis),
//!   [`analyze_map`] by shape, [`analyze_cubemap`], [`project_samples`],
//!   cube geometry ([`cube_face_direction`], [`cube_texel`]), resampling
//!   ([`bicubic_taps`], [`downsample_equirect`]).
//! - **Rotations** (`rotation.rs`): [`Rotation`] and the Ivanic-Ruedenberg
//!   reference [`ShRotation`].
//! - **RZH and ZHF** (`zhf/`): direction sets ([`DirectionSet`], [`Sharing`],
//!   [`Chooser`], [`fibonacci`]), the basis [`RzhBasis`] with ZHF/ZHE and ZHF
//!   rotation (Eq. 10, 11), [`RzhCoeffs`], [`condition_number`]; the
//!   generator [`SplitMix64`] (`rng.rs`); tabulated band expansions for the
//!   signal-tailored rotation, [`BandTables`] (`tabulated.rs`); `l + 1`
//!   in-plane lobes per band for functions even in `y`, [`PlaneRzhBasis`]
//!   (`zhf_plane.rs`).
//! - **ISD** (`profile.rs`): mother functions [`Profile`], `beta_{l l'}` and
//!   the general `M` ([`IsdBasis`], [`isd_matrix`], Eq. 15-19).
//! - **Spherical filters** (`kernel.rs`): closed forms [`Kernel`] and their
//!   projection ([`project_function`], [`project_band`], [`vmf_factors`]).
//! - **Filtering** (`filter.rs`): [`Decomposition`], prefiltering (Eq. 13)
//!   into [`Prefiltered`] and evaluation of `fhat(R)` (Eq. 6, 14),
//!   [`MapLayout`], [`meridian_frame`].

mod coeffs;
mod error;
mod filter;
mod kernel;
mod legendre;
mod profile;
mod rng;
mod rotation;
mod sh;
mod tabulated;
mod transform;
#[cfg(test)]
mod vector_tests;
mod zhf;
mod zhf_plane;

pub use crate::coeffs::{ShCoeffs, read_npy_f64};
pub use crate::error::{MAX_DEGREE, Result, SphereError};
pub use crate::filter::{Decomposition, MapLayout, Prefiltered, meridian_frame};
pub use crate::kernel::{Kernel, project_band, project_function, vmf_factors};
pub use crate::legendre::{gauss_legendre, legendre_all, legendre_p};
pub use crate::profile::{IsdBasis, MAX_ISD_DEGREE, Profile, check_isd_degree, isd_matrix};
pub use crate::rng::SplitMix64;
pub use crate::rotation::{Rotation, ShRotation};
pub use crate::sh::{ShEvaluator, direction, eval_sh, pi_l, sh_count, sh_index};
pub use crate::tabulated::BandTables;
pub use crate::transform::{
    Analysis, EquirectTransform, Negatives, Projection, analyze_cubemap, analyze_equirect,
    analyze_equirect_box, analyze_map, bicubic_taps, cube_face_direction, cube_texel,
    downsample_equirect, project_samples,
};
pub use crate::zhf::{
    Chooser, DEFAULT_COND_LIMIT, DirectionSet, RzhBasis, RzhCoeffs, Sharing, check_direction,
    condition_number, fibonacci,
};
pub use crate::zhf_plane::{
    PlaneRzhBasis, default_angles, odd_part_norm, plane_count, plane_index,
};
