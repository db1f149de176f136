//! meshoptimizer's simplification ([`crate::meshopt::simplify`]) for `meshbits.simplify`.

use numpy::{IntoPyArray, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use super::arrays::{rows, triples, triples_to_array};
use super::errors::{ParameterError, ShapeError};
use super::pool::run_detached;
use crate::meshopt;

/// meshoptimizer's simplification (see `rust/meshopt/simplify.rs`): a dict with `vertex_ids`
/// (kept input vertices, uint32), `faces` ((m, 3) uint32 over them) and `error` (length).
#[pyfunction]
#[pyo3(signature = (vertices, faces, target_faces, target_error, lock_border, locked, attributes, weights, prune, weld, update_positions))]
#[allow(clippy::too_many_arguments)]
pub(super) fn simplify<'py>(
    py: Python<'py>,
    vertices: PyReadonlyArray2<'py, f64>,
    faces: PyReadonlyArray2<'py, u32>,
    target_faces: Option<usize>,
    target_error: Option<f64>,
    lock_border: bool,
    locked: Option<PyReadonlyArray1<'py, bool>>,
    attributes: Option<PyReadonlyArray2<'py, f32>>,
    weights: Option<PyReadonlyArray1<'py, f32>>,
    prune: bool,
    weld: bool,
    update_positions: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let (v, f) = (triples(&vertices, "vertices")?, triples(&faces, "faces")?);
    let locked = locked
        .as_ref()
        .map(|l| l.as_slice())
        .transpose()
        .map_err(|e| ShapeError::new_err(format!("locked is not contiguous: {e}")))?;
    let attributes = match (&attributes, &weights) {
        (Some(values), Some(weights)) => Some(meshopt::Attributes {
            values: values
                .as_slice()
                .map_err(|e| ShapeError::new_err(format!("attributes: {e}")))?,
            weights: weights
                .as_slice()
                .map_err(|e| ShapeError::new_err(format!("weights: {e}")))?,
        }),
        (None, None) => None,
        _ => {
            return Err(ParameterError::new_err(
                "give attributes and weights together",
            ));
        }
    };
    let request = meshopt::Request {
        target_faces,
        target_error,
        lock_border,
        locked,
        attributes,
        prune,
        weld,
        update_positions,
    };
    let s = run_detached(py, || meshopt::simplify(v, f, &request))?;
    let kept = s.vertex_ids.len();
    let out = PyDict::new(py);
    out.set_item("vertex_ids", s.vertex_ids.into_pyarray(py))?;
    out.set_item("faces", rows(py, s.faces.into_flattened())?)?;
    out.set_item("error", s.error)?;
    if let Some(positions) = s.positions {
        out.set_item("positions", triples_to_array(py, positions)?)?;
    }
    if let Some(values) = s.attributes {
        let k = values.len() / kept.max(1);
        out.set_item("attributes", values.into_pyarray(py).reshape([kept, k])?)?;
    }
    Ok(out)
}
