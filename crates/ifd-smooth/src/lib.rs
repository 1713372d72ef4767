//! Hessian estimation and Hessian-driven anisotropic smoothing with isotropic
//! filter decompositions (Section 5.1 and Fig. 5 of the IFD paper): the engine
//! of the brush app.
//!
//! - [`hessian`]: the Hessian `(Hxx, Hxy, Hyy)` at any scale, from the
//!   decompositions of the second-derivative-of-Gaussian filters `xx` and
//!   `xy` (`yy` is `xx` rotated by 90 degrees, as in the paper), at one point
//!   (O(s) lookups) or over a whole image.
//! - [`orientation`]: from the Hessian to the smoothing filter's orientation and
//!   aspect ratio (the mapping and its parameters).
//! - [`bank`]: decompositions of anisotropic Gaussians tabulated over aspect
//!   ratio; between entries the weights are blended linearly.
//! - [`direct`]: footprints below the stack's finest levels (`S < 2` px), as
//!   tables of pixel-integrated anisotropic Gaussians applied tap by tap.
//! - [`smooth`]: the [`Smoother`], which owns one prefiltered scale stack and
//!   smooths a whole image or a dab, in the paper's mode (one filter per dab,
//!   from the Hessian at the dab's centre) or per pixel.
//! - [`tiled`]: images larger than memory, smoothed tile by tile with the
//!   halo each stage of the chain needs (the result of smoothing them whole).
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

pub mod bank;
pub mod direct;
pub mod error;
pub mod hessian;
pub mod orientation;
pub mod smooth;
pub mod tiled;

pub use bank::{AspectBank, BankOptions};
pub use error::SmoothError;
pub use hessian::{HessianBank, hessian_image};
pub use orientation::{AnisoParams, Orientation};
pub use smooth::{
    Dab, DabRegion, Mode, RegionRefresh, SmoothOptions, Smoother, smoother_stack_options,
};
