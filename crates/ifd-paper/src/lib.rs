//! Code only the reproductions of the papers' tables and figures need, kept
//! out of the product crates (the `ifd paper` commands are its front end).
//!
//! - [`convergence`]: ISD Fig. 4, the error of ISD shading and of its SH
//!   reference against the exact texel quadrature as `L` grows, as CSV and a
//!   plot.
//!
//! The product crates do not depend on this crate, nor on `ifd-plot` for a
//! study's figure.

pub mod convergence;
