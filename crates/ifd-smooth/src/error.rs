//! Errors of Hessian estimation and smoothing.

/// Everything that can go wrong estimating Hessians or smoothing.
#[derive(Debug, thiserror::Error)]
pub enum SmoothError {
    /// A parameter outside its supported range.
    #[error("{name} = {} is outside the supported range {range}", ifd_image::short_number(*value))]
    OutOfRange {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: f64,
        /// The supported range, in words.
        range: String,
    },
    /// The image has NaN or infinite values, or a wrong size.
    #[error("{0}")]
    BadImage(String),
    /// Fitting a decomposition failed.
    #[error("decomposing {spec}: {source}")]
    Decompose {
        /// The filter.
        spec: String,
        /// Why.
        source: ifd_planar::DecomposeError,
    },
    /// A kernel spec could not be built.
    #[error(transparent)]
    Kernel(#[from] ifd_planar::KernelError),
    /// Prefiltering or filtering failed.
    #[error(transparent)]
    Filter(#[from] ifd_planar::FilterError),
    /// Image errors.
    #[error(transparent)]
    Image(#[from] ifd_image::ImageError),
}

pub(crate) fn check_range(
    name: &'static str,
    value: f64,
    lo: f64,
    hi: f64,
) -> Result<(), SmoothError> {
    if value.is_finite() && value >= lo && value <= hi {
        Ok(())
    } else {
        Err(SmoothError::OutOfRange {
            name,
            value,
            range: format!("[{lo}, {hi}]"),
        })
    }
}
