//! Planar isotropic filter decomposition (IFD), after Soler, Bagher and
//! Nowrouzezahrai, *Accurate and Efficient Filtering using Anisotropic Filter
//! Decomposition* (INRIA RR-8349, 2013), Sections 3 and 4.1.
//!
//! A 2D filter `k` is decomposed once into a sparse sum of displaced isotropic
//! Gaussians ([`Decomposition`]); the image is prefiltered once with every
//! isotropic Gaussian it needs (a scale stack, by FFT); then any rotated,
//! scaled copy of `k` is applied at any pixel with one lookup per term.
//!
//! # Conventions
//! - Image axes: `x` = column (right), `y` = row (down); pixel centres at
//!   integer coordinates.
//! - Filtering is **correlation**, as in `cv2.filter2D`:
//!   `out(p) = sum_q k(q - p) f(q)`.
//! - Angles are in degrees, counter-clockwise as seen on screen (the
//!   `cv2.getRotationMatrix2D` convention). In `(x right, y down)` coordinates
//!   the rotation is `R_theta = [[cos, sin], [-sin, cos]]`.
//! - A filter rotated by `theta` and scaled by `s` is
//!   `k_{theta,s}(d) = k(R_{-theta} d / s) / s^2`.
//! - Atoms are normalised Gaussians
//!   `g_sigma(d) = exp(-|d|^2 / (2 sigma^2)) / (2 pi sigma^2)` with `sigma` in
//!   pixels. With `k(d) = sum_t w_t g_{sigma_t}(d - c_t)` the filtered image is
//!   `out(p) = sum_t w_t fhat_{s sigma_t}(p + s R_theta c_t)` where
//!   `fhat_sigma = f (*) g_sigma` is one level of the scale stack.
//! - Default border: reflect-101 (OpenCV's `BORDER_DEFAULT`, scipy's
//!   `'mirror'`); also constant, replicate and wrap.

pub mod accuracy;
pub mod decomposition;
pub mod dictionary;
pub mod fit;
pub mod kernel;
pub mod prepared;
pub mod sparsa;

pub mod border;
pub mod error;
pub mod field;
pub mod filter;
pub mod pipeline;
pub mod reference;
pub mod stack;
pub mod tiled;

pub use accuracy::{EvalPlan, PlanOptions};
pub use decomposition::{Decomposition, FitReport, Term};
pub use fit::{DecomposeError, DecomposeOptions, decompose};
pub use kernel::{Kernel, KernelError, KernelSpec};
pub use prepared::{Prepare, PreparedDecomposition};

pub use border::Border;
pub use error::FilterError;
pub use field::{CheckField, CheckedField, Field, FieldKind};
pub use filter::{
    DIRECT_SIGMA, Filter, Rotation, ScaledFilter, Taps, stack_for_decomposition,
    stack_plan_for_decomposition,
};
pub use stack::gather::vector_kernels;
pub use stack::refresh::{FixedTap, PixelRect, RefreshReport};
pub use stack::{
    Interpolation, LevelLayout, LevelLocator, ScaleStack, StackLayout, StackOptions, StackPlan,
};
