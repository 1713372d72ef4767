//! One displaced isotropic Gaussian of a decomposition: [`Term`], the atom
//! both a decomposition and the dictionary it is fitted from are made of.

use serde::{Deserialize, Serialize};

/// One displaced isotropic Gaussian of a decomposition: `weight * g_sigma(d - (x, y))`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Term {
    /// The weight `lambda_l^m`.
    pub weight: f64,
    /// Displacement of the atom's centre from the kernel centre along `x`
    /// (column, right), in pixels.
    pub x: f64,
    /// Displacement of the atom's centre from the kernel centre along `y`
    /// (row, down), in pixels.
    pub y: f64,
    /// Standard deviation, in pixels, of the normalised Gaussian
    /// `g_sigma(d) = exp(-|d|^2 / (2 sigma^2)) / (2 pi sigma^2)`.
    pub sigma: f64,
}
