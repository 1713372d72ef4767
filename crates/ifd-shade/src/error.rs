//! The error type of `ifd-shade`.

use std::path::PathBuf;

/// Everything that can go wrong in `ifd-shade`. Messages name the offending
/// value or file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ShadeError {
    /// A BRDF spec that does not parse or has invalid parameters.
    #[error("BRDF spec {spec:?}: {reason}")]
    Spec {
        /// The text.
        spec: String,
        /// Why it is refused.
        reason: String,
    },
    /// A file that is malformed, truncated or does not match what it should hold.
    #[error("{path}: {reason}")]
    File {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// Objects built for different BRDFs, degrees or channel counts.
    #[error("mismatch: {0}")]
    Mismatch(String),
    /// A parameter outside its valid range.
    #[error("invalid {name} = {value}: {reason}")]
    Parameter {
        /// Parameter name.
        name: &'static str,
        /// Its value, formatted.
        value: String,
        /// Why.
        reason: String,
    },
    /// An error of the spherical core.
    #[error(transparent)]
    Sphere(#[from] ifd_sphere::SphereError),
}

/// Result alias of this crate.
pub type Result<T, E = ShadeError> = std::result::Result<T, E>;
