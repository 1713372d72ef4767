//! Errors of image I/O and metrics.

use crate::messages::fmt_bytes;
use std::path::{Path, PathBuf};

/// Everything that can go wrong reading, writing or comparing images.
///
/// Every variant's message names the file (where there is one) and the problem.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    /// The file does not exist.
    #[error("{}: no such file", path.display())]
    NotFound {
        /// The file.
        path: PathBuf,
    },
    /// The extension names no format ifd reads or writes.
    #[error("{}: unsupported file extension {ext:?} (supported: png, jpg/jpeg, tif/tiff, exr, hdr, npy)", path.display())]
    UnsupportedExtension {
        /// The file.
        path: PathBuf,
        /// The extension found (empty when none).
        ext: String,
    },
    /// The file could not be decoded: truncated, corrupt, or a variant of the
    /// format that is not supported.
    #[error("{}: cannot decode {format} file: {reason}", path.display())]
    Decode {
        /// The file.
        path: PathBuf,
        /// The format the extension announced.
        format: &'static str,
        /// What the decoder said.
        reason: String,
    },
    /// The file could not be encoded or written.
    #[error("{}: cannot write: {reason}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// An I/O error other than a missing file.
    // `error`, not `source`: the message already says it, and as an error
    // source it would be printed twice by `{:#}` chains.
    #[error("{}: {error}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        error: std::io::Error,
    },
    /// A zero-sized image.
    #[error("{}image is empty ({width}x{height} with {channels} channels)", file_prefix(path.as_deref()))]
    Empty {
        /// The file, when the image came from one.
        path: Option<PathBuf>,
        /// Width.
        width: usize,
        /// Height.
        height: usize,
        /// Channels.
        channels: usize,
    },
    /// An image whose samples would need more memory than the budget.
    #[error("{}image would need {} of memory, more than the budget of {}", file_prefix(path.as_deref()), fmt_bytes(*needed_bytes), fmt_bytes(*budget_bytes))]
    TooLarge {
        /// The file, when the image came from one.
        path: Option<PathBuf>,
        /// Bytes the samples would need.
        needed_bytes: u64,
        /// The budget.
        budget_bytes: u64,
    },
    /// NaN or infinite samples where finite ones are required.
    #[error("{}: {count} non-finite (NaN or infinite) values, first at x={x}, y={y}, channel {channel}; pass --replace-nonfinite to replace them", path.display())]
    NonFinite {
        /// The file.
        path: PathBuf,
        /// How many samples are non-finite.
        count: usize,
        /// Column of the first.
        x: usize,
        /// Row of the first.
        y: usize,
        /// Channel of the first.
        channel: usize,
    },
    /// Mismatched shapes or lengths.
    #[error("{0}")]
    Shape(String),
    /// A parameter outside its valid range.
    #[error("{0}")]
    InvalidParameter(String),
}

impl ImageError {
    /// Names `path` in an error that was raised without knowing the file
    /// ([`ImageError::Empty`] and [`ImageError::TooLarge`] from in-memory
    /// checks such as [`crate::MemoryBudget::check`]); other errors, and
    /// errors that already name a file, are returned unchanged.
    ///
    /// ```
    /// use ifd_image::MemoryBudget;
    /// let e = MemoryBudget::bytes(10).check(20).unwrap_err();
    /// assert!(e.in_file("big.png".as_ref()).to_string().starts_with("big.png: image would need"));
    /// ```
    #[must_use]
    pub fn in_file(self, file: &Path) -> Self {
        match self {
            Self::Empty {
                path: None,
                width,
                height,
                channels,
            } => Self::Empty {
                path: Some(file.to_path_buf()),
                width,
                height,
                channels,
            },
            Self::TooLarge {
                path: None,
                needed_bytes,
                budget_bytes,
            } => Self::TooLarge {
                path: Some(file.to_path_buf()),
                needed_bytes,
                budget_bytes,
            },
            other => other,
        }
    }
}

/// `"FILE: "` for messages of errors that may or may not have a file.
fn file_prefix(path: Option<&Path>) -> String {
    path.map(|p| format!("{}: ", p.display()))
        .unwrap_or_default()
}
