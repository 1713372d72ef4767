//! Plots that explain ifd's results, kept out of the algorithm crates: they
//! depend on `ifd-planar` and `ifd-sphere`, never the other way round.
//!
//! - [`decomposition_plot`]: a planar fit (`ifd decompose --plot`): kernel,
//!   sum of Gaussians, error and the weights per level, titled, with axes in
//!   pixels and colour bars.
//! - [`log_line_plot`]: curves on a logarithmic `y` axis (convergence and
//!   timing studies, `ifd envmap`, `ifd-render`).
//! - [`draw`]: the primitives (lines, a 5x7 bitmap font, colour maps).
//!
//! ```
//! let s = ifd_plot::Series { name: "error".into(), colour: [0.9, 0.1, 0.1], dotted: false,
//!                            points: vec![(1.0, 1.0), (2.0, 0.1), (4.0, 0.01)] };
//! let img = ifd_plot::log_line_plot(&[s], "L", "relative error")?;
//! assert_eq!(img.channels(), 3);
//! # Ok::<(), ifd_image::ImageError>(())
//! ```

pub mod decomposition;
pub mod draw;
pub mod lines;

pub use decomposition::decomposition_plot;
pub use lines::{PLOT_SIZE, Series, log_line_plot, profile_colour};
