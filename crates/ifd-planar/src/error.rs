//! The crate's error type for prefiltering, filtering and the references,
//! in a module of its own so that every other module (border handling, the
//! scale stack, the references, the filters) depends on it and none on
//! another for it. Fitting has its own [`crate::DecomposeError`] and kernels
//! [`crate::KernelError`], each wrapping this one where it can occur.

/// Errors of prefiltering, filtering and the brute-force references.
#[derive(Debug, thiserror::Error)]
pub enum FilterError {
    /// A zero-sized image.
    #[error("image is empty ({width}x{height} with {channels} channels)")]
    EmptyImage {
        /// Width.
        width: usize,
        /// Height.
        height: usize,
        /// Channels.
        channels: usize,
    },
    /// NaN or infinite values in an image or map.
    #[error(
        "{what} has {count} non-finite (NaN or infinite) values, first at x={x}, y={y}, channel {channel}"
    )]
    NonFinite {
        /// What holds them ("image", "angle map", ...).
        what: &'static str,
        /// How many.
        count: usize,
        /// Column of the first.
        x: usize,
        /// Row of the first.
        y: usize,
        /// Channel of the first.
        channel: usize,
    },
    /// A sigma range or stack option that makes no sense.
    #[error("invalid scale-stack range: {0}")]
    InvalidRange(String),
    /// A lookup at a sigma the stack does not cover.
    #[error("sigma {sigma} px is outside the scale stack's range [{min}, {max}] px")]
    SigmaOutOfRange {
        /// The sigma asked for.
        sigma: f64,
        /// Smallest sigma of the stack.
        min: f64,
        /// Largest sigma of the stack.
        max: f64,
    },
    /// A filter scale whose `s * sigma_t` falls outside the stack.
    #[error(
        "scale {scale}{location} needs sigma {needed} px (term sigma {term_sigma} px), outside the scale stack's range [{min}, {max}] px"
    )]
    ScaleOutOfRange {
        /// The offending scale.
        scale: f64,
        /// `" at pixel (x, y)"` for a map value, empty for a constant.
        location: String,
        /// The term's sigma.
        term_sigma: f64,
        /// `scale * term_sigma`.
        needed: f64,
        /// Smallest sigma of the stack.
        min: f64,
        /// Largest sigma of the stack.
        max: f64,
    },
    /// A per-pixel map of the wrong size.
    #[error("{name} map has {len} values, expected {width}x{height} = {expected}")]
    MapSize {
        /// "angle" or "scale".
        name: &'static str,
        /// Values given.
        len: usize,
        /// Image width.
        width: usize,
        /// Image height.
        height: usize,
        /// `width * height`.
        expected: usize,
    },
    /// An invalid angle or scale value.
    #[error("invalid {name} {value}{location}: {why}")]
    InvalidValue {
        /// "angle" or "scale".
        name: &'static str,
        /// The value.
        value: f32,
        /// `" at pixel (x, y)"` for a map value, empty for a constant.
        location: String,
        /// Why it is invalid.
        why: &'static str,
    },
    /// An unknown border mode name.
    #[error(
        "unknown border mode {0:?} (expected reflect101, constant, constant:VALUE, replicate or wrap)"
    )]
    InvalidBorder(String),
    /// A decomposition term that cannot be evaluated.
    #[error("decomposition term {index} is invalid: {why}")]
    InvalidTerm {
        /// Index of the term.
        index: usize,
        /// Why.
        why: String,
    },
    /// Mismatched shapes or lengths (kernels, buffers).
    #[error("{0}")]
    Shape(String),
    /// Another parameter outside its valid range.
    #[error("{0}")]
    InvalidParameter(String),
    /// The computation would need too much memory.
    #[error("too large: {0}")]
    TooLarge(String),
    /// Reading or writing the pixels of a tile failed (tiled filtering: the
    /// message names the file).
    #[error("{0}")]
    Io(String),
}
