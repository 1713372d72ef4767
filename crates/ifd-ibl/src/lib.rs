//! Image-based lighting baker: an environment map turned into what engines
//! load, computed in frequency space (Ramamoorthi and Hanrahan's SHRM
//! convolution, `P_lm = lambda_l L_lm`) with the brightest texels summed
//! exactly, so that suns neither ring nor sparkle.
//!
//! - [`Baker`]: GGX-prefiltered radiance levels (the split-sum lobe, one
//!   roughness per mip, [`chain::RoughnessMapping`]), the irradiance map
//!   (`E / pi`, [`lobe::Lobe::Lambert`]) and SH coefficients of the source;
//! - [`ktx2`]: an RGBA16F cube-map KTX2 writer;
//! - [`dfg`]: the split-sum DFG table;
//! - [`cube`]: face order, orientation and the mapping from an
//!   equirectangular source (glTF-IBL-Sampler's).
//!
//! Formulas, conventions, the cost model and the measured accuracy:
//! `docs/ibl.md`.
//!
//! ```
//! use ifd_ibl::{Baker, BakeOptions, lobe::Lobe};
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

pub mod chain;
pub mod cube;
pub mod dfg;
mod error;
pub mod ktx2;
pub mod lobe;
mod prefilter;

pub use crate::error::{IblError, Result};
pub use crate::prefilter::{BakeOptions, Baker, LevelStats};
