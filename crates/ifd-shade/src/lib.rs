//! Shading with isotropic spherical decomposition (ISD Sec. 6.1, 7; IFD Sec.
//! 5.2): BRDF models and their cosine-weighted slices as spherical filters,
//! closed-form zonal coefficients, and view-dependent lobe-weight tables.
//!
//! ```
//! use ifd_shade::{Brdf, project_slice};
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
//! `wi` towards the light, `wo` towards the viewer ([`Brdf`]). SH, directions
//! and rotations are `ifd-sphere`'s.
//!
//! # The API, by topic (the modules are private; everything is here)
//! - **BRDFs** (`brdf.rs`): [`Brdf`] models and specs, their slices,
//!   [`Model`], [`MAX_EXPONENT`], [`blinn_exact_norm`]; importance sampling
//!   of slices for Monte Carlo references (`sample.rs`, [`Brdf::sample`]).
//! - **glTF** (`gltf.rs`): the glTF 2.0 metallic-roughness BRDF
//!   ([`GltfMaterial`], [`GLTF_MIN_ROUGHNESS`], [`GLTF_DIELECTRIC_F0`]),
//!   whole (`gltf`) and as its three view-dependent parts (`gltf-lobes`), which
//!   one table holds and [`Material::shade_isd_parts`] shades at once.
//! - **MERL** (`merl.rs`): measured BRDFs, [`Merl`]; the file format's
//!   constants and its half/difference angles in [`merl_format`].
//! - **BRDFs on the 4D SH basis** (`brdf_sh.rs`): [`BrdfSh`], vMF filtering of
//!   noisy and sparse data (Eq. 30-32), [`BrdfSampler`].
//! - **Zonal coefficients** (`zonal.rs`): closed forms for Lambert and Phong,
//!   [`zonal_slice`], [`legendre_moments`].
//! - **Slices** (`slice.rs`): SH projection of slices, [`project_slice`],
//!   [`slice_nodes`], [`SLICE_TOLERANCE`], [`MAX_SLICE_NODES`].
//! - **Lobe tables** (`table/`): view-dependent lobe weights, [`LobeTable`],
//!   their bases ([`LobeKind`], [`LobeLayout`], [`LobeBasis`]) and file
//!   format ([`TableHeader`], [`TABLE_VERSION`], [`brdf_digest`]),
//!   [`default_theta_entries`], [`view_frame_angle`], [`MAX_TABLE_DEGREE`].
//! - **Shading** (`shade.rs`): Eq. 22, ISD and the SH reference:
//!   [`Material`], [`Scratch`]; the lighting it shades under, per band
//!   (`bands.rs`, [`Bands`]): the environment's SH coefficients
//!   (`environment/`, [`Environment`], [`Precision`]; their `f32` vector
//!   lanes in `environment/lanes.rs`) or their equirectangular band maps
//!   (`band_maps.rs`, [`BandMaps`]); the surface point's frame (`frame.rs`,
//!   [`Frame`]).
//! - **Zonal lighting** (`lights.rs`): spherical light sources (Eq. 33-34) and
//!   radially symmetric light (Eq. 23) with their quadrature reference:
//!   [`SphericalLight`], [`ZonalLighting`], [`cap_coefficients`],
//!   [`zonal_projection`], [`zonal_quadrature`].
//! - **Radial reflection maps** (`radial.rs`) for any BRDF (Eq. 23-24):
//!   [`RadialMap`], [`RadialProfile`], [`MapSize`].
//! - Errors: [`ShadeError`], [`Result`].

mod band_maps;
mod bands;
mod brdf;
mod brdf_sh;
mod environment;
mod error;
mod frame;
mod gltf;
mod lights;
mod merl;
mod radial;
mod sample;
mod shade;
mod slice;
mod table;
mod zonal;

pub use crate::band_maps::BandMaps;
pub use crate::bands::Bands;
pub use crate::brdf::{Brdf, MAX_EXPONENT, Model, blinn_exact_norm};
pub use crate::brdf_sh::{BrdfSampler, BrdfSh};
pub use crate::environment::{Environment, Precision};
pub use crate::error::{Result, ShadeError};
pub use crate::frame::Frame;
pub use crate::gltf::{
    DIELECTRIC_F0 as GLTF_DIELECTRIC_F0, GltfMaterial, MIN_ROUGHNESS as GLTF_MIN_ROUGHNESS,
};
pub use crate::lights::{
    SphericalLight, ZonalLighting, cap_coefficients, zonal_projection, zonal_quadrature,
};
pub use crate::merl::Merl;
pub use crate::radial::{MapSize, RadialMap, RadialProfile};
pub use crate::shade::{Material, Scratch};
pub use crate::slice::{MAX_SLICE_NODES, SLICE_TOLERANCE, project_slice, slice_nodes};
pub use crate::table::{
    LobeBasis, LobeKind, LobeLayout, LobeTable, MAX_TABLE_DEGREE, TableHeader,
    VERSION as TABLE_VERSION, brdf_digest, default_theta_entries, view_frame_angle,
};
pub use crate::zonal::{legendre_moments, zonal_slice};

/// The MERL measured-BRDF file format: its sizes, the bins of its
/// half/difference parameterisation and the conversion to and from
/// directions (details on [`Merl`]).
pub mod merl_format {
    pub use crate::merl::{
        FILE_BYTES, PHI_D, SAMPLES, SCALE, THETA_D, THETA_H, bin_centre, bin_index, from_half_diff,
        half_diff,
    };
}
