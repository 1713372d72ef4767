//! Shading with isotropic spherical decomposition (ISD Sec. 6.1, 7; IFD Sec.
//! 5.2): BRDF models and their cosine-weighted slices as spherical filters,
//! closed-form zonal coefficients, and view-dependent lobe-weight tables.
//!
//! ```
//! use ifd_shade::brdf::Brdf;
//! use ifd_shade::slice::project_slice;
//! // The white furnace: the slice of a white Lambertian BRDF integrates to 1,
//! // so its SH coefficient c_00 is 1 / sqrt(4 pi).
//! let b = Brdf::parse("lambert")?;
//! let c = project_slice(&b, [0.3, 0.0, 0.954], 8, None)?;
//! assert!((c.get(0, 0, 0) * (4.0 * std::f64::consts::PI).sqrt() - 1.0).abs() < 1e-12);
//! # Ok::<(), ifd_shade::ShadeError>(())
//! ```
//!
//! # Conventions
//! Local frame at a surface point: normal `+z`, tangent `+x`, bitangent `+y`;
//! `wi` towards the light, `wo` towards the viewer ([`brdf`]). SH, directions
//! and rotations are `ifd-sphere`'s.
//!
//! # Modules
//! - [`brdf`]: models, specs, slices.
//! - [`merl`]: the MERL measured-BRDF format.
//! - [`brdf_sh`]: BRDFs on the 4D SH basis, vMF filtering of noisy and
//!   sparse data (Eq. 30-32).
//! - [`zonal`]: closed-form zonal coefficients (Lambert, Phong).
//! - [`slice`](mod@slice): SH projection of slices.
//! - [`table`]: view-dependent lobe-weight tables and their file format.
//! - [`shade`]: shading by Eq. 22 (ISD and the SH reference).
//! - [`lights`]: zonal lighting: spherical light sources (Eq. 33-34) and
//!   radially symmetric light (Eq. 23), with their quadrature reference.
//! - [`radial`]: radial reflection maps for any BRDF (Eq. 23-24).
//! - [`sample`]: importance sampling of slices (Monte Carlo references).

mod error;

pub mod brdf;
pub mod brdf_sh;
pub mod lights;
pub mod merl;
pub mod radial;
pub mod sample;
pub mod shade;
pub mod slice;
pub mod table;
pub mod zonal;

pub use crate::brdf::Brdf;
pub use crate::error::{Result, ShadeError};
