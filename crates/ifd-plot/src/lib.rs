//! Plots that explain ifd's results, kept out of the algorithm crates: they
//! depend on `ifd-planar` and `ifd-sphere`, never the other way round.
//!
//! - [`decomposition_plot`]: a planar fit (`ifd decompose --plot`): kernel,
//!   sum of Gaussians, error and the weights per level, titled, with axes in
//!   pixels and colour bars.
//! - [`log_line_plot`]: curves on a logarithmic `y` axis (convergence and
//!   timing studies, `ifd envmap`, `ifd-render`).
//! - [`diverging`], [`sequential`]: the colour maps of those plots;
//!   [`PLOT_SIZE`] and the margins ([`PLOT_LEFT`], [`PLOT_RIGHT`],
//!   [`PLOT_TOP`], [`PLOT_BOTTOM`]) for plots drawn in the same style.
//! - [`draw`]: the primitives (lines, a 5x7 bitmap font), the one public
//!   module, for plots made elsewhere (`ifd-paper`'s).
//!
//! ```
//! let s = ifd_plot::Series { name: "error".into(), colour: [0.9, 0.1, 0.1], dotted: false,
//!                            points: vec![(1.0, 1.0), (2.0, 0.1), (4.0, 0.01)] };
//! let img = ifd_plot::log_line_plot(&[s], "L", "relative error")?;
//! assert_eq!(img.channels(), 3);
//! # Ok::<(), ifd_image::ImageError>(())
//! ```

mod decomposition;
pub mod draw;
mod lines;

pub use decomposition::{decomposition_plot, diverging, sequential};
pub use lines::{
    BOTTOM as PLOT_BOTTOM, LEFT as PLOT_LEFT, PLOT_SIZE, RIGHT as PLOT_RIGHT, Series,
    TOP as PLOT_TOP, log_line_plot, profile_colour,
};
