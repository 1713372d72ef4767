//! f32 image buffers, file I/O and image-quality metrics for ifd.
//!
//! - [`Image`]: interleaved `f32` samples, `H x W x C`, `x` = column, `y` = row;
//!   [`ImageView`] borrows samples in the same layout (NumPy arrays, tiles).
//! - [`read_image`] / [`write_image`]: PNG, JPEG, TIFF (8/16 bit), OpenEXR
//!   (DWAB included), Radiance HDR and NumPy `.npy`, chosen by extension;
//!   atomic writes; clear errors naming the file.
//! - [`compare`], [`psnr`] and [`Metrics`] (`metrics.rs`): PSNR and SSIM
//!   defined exactly as scikit-image defines them.
//! - What every ifd crate shares beyond images: the memory budget of large
//!   work ([`MemoryBudget`], [`physical_memory`]), atomic output files
//!   ([`atomic_write`]), and how messages print numbers and sizes
//!   ([`short_number`], [`fmt_bytes`]).
//!
//! ```
//! use ifd_image::{compare, read};
//! let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../testdata/camera.png");
//! let a = read(path)?;
//! let m = compare(&a, &a, 1.0)?;
//! assert_eq!(m.overall.max_abs, 0.0);
//! # Ok::<(), ifd_image::ImageError>(())
//! ```

mod budget;
mod error;
mod files;
mod image;
mod io;
mod messages;
mod metrics;
mod npy;
mod npy_stream;

pub use crate::budget::{MemoryBudget, physical_memory};
pub use crate::error::ImageError;
pub use crate::files::{atomic_write, output_folder_problem, remove_pending_outputs};
pub use crate::image::{Image, ImageView};
pub use crate::io::{
    BitDepth, FileFormat, LoadedImage, NonFinitePolicy, ReadOptions, WriteOptions, WriteReport,
    linear_to_srgb, read, read_image, read_image_bytes, srgb_to_linear, write, write_image,
};
pub use crate::messages::{fmt_bytes, short_number};
pub use crate::metrics::{
    Comparison, Metrics, SSIM_SIGMA, SSIM_TRUNCATE, compare, crop_border, default_data_range, psnr,
    psnr_from_mse, ssim_radius,
};
pub use crate::npy::{NpyArray, read_npy_array, write_npy_f64};
pub use crate::npy_stream::{NpyReader, NpyWriter};
