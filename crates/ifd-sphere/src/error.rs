//! The error type of `ifd-sphere`.

use std::path::PathBuf;

/// Everything that can go wrong in `ifd-sphere`. Messages name the offending value.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SphereError {
    /// A degree beyond what this crate supports.
    #[error("SH degree L = {l_max} is not supported (at most {max})")]
    DegreeTooHigh {
        /// The requested degree.
        l_max: usize,
        /// The largest supported degree.
        max: usize,
    },
    /// A buffer whose length does not match the degree and channel count.
    #[error("{what}: {got} values given, {expected} expected")]
    Length {
        /// What the buffer is.
        what: &'static str,
        /// Its length.
        got: usize,
        /// The expected length.
        expected: usize,
    },
    /// An environment map that is not 2:1 (equirectangular) or is too small.
    #[error("an equirectangular map must be 2:1 (W = 2H, H >= 2); got {width}x{height}")]
    NotEquirect {
        /// Width in pixels.
        width: usize,
        /// Height in pixels.
        height: usize,
    },
    /// A cubemap whose faces are not square or not six.
    #[error(
        "a cubemap must be a 6-face cross-free strip of square faces (W = 6H); got {width}x{height}"
    )]
    NotCubemap {
        /// Width in pixels.
        width: usize,
        /// Height in pixels.
        height: usize,
    },
    /// Non-finite samples (NaN or infinity) in the input.
    #[error("{count} non-finite sample(s) in {what} (first at index {first})")]
    NonFinite {
        /// What held them.
        what: &'static str,
        /// How many.
        count: usize,
        /// Flat index of the first one.
        first: usize,
    },
    /// A direction set whose matrix `M_l` is singular or too badly conditioned.
    #[error(
        "degenerate direction set for band l = {band}: condition number of M {cond:.3e} exceeds {limit:.1e}"
    )]
    Degenerate {
        /// The band.
        band: usize,
        /// The 2-norm condition number (infinite when singular).
        cond: f64,
        /// The accepted limit.
        limit: f64,
    },
    /// A full ISD matrix `M` (Eq. 17, any profile) that is singular or too badly
    /// conditioned for its lobe directions.
    #[error(
        "ISD matrix M of degree L = {l_max} ({profile} profile) is degenerate: condition number \
         {cond:.3e} exceeds {limit:.1e} (try per-band or optimized directions, another profile \
         or a lower L)"
    )]
    IllConditioned {
        /// The degree `L`.
        l_max: usize,
        /// The profile's name.
        profile: &'static str,
        /// The 2-norm condition number of `M` (infinite when singular).
        cond: f64,
        /// The accepted limit.
        limit: f64,
    },
    /// A direction that cannot be normalised (zero, too short or too long,
    /// non-finite components) or, in a set read from a file, is not a unit vector.
    #[error(
        "direction {index} = ({}, {}, {}) {reason}",
        ifd_image::short_number(*.x),
        ifd_image::short_number(*.y),
        ifd_image::short_number(*.z)
    )]
    BadDirection {
        /// Position in the set.
        index: usize,
        /// What is wrong with it (a clause such as "is the zero vector").
        reason: &'static str,
        /// x.
        x: f64,
        /// y.
        y: f64,
        /// z.
        z: f64,
    },
    /// A parameter outside its valid range.
    #[error("invalid parameter {name} = {value}: {reason}")]
    Parameter {
        /// Parameter name.
        name: &'static str,
        /// Its value, formatted.
        value: String,
        /// Why it is invalid.
        reason: &'static str,
    },
    /// Malformed text specification (kernel spec, direction spec, ...).
    #[error("cannot parse {what}{}: {reason}",
        if text.is_empty() { String::new() } else { format!(" {text:?}") })]
    Parse {
        /// What was being parsed.
        what: &'static str,
        /// The text.
        text: String,
        /// Why.
        reason: String,
    },
    /// A dense ISD problem (matrix `M` of Eq. 17 and its SVD) too large to build.
    #[error(
        "L = {l_max} is too large for a dense ISD decomposition: M would be {n}x{n} \
         ({mib:.0} MiB) and its SVD about {gflop:.0} GFLOP; at most L = {max} is supported"
    )]
    IsdTooLarge {
        /// The requested degree.
        l_max: usize,
        /// The largest supported degree.
        max: usize,
        /// Side of `M`, `(L + 1)^2`.
        n: usize,
        /// Memory of `M` alone, MiB.
        mib: f64,
        /// Rough cost of the SVD, `~ 10 n^3` flops, in GFLOP.
        gflop: f64,
    },
    /// Two objects with incompatible degrees or channel counts.
    #[error("mismatch: {0}")]
    Mismatch(String),
    /// A file that could not be read or written.
    #[error("{path}: {reason}")]
    File {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        reason: String,
    },
    /// An error from `ifd-image`.
    #[error(transparent)]
    Image(#[from] ifd_image::ImageError),
}

/// Result alias of this crate.
pub type Result<T, E = SphereError> = std::result::Result<T, E>;

/// The largest SH degree supported by the evaluators and transforms.
///
/// The recurrences are stable far beyond it; the limit only keeps
/// `(L + 1)^2`-sized tables and `sin^m` factors (which underflow to zero, as
/// the true values do, near the poles) within sane bounds.
pub const MAX_DEGREE: usize = 1000;

pub(crate) fn check_degree(l_max: usize) -> Result<()> {
    if l_max > MAX_DEGREE {
        return Err(SphereError::DegreeTooHigh {
            l_max,
            max: MAX_DEGREE,
        });
    }
    Ok(())
}
