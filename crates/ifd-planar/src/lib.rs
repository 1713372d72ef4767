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

//! # The API
//! The crate's modules are private; what a user applies is re-exported here,
//! by task:
//! - **describe a filter**: [`KernelSpec`] (parsed specs such as
//!   `gauss:s=3`, `box:w=9`, `motion:l=21,a=30`, files), [`Kernel`] (the
//!   rasterised filter), [`Sampling`] (how it was sampled);
//! - **decompose it**: [`decompose`], [`decompose_spec`] (spec to
//!   decomposition, as every front end does), [`DecomposeOptions`],
//!   [`measure`] (a decomposition's error against its kernel),
//!   [`FIT_REVISION`] (bumped when fits change, so cached fits are refitted),
//!   fits kept between runs ([`FitCache`], [`FitSource`], [`cache_root`]);
//!   the result is a [`Decomposition`] of [`Term`]s with its [`FitReport`],
//!   read and written as JSON ([`DECOMPOSITION_FORMAT`],
//!   [`DECOMPOSITION_VERSION`], [`DecompositionFileError`]);
//! - **filter an image**: [`filter_image`] with [`FilterOptions`] (the whole
//!   pipeline), or its steps: [`FilterPlan`], [`EvalPlan`]/[`PlanOptions`],
//!   [`PreparedDecomposition`] ([`Prepare`]), the scale stack
//!   ([`ScaleStack`], [`StackOptions`], [`StackPlan`], [`StackLayout`],
//!   [`LevelLayout`], [`LevelLocator`], [`Interpolation`],
//!   [`stack_for_decomposition`], [`stack_plan_for_decomposition`]) and the
//!   evaluator ([`Filter`], [`Rotation`]); per-pixel angle, scale and bank
//!   fields ([`Field`], [`FieldKind`], [`CheckField`], [`CheckedField`]);
//!   borders ([`Border`]); errors ([`FilterError`]);
//! - **dabs** (the brush): [`ScaledFilter`] and its [`Taps`], the
//!   rectangle refresh of a stack ([`PixelRect`], [`FixedTap`],
//!   [`RefreshReport`]), [`sigma_bounds`], [`level_sigmas`],
//!   [`evaluated_directly`], [`DIRECT_SIGMA`];
//! - **images larger than memory**: [`Tiling`], [`TileGrid`],
//!   [`TiledField`], [`RegionReader`], [`RegionWriter`], [`filter_tiled`],
//!   [`tile_halo`];
//! - the CPU's vector kernels: chosen once per process by `ifd_simd`
//!   ([`ifd_simd::isa`], capped by `IFD_SIMD`), the same bits on each.
//!
//! What tests, benches and studies need beyond that (the brute-force
//! reference correlation, the SpaRSA solver, the dictionary) is in
//! `internals`, hidden from these pages: not part of the API.

mod accuracy;
mod border;
mod dab;
mod decomposition;
mod dictionary;
mod error;
mod field;
mod filter;
mod filter_set;
mod fit;
mod fit_cache;
mod kernel;
mod ln;
mod pipeline;
mod prepared;
mod reference;
mod sparsa;
mod stack;
mod term;
/// Unit tests that cannot run on this machine record themselves as skipped.
#[cfg(test)]
#[path = "../../../tests/support/skip.rs"]
mod test_skip;
mod tiled;
mod trig;

pub use accuracy::{EvalPlan, PlanOptions};
pub use border::Border;
pub use dab::{Rotation, ScaledFilter};
pub use decomposition::{
    Decomposition, DecompositionFileError, FORMAT as DECOMPOSITION_FORMAT, FitReport,
    VERSION as DECOMPOSITION_VERSION,
};
pub use error::FilterError;
pub use field::{CheckField, CheckedField, Field, FieldKind, MAX_FIELD_VALUE, MIN_FIELD_SCALE};
pub use filter::Filter;
pub use filter_set::FilterSetPlan;
pub use fit::{DecomposeError, DecomposeOptions, FIT_REVISION, decompose, decompose_spec, measure};
pub use fit_cache::{FitCache, FitSource, cache_root};
pub use kernel::{Kernel, KernelError, KernelSpec, MAX_RADIUS as MAX_KERNEL_RADIUS, Sampling};
pub use pipeline::{FilterOptions, FilterPlan, filter_image};
pub use prepared::{Prepare, PreparedDecomposition};
pub use stack::for_decomposition::{
    DIRECT_SIGMA, evaluated_directly, level_sigmas, sigma_bounds, stack_for_decomposition,
    stack_plan_for_decomposition,
};
pub use stack::lookup::Taps;
pub use stack::refresh::{FixedTap, PixelRect, RefreshReport};
pub use stack::{
    Interpolation, LevelLayout, LevelLocator, ScaleStack, StackBuild, StackLayout, StackOptions,
    StackPlan,
};
pub use term::Term;
pub use tiled::{
    RegionReader, RegionWriter, TileGrid, TiledField, Tiling, filter_tiled, halo as tile_halo,
};

/// Not the API: what tests, benches, examples and studies need beyond it.
/// Paths here may change without notice.
// Hidden from the documentation (and so from the public API list,
// docs/reference/api/ifd-planar.txt): public only for the crates' own tests,
// benches and doc examples, ifd-smooth's tests (the reference correlation)
// and ifd-paper's dictionary study (the dictionary's parameters). Not a
// cargo feature: every user is a dev-dependency, and a feature would need
// ifd-planar's own tests and doc examples to turn it on for themselves.
#[doc(hidden)]
pub mod internals {
    /// The brute-force references the fast paths are tested against.
    pub mod reference {
        pub use crate::reference::{
            correlate, correlate_varying, correlate_varying_rows, sample_kernel,
        };
    }
    /// The SpaRSA solver behind [`crate::decompose`].
    pub mod sparsa {
        pub use crate::sparsa::{
            DenseOperator, LinearOperator, Sparsa, SparsaOptions, SparsaOutput, StopCriterion,
            debias, nnz, sparsa,
        };
    }
    /// Fitting's parts: the oversampled fit, the sampled DC gain, the default
    /// margin.
    pub mod fit {
        pub use crate::fit::{decompose_oversampled, default_margin, sampled_dc_gain};
    }
    /// The lookup error of a stack level against the exact convolution.
    pub mod accuracy {
        pub use crate::accuracy::{level_blend_error, lookup_error, nearest_level_error};
    }
    /// The Mixture-of-Gaussians dictionary behind [`crate::decompose`].
    pub mod dictionary {
        pub use crate::dictionary::{
            Atom, Dictionary, DictionaryError, DictionaryOptions, DictionaryParams, MAX_ATOMS,
            MAX_LEVELS, feature_width,
        };
    }
}
