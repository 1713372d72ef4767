//! numpy arrays in and out: borrowed image views, owned results.

use ifd_image::{Image, ImageView};
use ndarray::{Array, IxDyn};
use numpy::{PyArray, PyArrayDyn, PyReadonlyArray2, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::errors;

/// `(height, width, channels)` of an `(H, W)` or `(H, W, C)` array.
fn image_dims(what: &str, shape: &[usize]) -> PyResult<(usize, usize, usize)> {
    match *shape {
        [h, w] => Ok((h, w, 1)),
        [h, w, c] => Ok((h, w, c)),
        _ => Err(errors::value(
            what,
            format!("expected an (H, W) or (H, W, C) array, got shape {shape:?}"),
        )),
    }
}

/// The samples of a C-contiguous array, borrowed.
fn contiguous<'a, T: numpy::Element, D: ndarray::Dimension>(
    what: &str,
    a: &'a numpy::PyReadonlyArray<'_, T, D>,
) -> PyResult<&'a [T]> {
    a.as_slice()
        .map_err(|_| errors::value(what, "the array is not C-contiguous"))
}

/// A borrowed view of an `(H, W)` or `(H, W, C)` float32 array (no copy).
pub(crate) fn image_view<'a>(
    what: &str,
    a: &'a PyReadonlyArrayDyn<'_, f32>,
) -> PyResult<ImageView<'a>> {
    let (h, w, c) = image_dims(what, a.shape())?;
    ImageView::new(w, h, c, contiguous(what, a)?).map_err(|e| errors::value(what, e))
}

/// A per-pixel field: an `(H, W)` float32 array, borrowed.
pub(crate) fn field<'a>(what: &str, a: &'a PyReadonlyArray2<'_, f32>) -> PyResult<&'a [f32]> {
    contiguous(what, a)
}

/// The shape of a field array, `(height, width)`.
pub(crate) fn field_shape(a: &PyReadonlyArray2<'_, f32>) -> (usize, usize) {
    let s = a.shape();
    (s[0], s[1])
}

/// An image as an array: `(H, W)` when it has one channel and `squeeze`,
/// else `(H, W, C)`. The samples move into the array (no copy).
pub(crate) fn image_array(
    py: Python<'_>,
    image: Image,
    squeeze: bool,
) -> Bound<'_, PyArrayDyn<f32>> {
    let (w, h, c) = (image.width(), image.height(), image.channels());
    let shape = if squeeze && c == 1 {
        vec![h, w]
    } else {
        vec![h, w, c]
    };
    let array = Array::from_shape_vec(IxDyn(&shape), image.into_vec())
        .expect("an image's samples fill its shape");
    PyArray::from_owned_array(py, array)
}

/// An owned array of any shape from row-major values.
pub(crate) fn array_f64<'py>(
    py: Python<'py>,
    shape: &[usize],
    data: Vec<f64>,
) -> Bound<'py, PyArrayDyn<f64>> {
    let array =
        Array::from_shape_vec(IxDyn(shape), data).expect("values fill the shape they come with");
    PyArray::from_owned_array(py, array)
}

/// The values of a C-contiguous float64 array of any shape, with its shape.
pub(crate) fn values_f64<'a>(
    what: &str,
    a: &'a PyReadonlyArrayDyn<'_, f64>,
) -> PyResult<(Vec<usize>, &'a [f64])> {
    Ok((a.shape().to_vec(), contiguous(what, a)?))
}
