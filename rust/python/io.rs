//! Mesh files read by [`crate::io`] for `meshbits.formats.native`.

use std::path::PathBuf;

use pyo3::exceptions::{PyOSError, PyRuntimeError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use super::arrays::rows;
use super::errors::ParameterError;
use crate::io::{self, Format, ReadError};

/// Reads the mesh file at `path` in `format` (`"ply"`, `"stl"` or `"obj"`).
///
/// Returns `(vertices float64 (n, 3), faces uint32 (m, 3), counts)` with `counts` a dict
/// of `polygons`, `polygon_triangles` and `skipped_elements`; or a string saying why the
/// file is left to the general reader. Raises `OSError` when the file cannot be opened.
#[pyfunction]
pub(super) fn read_mesh(py: Python<'_>, path: PathBuf, format: &str) -> PyResult<Py<PyAny>> {
    let Some(format) = Format::from_name(format) else {
        return Err(ParameterError::new_err(format!(
            "format must be 'ply', 'stl' or 'obj', got {format:?}"
        )));
    };
    let outcome = py
        .detach(|| std::panic::catch_unwind(|| crate::pool::run(|| io::read_mesh(&path, format))));
    let read = match outcome {
        Ok(Ok(Ok(read))) => read,
        Ok(Ok(Err(ReadError::Fallback(why)))) => {
            return Ok(why.into_pyobject(py)?.into_any().unbind());
        }
        Ok(Ok(Err(ReadError::Io(err)))) => return Err(PyOSError::new_err(err.to_string())),
        Ok(Err(threads)) => return Err(PyRuntimeError::new_err(threads)),
        Err(_) => {
            return Err(PyRuntimeError::new_err(
                "meshbits internal error (please report): the mesh reader panicked",
            ));
        }
    };
    let counts = PyDict::new(py);
    counts.set_item("polygons", read.polygons)?;
    counts.set_item("polygon_triangles", read.polygon_triangles)?;
    counts.set_item("skipped_elements", read.skipped_elements)?;
    let vertices = rows(py, read.vertices.into_flattened())?;
    let faces = rows(py, read.faces.into_flattened())?;
    Ok((vertices, faces, counts)
        .into_pyobject(py)?
        .into_any()
        .unbind())
}
