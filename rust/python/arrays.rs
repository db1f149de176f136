//! numpy arrays in and out: `(n, 3)` C-ordered arrays viewed as triples (their layout
//! checked), triples and flat vectors returned as `(n, 3)` arrays, face arrays of either
//! index dtype.

use numpy::{IntoPyArray, PyArray2, PyArrayMethods, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;

use super::errors::ShapeError;

/// Views an `(n, 3)` C-ordered array as `n` triples.
pub(super) fn triples<'a, T: numpy::Element>(
    array: &'a PyReadonlyArray2<'_, T>,
    name: &str,
) -> PyResult<&'a [[T; 3]]> {
    let shape = array.shape();
    if shape[1] != 3 {
        return Err(ShapeError::new_err(format!(
            "{name} must have shape (n, 3), got ({}, {})",
            shape[0], shape[1]
        )));
    }
    if !array.is_c_contiguous() {
        return Err(ShapeError::new_err(format!("{name} must be C-contiguous")));
    }
    let flat = array
        .as_slice()
        .map_err(|e| ShapeError::new_err(format!("{name} is not contiguous: {e}")))?;
    let (chunks, rest) = flat.as_chunks::<3>();
    debug_assert!(rest.is_empty());
    Ok(chunks)
}

/// `n` triples as an `(n, 3)` float64 array.
pub(super) fn triples_to_array<'py>(
    py: Python<'py>,
    rows: Vec<[f64; 3]>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let n = rows.len();
    rows.into_iter()
        .flatten()
        .collect::<Vec<f64>>()
        .into_pyarray(py)
        .reshape([n, 3])
}

/// A flat vector of `3 n` values as an `(n, 3)` array, without copying.
pub(super) fn rows<T: numpy::Element>(
    py: Python<'_>,
    flat: Vec<T>,
) -> PyResult<Bound<'_, numpy::PyArray2<T>>> {
    let n = flat.len() / 3;
    flat.into_pyarray(py).reshape([n, 3])
}

/// Face indices as numpy holds them: uint32, or int64 (numpy's default integer) read in
/// place by kernels generic over [`VertexIndex`].
#[derive(FromPyObject)]
pub(super) enum FaceArray<'py> {
    U32(PyReadonlyArray2<'py, u32>),
    I64(PyReadonlyArray2<'py, i64>),
}
