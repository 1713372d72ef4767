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
    /// A glTF asset (or a part of it) that cannot be read: the file, the part
    /// (`accessor 3 (POSITION of mesh 0 primitive 1)`) and why.
    #[error("{}: {part}: {reason}", file.display())]
    Asset {
        /// The file.
        file: std::path::PathBuf,
        /// The part of the file.
        part: String,
        /// Why it cannot be read.
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
