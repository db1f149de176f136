//! Shape complexity K ([`crate::complexity`]) for `meshbits.complexity`.

use numpy::{IntoPyArray, PyArrayMethods, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use super::arrays::{FaceArray, triples};
use super::errors::ParameterError;
use super::pool::run_detached;
use crate::complexity::{self, Estimator, Tolerances};

fn parse_estimator(name: &str) -> PyResult<Estimator> {
    match name {
        "circumsphere" => Ok(Estimator::Circumsphere),
        "dihedral" => Ok(Estimator::Dihedral),
        "hybrid" => Ok(Estimator::Hybrid),
        other => Err(ParameterError::new_err(format!(
            "estimator must be 'circumsphere', 'dihedral' or 'hybrid', got {other:?}"
        ))),
    }
}

/// Shape complexity; returns a dict of raw measurements (see `meshbits.complexity`).
/// `faces` may be uint32 or int64; the kernel checks the indices.
#[pyfunction]
#[pyo3(signature = (vertices, faces, estimator, merge_vertices, per_edge, flat_angle, ill_angle, ill_cocircular))]
#[allow(clippy::too_many_arguments)]
pub(super) fn shape_complexity<'py>(
    py: Python<'py>,
    vertices: PyReadonlyArray2<'py, f64>,
    faces: FaceArray<'py>,
    estimator: &str,
    merge_vertices: bool,
    per_edge: bool,
    flat_angle: f64,
    ill_angle: f64,
    ill_cocircular: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let estimator = parse_estimator(estimator)?;
    let tol = Tolerances {
        flat_angle,
        ill_angle,
        ill_cocircular,
    };
    let v = triples(&vertices, "vertices")?;
    let c = match &faces {
        FaceArray::U32(f) => {
            let f = triples(f, "faces")?;
            run_detached(py, || {
                complexity::shape_complexity(v, f, estimator, merge_vertices, per_edge, &tol)
            })?
        }
        FaceArray::I64(f) => {
            let f = triples(f, "faces")?;
            run_detached(py, || {
                complexity::shape_complexity(v, f, estimator, merge_vertices, per_edge, &tol)
            })?
        }
    };
    let out = PyDict::new(py);
    out.set_item("k_raw", c.k_raw)?;
    out.set_item("area", c.area)?;
    out.set_item("bbox_min", c.bbox_min.to_vec())?;
    out.set_item("bbox_max", c.bbox_max.to_vec())?;
    out.set_item("edges", c.edges)?;
    out.set_item("interior_edges", c.interior_edges)?;
    out.set_item("boundary_edges", c.boundary_edges)?;
    out.set_item("nonmanifold_edges", c.nonmanifold_edges)?;
    out.set_item("flat_edges", c.flat_edges)?;
    out.set_item("ill_conditioned_edges", c.ill_conditioned_edges)?;
    out.set_item("degenerate_edges", c.degenerate_edges)?;
    out.set_item("merged_vertices", c.merged_vertices)?;
    out.set_item("degenerate_faces", c.degenerate_faces)?;
    if let Some(edges) = c.per_edge {
        let pairs: Vec<u32> = edges.vertices.into_iter().flatten().collect();
        let n = pairs.len() / 2;
        out.set_item("edge_vertices", pairs.into_pyarray(py).reshape([n, 2])?)?;
        out.set_item("edge_kind", edges.kind.into_pyarray(py))?;
        out.set_item("edge_radius", edges.radius.into_pyarray(py))?;
        out.set_item("edge_weight", edges.weight.into_pyarray(py))?;
        out.set_item("edge_contribution", edges.contribution.into_pyarray(py))?;
    }
    Ok(out)
}
