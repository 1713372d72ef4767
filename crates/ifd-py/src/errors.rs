//! Rust errors as Python exceptions: `ValueError` for values, shapes and
//! parameters, `OSError` for files.

use std::fmt::Display;

use pyo3::PyErr;
use pyo3::exceptions::{PyOSError, PyValueError};

/// A `ValueError` with `error`'s message, prefixed by `what` (the argument)
/// when it is not empty.
pub(crate) fn value(what: &str, error: impl Display) -> PyErr {
    if what.is_empty() {
        PyValueError::new_err(error.to_string())
    } else {
        PyValueError::new_err(format!("{what}: {error}"))
    }
}

/// An `OSError` with `error`'s message (which names the file).
pub(crate) fn os(error: impl Display) -> PyErr {
    PyOSError::new_err(error.to_string())
}

/// A decomposition file error: `OSError` when the file could not be read or
/// written, `ValueError` when its contents are wrong.
pub(crate) fn decomposition_file(error: &ifd_planar::DecompositionFileError) -> PyErr {
    use ifd_planar::DecompositionFileError as E;
    match error {
        E::Io { .. } => os(error),
        _ => value("", error),
    }
}
