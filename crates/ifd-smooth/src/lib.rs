//! Hessian estimation and Hessian-driven anisotropic smoothing with isotropic
//! filter decompositions (Section 5.1 and Fig. 5 of the IFD paper): the engine
//! of the brush app.
//!
//! The modules are private; the API is re-exported here, by topic:
//! - **Hessian** (`hessian.rs`): the Hessian `(Hxx, Hxy, Hyy)` at any
//!   scale, from the decompositions of the second-derivative-of-Gaussian
//!   filters `xx` and `xy` (`yy` is `xx` rotated by 90 degrees, as in the
//!   paper), at one point (O(s) lookups) or over a whole image:
//!   [`HessianBank`], [`HessianFilters`], [`hessian_image`],
//!   [`hessian_stack_options`], [`check_sigma`], [`HESSIAN_SIGMA0`],
//!   [`HESSIAN_SIGMA_RANGE`].
//! - **Orientation** (`orientation.rs`): from the Hessian to the smoothing
//!   filter's orientation and aspect ratio: [`Orientation`], [`AnisoParams`],
//!   [`tensor`].
//! - **Aspect bank** (`bank.rs`): decompositions of anisotropic Gaussians
//!   tabulated over aspect ratio, blended linearly between entries:
//!   [`AspectBank`], [`BankOptions`], [`BANK_SAMPLING`],
//!   [`log_spaced_aspects`], [`locate_aspect`].
//! - **Direct kernels** (`direct.rs`): footprints below the stack's finest
//!   levels (`S < 2` px), tables of pixel-integrated anisotropic Gaussians
//!   applied tap by tap: [`DirectKernels`], [`Tap`], [`DIRECT_BELOW`],
//!   [`integrated_kernel`], [`cell_integral`], [`covariance`].
//! - **Per-pixel Gaussians** (`gaussians.rs`): an anisotropic Gaussian of
//!   any angle, aspect ratio and footprint at any point, from the aspect
//!   bank (or evaluated directly when small), what dabs apply per pixel
//!   (whole images, smoothed or through a sigma map, take one weighted
//!   pass per bank entry instead, the same sums): [`PixelGaussians`], [`AnisoGaussian`],
//!   [`BankLookups`], [`SmallFootprints`], [`SAMPLED_BELOW`],
//!   [`SAMPLED_MINOR_BELOW`].
//! - **Sigma map** (`sigma_map.rs`): a normalised anisotropic Gaussian per
//!   pixel from an `H x W x 3` map (major sigma, minor sigma, angle), `ifd
//!   filter --kernel gauss --sigma-map`: [`filter_sigma_map`],
//!   [`sigma_map_gaussians`], [`SIGMA_MAP_SAMPLING`],
//!   [`SIGMA_MAP_MAX_SIGMA`], [`SIGMA_MAP_CHANNELS`].
//! - **Smoothing** (`smooth/`): the [`Smoother`], which owns one prefiltered
//!   scale stack and smooths a whole image or a [`Dab`], in the paper's mode
//!   (one filter per dab, from the Hessian at the dab's centre) or per pixel
//!   ([`Mode`], [`SmoothOptions`], [`SCALE_RANGE`], [`smoother_stack_options`]),
//!   refreshed for a changed rectangle ([`RegionRefresh`]); the dab grid
//!   ([`dab_grid_corners`], [`anchored_dab_grid_corners`],
//!   [`nearest_pixel`], [`DabRegion`]).
//! - **Tiles** (`tiled.rs`): images larger than memory, smoothed tile by tile
//!   with the halo each stage of the chain needs (the result of smoothing
//!   them whole): [`smooth_tiled`], [`SmoothTiles`], [`Tile`],
//!   [`smooth_halo`], [`smoother_bytes`].
//! - Errors: [`SmoothError`].
//!
//! Conventions are those of `ifd_planar`: `x` = column, `y` = row (down),
//! angles in degrees counter-clockwise on screen, filtering is correlation.
//!
//! ```no_run
//! use ifd_smooth::{Smoother, SmoothOptions, Mode};
//! let img = ifd_image::read("testdata/camera.png")?;
//! let smoother = Smoother::new(&img, &SmoothOptions { scale: 6.0, ..SmoothOptions::default() })?;
//! let out = smoother.smooth_image(Mode::PerPixel)?;
//! ifd_image::write("smoothed.png", &out)?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod bank;
mod direct;
mod error;
mod gaussians;
mod hessian;
mod orientation;
mod sigma_map;
mod smooth;
mod tiled;

pub use bank::{AspectBank, BANK_SAMPLING, BankOptions, locate_aspect, log_spaced_aspects};
pub use direct::{DIRECT_BELOW, DirectKernels, Tap, cell_integral, covariance, integrated_kernel};
pub use error::SmoothError;
pub use gaussians::{
    AnisoGaussian, BankLookups, PixelGaussians, SAMPLED_BELOW, SAMPLED_MINOR_BELOW, SmallFootprints,
};
pub use hessian::{
    HESSIAN_SIGMA_RANGE, HESSIAN_SIGMA0, HessianBank, HessianFilters, check_sigma, hessian_image,
    hessian_stack_options,
};
pub use orientation::{AnisoParams, Orientation, tensor};
pub use sigma_map::{
    SIGMA_MAP_CHANNELS, SIGMA_MAP_MAX_SIGMA, SIGMA_MAP_SAMPLING, filter_sigma_map,
    sigma_map_gaussians,
};
pub use smooth::{
    Dab, DabRegion, Mode, RegionRefresh, SCALE_RANGE, SmoothOptions, Smoother,
    anchored_dab_grid_corners, dab_grid_corners, nearest_pixel, smoother_stack_options,
};
pub use tiled::{SmoothTiles, Tile, smooth_halo, smooth_tiled, smoother_bytes};
