//! Errors of the IBL baker.

use std::path::PathBuf;

/// Everything that can go wrong while baking.
#[derive(Debug, thiserror::Error)]
pub enum IblError {
    /// An error of the SH layer (bad maps, NaN samples, degrees).
    #[error(transparent)]
    Sphere(#[from] ifd_sphere::SphereError),
    /// An image could not be allocated, read or written.
    #[error(transparent)]
    Image(#[from] ifd_image::ImageError),
    /// A parameter is out of range; names the parameter and the reason.
    #[error("{what}: {why}")]
    Param {
        /// The parameter (as the CLI spells it).
        what: &'static str,
        /// What is wrong with it.
        why: String,
    },
    /// An output file could not be written.
    #[error("{path}: {reason}")]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        reason: String,
    },
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, IblError>;

pub(crate) fn param(what: &'static str, why: impl Into<String>) -> IblError {
    IblError::Param {
        what,
        why: why.into(),
    }
}
