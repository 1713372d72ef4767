//! The error type of `ifd-render`.

/// Everything that can go wrong in `ifd-render`.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RenderError {
    /// A parameter outside its valid range (camera, sizes, scene names).
    #[error("invalid {name} {value}: {reason}")]
    Parameter {
        /// The option or parameter.
        name: &'static str,
        /// Its value, formatted.
        value: String,
        /// Why.
        reason: String,
    },
    /// The camera sees no object.
    #[error("the camera sees no object: {0}")]
    NothingVisible(String),
    /// An error of the shading library.
    #[error(transparent)]
    Shade(#[from] ifd_shade::ShadeError),
    /// An error of the spherical core.
    #[error(transparent)]
    Sphere(#[from] ifd_sphere::SphereError),
    /// An image error.
    #[error(transparent)]
    Image(#[from] ifd_image::ImageError),
}

/// Result alias of this crate.
pub type Result<T, E = RenderError> = std::result::Result<T, E>;
