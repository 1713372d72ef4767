//! Image-based lighting baker: an environment map turned into what engines
//! load, computed in frequency space (Ramamoorthi and Hanrahan's SHRM
//! convolution, `P_lm = lambda_l L_lm`) with the brightest texels summed
//! exactly, so that suns neither ring nor sparkle.
//!
//! The modules are private; the API is re-exported here:
//! - [`Baker`] (`prefilter.rs`, with [`BakeOptions`], [`LevelStats`]):
//!   GGX-prefiltered radiance levels (the split-sum lobe, one roughness per
//!   mip, [`RoughnessMapping`] and [`check_chain`] in `chain.rs`), the
//!   irradiance map (`E / pi`, [`Lobe::Lambert`]) and SH coefficients of the
//!   source; the lobes and their band limits in `lobe.rs` ([`Lobe`],
//!   [`band_limit_of`]);
//! - an RGBA16F cube-map KTX2 writer (`ktx2.rs`: [`encode_ktx2_cube`],
//!   [`write_ktx2_cube`], [`VK_FORMAT_R16G16B16A16_SFLOAT`]);
//! - the split-sum DFG table (`dfg.rs`: [`dfg`], [`dfg_table`]);
//! - cube maps (`cube.rs`): [`CubeLevel`], face order and names
//!   ([`FACE_NAMES`], [`FACE_FILE_NAMES`]), orientation ([`world_to_ifd`],
//!   [`face_coords`], [`face_texel`]) and the mapping from an equirectangular
//!   source (glTF-IBL-Sampler's: [`equirect_coords`], [`sample_bicubic`],
//!   [`strip_to_equirect`]);
//! - errors: [`IblError`], [`Result`].
//!
//! Formulas, conventions, the cost model and the measured accuracy:
//! `docs/ibl.md`.
//!
//! ```
//! use ifd_ibl::{Baker, BakeOptions, Lobe};
//! // a sky that is brighter above than below
//! let (w, h) = (64, 32);
//! let data: Vec<f32> = (0..w * h * 3).map(|k| if k / 3 / w < h / 2 { 2.0 } else { 0.5 }).collect();
//! let env = ifd_image::Image::from_vec(w, h, 3, data)?;
//! let lobes = [Lobe::Mirror, Lobe::Ggx { alpha: 0.25 }, Lobe::Lambert];
//! let baker = Baker::new(&env, &BakeOptions::default(), &lobes)?;
//! let (irr, _) = baker.level(&Lobe::Lambert, 8)?;
//! // irradiance / pi facing up (+Y face centre) lies between the two halves
//! let up = irr.get(2, 4, 4)[0];
//! assert!(up > 0.5 && up < 2.0);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod chain;
mod cube;
mod dfg;
mod direct;
mod error;
mod ktx2;
mod lobe;
mod prefilter;

pub use crate::chain::{RoughnessMapping, check_chain};
pub use crate::cube::{
    CubeLevel, FACE_FILE_NAMES, FACE_NAMES, equirect_coords, face_coords, face_texel,
    sample_bicubic, strip_to_equirect, world_to_ifd,
};
pub use crate::dfg::{dfg, dfg_table, dfg_table_with_progress};
pub use crate::error::{IblError, Result};
pub use crate::ktx2::{VK_FORMAT_R16G16B16A16_SFLOAT, encode_ktx2_cube, write_ktx2_cube};
pub use crate::lobe::{Lobe, band_limit_of};
pub use crate::prefilter::{BakeOptions, Baker, LevelStats};
