//! `ifd`: isotropic filter decomposition. Apply huge, anisotropic, rotated,
//! scaled, spatially varying filters to images at the cost of a few lookups
//! per pixel (Soler, Bagher and Nowrouzezahrai, INRIA RR-8349, 2013), and
//! filter spherical signals with isotropic spherical decompositions.
//!
//! This facade re-exports the CPU libraries under short names:
//!
//! - [`image`] (`ifd-image`): f32 image buffers, file I/O, PSNR/SSIM;
//! - [`planar`] (`ifd-planar`): decompositions, scale stacks, filtering;
//! - [`smooth`] (`ifd-smooth`): the Hessian and anisotropic smoothing;
//! - [`sphere`] (`ifd-sphere`): spherical harmonics, rotation, ISD;
//! - [`shade`] (`ifd-shade`): BRDFs as spherical filters, lobe-weight tables, Eq. 22;
//! - [`render`] (`ifd-render`): the CPU renderer, its oracle and Monte Carlo;
//! - [`ibl`] (`ifd-ibl`): the IBL baker (prefiltered GGX mips, irradiance,
//!   SH, KTX2, the DFG table).
//!
//! GPU evaluation lives in the `ifd-gpu` crate, which is not re-exported
//! here, so that depending on `ifd` does not pull in wgpu.
//!
//! A filter made of two displaced isotropic Gaussians (a short horizontal
//! blur), applied rotated by 30 degrees to a bundled image:
//!
//! ```
//! use ifd::planar::{
//!     Border, Decomposition, Field, Filter, StackOptions, Term, stack_for_decomposition,
//! };
//! let d = Decomposition::from_terms(vec![
//!     Term { weight: 0.5, x: -3.0, y: 0.0, sigma: 2.0 },
//!     Term { weight: 0.5, x: 3.0, y: 0.0, sigma: 2.0 },
//! ]);
//! let img = ifd::image::read(concat!(env!("CARGO_MANIFEST_DIR"), "/testdata/camera.png"))?;
//! // Prefilter once for the scales used (here only 1), then one lookup per term.
//! let stack = stack_for_decomposition(&img, &d, 1.0, 1.0, Border::Reflect101, StackOptions::default())?;
//! let out = Filter::new(&stack, &d)?.apply(Field::Constant(30.0), Field::Constant(1.0))?;
//! assert_eq!((out.width(), out.height(), out.channels()), (512, 512, 1));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub use ifd_ibl as ibl;
pub use ifd_image as image;
pub use ifd_planar as planar;
pub use ifd_render as render;
pub use ifd_shade as shade;
pub use ifd_smooth as smooth;
pub use ifd_sphere as sphere;
