//! meshoptimizer's glTF codecs ([`crate::meshopt`]): the encoders meshbits writes with
//! and the `bufferView` decoder it reads with.

use numpy::PyUntypedArrayMethods;
use numpy::{IntoPyArray, PyArray2, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyBytes;

use super::arrays::{rows, triples};
use super::errors::ShapeError;
use super::pool::run_detached;
use crate::meshopt;

/// meshoptimizer's vertex codec (`EXT_meshopt_compression`, version 0) over rows of
/// `stride` bytes.
#[pyfunction]
pub(super) fn meshopt_encode_vertices<'py>(
    py: Python<'py>,
    data: PyReadonlyArray1<'py, u8>,
    stride: usize,
) -> PyResult<Bound<'py, PyBytes>> {
    let bytes = data
        .as_slice()
        .map_err(|e| ShapeError::new_err(format!("data is not contiguous: {e}")))?;
    let encoded = run_detached(py, || meshopt::encode_vertices(bytes, stride))?;
    Ok(PyBytes::new(py, &encoded))
}

/// meshoptimizer's index codec over a triangle list of `vertex_count` vertices.
#[pyfunction]
pub(super) fn meshopt_encode_triangles<'py>(
    py: Python<'py>,
    faces: PyReadonlyArray2<'py, u32>,
    vertex_count: usize,
) -> PyResult<Bound<'py, PyBytes>> {
    let f = triples(&faces, "faces")?;
    let encoded = run_detached(py, || {
        meshopt::encode_triangles(f.as_flattened(), vertex_count)
    })?;
    Ok(PyBytes::new(py, &encoded))
}

/// Triangles reordered for meshoptimizer's codecs: `(new triangles, old vertex of each new
/// vertex)`.
#[pyfunction]
pub(super) fn meshopt_reorder<'py>(
    py: Python<'py>,
    faces: PyReadonlyArray2<'py, u32>,
    vertex_count: usize,
) -> PyResult<(Bound<'py, PyArray2<u32>>, Bound<'py, PyAny>)> {
    let f = triples(&faces, "faces")?;
    let (triangles, old) = run_detached(py, || {
        meshopt::reorder_for_codecs(f.as_flattened(), vertex_count)
    })?;
    Ok((rows(py, triangles)?, old.into_pyarray(py).into_any()))
}

/// Unit vectors `(n, 4)` as octahedral signed normalized integers: `(n, 4)` bytes
/// (`bits <= 8`) or `(n, 8)` (two bytes a component, little-endian).
#[pyfunction]
pub(super) fn meshopt_encode_octahedral<'py>(
    py: Python<'py>,
    vectors: PyReadonlyArray2<'py, f32>,
    bits: u32,
) -> PyResult<Bound<'py, PyArray2<u8>>> {
    if vectors.shape()[1] != 4 || !vectors.is_c_contiguous() {
        return Err(ShapeError::new_err(
            "vectors must be a C-contiguous (n, 4) float32 array",
        ));
    }
    let flat = vectors
        .as_slice()
        .map_err(|e| ShapeError::new_err(format!("vectors: {e}")))?;
    let (rows_in, _) = flat.as_chunks::<4>();
    let n = rows_in.len();
    let encoded = run_detached(py, || meshopt::encode_octahedral(rows_in, bits))?;
    let width = encoded.len() / n.max(1);
    encoded.into_pyarray(py).reshape([n, width])
}

/// One `bufferView` of `EXT_meshopt_compression` / `KHR_meshopt_compression` decoded:
/// `data` (the compressed bytes), `count` elements of `stride` bytes, `mode`
/// (`"ATTRIBUTES"`, `"TRIANGLES"`, `"INDICES"`) and `filter` (`"NONE"`, `"OCTAHEDRAL"`,
/// `"QUATERNION"`, `"EXPONENTIAL"`, `"COLOR"`; None for none): the `count * stride` plain
/// bytes (see [`meshopt::decode_buffer_view`]).
#[pyfunction]
#[pyo3(signature = (data, count, stride, mode, filter = None))]
pub(super) fn meshopt_decode<'py>(
    py: Python<'py>,
    data: &[u8],
    count: usize,
    stride: usize,
    mode: &str,
    filter: Option<&str>,
) -> PyResult<Bound<'py, PyBytes>> {
    let mode = meshopt::Mode::from_name(mode)?;
    let filter = meshopt::Filter::from_name(filter.unwrap_or("NONE"))?;
    let decoded = run_detached(py, || {
        meshopt::decode_buffer_view(data, count, stride, mode, filter)
    })?;
    Ok(PyBytes::new(py, decoded.as_bytes()))
}

/// Unit quaternions `(n, 4)` as the `QUATERNION` filter's records at `bits` bits (4 to
/// 16): `(n, 8)` bytes (four little-endian shorts a row).
#[pyfunction]
pub(super) fn meshopt_encode_quaternions<'py>(
    py: Python<'py>,
    quaternions: PyReadonlyArray2<'py, f32>,
    bits: u32,
) -> PyResult<Bound<'py, PyArray2<u8>>> {
    if quaternions.shape()[1] != 4 || !quaternions.is_c_contiguous() {
        return Err(ShapeError::new_err(
            "quaternions must be a C-contiguous (n, 4) float32 array",
        ));
    }
    let flat = quaternions
        .as_slice()
        .map_err(|e| ShapeError::new_err(format!("quaternions: {e}")))?;
    let (rows_in, _) = flat.as_chunks::<4>();
    let n = rows_in.len();
    let encoded = run_detached(py, || meshopt::encode_quaternions(rows_in, bits))?;
    encoded.into_pyarray(py).reshape([n, 8])
}

/// Rows `(n, c)` of float32 values (c from 1 to 64) as the `EXPONENTIAL` filter's words at
/// `bits` mantissa bits (1 to 24), the exponents shared as `mode` says (`"separate"`,
/// `"vector"`: one per row, `"component"`: one per column): `(n, 4 c)` bytes.
#[pyfunction]
pub(super) fn meshopt_encode_exponential<'py>(
    py: Python<'py>,
    values: PyReadonlyArray2<'py, f32>,
    bits: u32,
    mode: &str,
) -> PyResult<Bound<'py, PyArray2<u8>>> {
    if !values.is_c_contiguous() {
        return Err(ShapeError::new_err(
            "values must be a C-contiguous float32 array",
        ));
    }
    let (n, components) = (values.shape()[0], values.shape()[1]);
    let flat = values
        .as_slice()
        .map_err(|e| ShapeError::new_err(format!("values: {e}")))?;
    let mode = meshopt::ExponentMode::from_name(mode)?;
    let encoded = run_detached(py, || {
        meshopt::encode_exponential(flat, components, bits, mode)
    })?;
    encoded.into_pyarray(py).reshape([n, 4 * components])
}
