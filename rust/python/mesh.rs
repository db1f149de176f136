//! Mesh arrays: faces welded on identical vertices ([`crate::weld`]), and int64 faces
//! converted to uint32 in one checked pass.

use numpy::PyArray2;
use numpy::PyReadonlyArray2;
use pyo3::prelude::*;

use super::arrays::{rows, triples};
use super::pool::run_detached;

/// Faces with every vertex replaced by the smallest-index vertex of identical coordinates
/// (see [`crate::weld::weld_faces`]), and how many vertices were merged.
#[pyfunction]
pub(super) fn weld<'py>(
    py: Python<'py>,
    vertices: PyReadonlyArray2<'py, f64>,
    faces: PyReadonlyArray2<'py, u32>,
) -> PyResult<(Bound<'py, PyArray2<u32>>, usize)> {
    let (v, f) = (triples(&vertices, "vertices")?, triples(&faces, "faces")?);
    let (welded, merged) = run_detached(py, || crate::weld::weld_faces(v, f))?;
    Ok((rows(py, welded.into_flattened())?, merged))
}

/// `(m, 3)` int64 faces as C-ordered uint32, checked against `vertex_count` in one
/// parallel pass; `None` when an index is out of range (Python names the face).
#[pyfunction]
pub(super) fn faces_as_u32<'py>(
    py: Python<'py>,
    faces: PyReadonlyArray2<'py, i64>,
    vertex_count: usize,
) -> PyResult<Option<Bound<'py, PyArray2<u32>>>> {
    let f = triples(&faces, "faces")?;
    let converted = run_detached(py, || Ok(crate::error::indices_from_i64(f, vertex_count)))?;
    converted
        .map(|rows_u32| rows(py, rows_u32.into_flattened()))
        .transpose()
}
