//! The triangle tree ([`crate::bvh`]) as the Python class `TriangleTree`, its builders,
//! and the box overlap measure.

use numpy::{IntoPyArray, PyArray1, PyReadonlyArray2};
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use rayon::prelude::*;

use super::arrays::{triples, triples_to_array};
use super::pool::run_detached;
use crate::bvh::TriangleTree;
use crate::error::{MeshError, check_indices};

/// A BVH over one mesh's triangles (see `rust/bvh/`); built by `build_tree`.
#[pyclass(frozen, name = "TriangleTree", module = "meshbits._core")]
pub(super) struct PyTriangleTree {
    pub(super) tree: TriangleTree,
}

#[pymethods]
impl PyTriangleTree {
    /// Exact nearest triangle of each point: `(distances, closest points, face indices)`.
    fn query<'py>(
        &self,
        py: Python<'py>,
        points: PyReadonlyArray2<'py, f64>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>, Bound<'py, PyAny>)> {
        let p = triples(&points, "points")?;
        let (d, q, f) = run_detached(py, || self.tree.query(p))?;
        Ok((
            d.into_pyarray(py).into_any(),
            triples_to_array(py, q)?.into_any(),
            f.into_pyarray(py).into_any(),
        ))
    }

    /// Whether each point lies farther than `distance` from the mesh (exact verdicts).
    fn farther_than<'py>(
        &self,
        py: Python<'py>,
        points: PyReadonlyArray2<'py, f64>,
        distance: f64,
    ) -> PyResult<Bound<'py, PyArray1<bool>>> {
        let p = triples(&points, "points")?;
        let far = run_detached(py, || self.tree.farther_than(p, distance))?;
        Ok(far.into_pyarray(py))
    }

    /// Checks the tree's invariants; raises `RuntimeError` naming the first broken one.
    fn validate(&self) -> PyResult<()> {
        self.tree
            .validate()
            .map_err(|e| PyRuntimeError::new_err(format!("invalid tree: {e}")))
    }

    #[getter]
    fn n_faces(&self) -> usize {
        self.tree.len()
    }

    #[getter]
    fn n_vertices(&self) -> usize {
        self.tree.vertex_count()
    }

    #[getter]
    fn depth(&self) -> usize {
        self.tree.depth()
    }

    #[getter]
    fn box_overlap(&self) -> f64 {
        self.tree.box_overlap()
    }

    #[getter]
    fn centre(&self) -> [f64; 3] {
        self.tree.centre().to_array()
    }
}

/// Builds the BVH of a mesh.
#[pyfunction]
pub(super) fn build_tree<'py>(
    py: Python<'py>,
    vertices: PyReadonlyArray2<'py, f64>,
    faces: PyReadonlyArray2<'py, u32>,
) -> PyResult<PyTriangleTree> {
    let (v, f) = (triples(&vertices, "vertices")?, triples(&faces, "faces")?);
    let tree = run_detached(py, || TriangleTree::build(v, f))?;
    Ok(PyTriangleTree { tree })
}

/// [`crate::reduce::box_overlap`]: mean number of triangle boxes over a point of the box.
#[pyfunction]
pub(super) fn box_overlap<'py>(
    py: Python<'py>,
    vertices: PyReadonlyArray2<'py, f64>,
    faces: PyReadonlyArray2<'py, u32>,
) -> PyResult<f64> {
    let (v, f) = (triples(&vertices, "vertices")?, triples(&faces, "faces")?);
    run_detached(py, || {
        check_indices(f, v.len())?;
        Ok::<f64, MeshError>(crate::reduce::box_overlap(v, f))
    })
}

/// Builds the BVHs of several meshes at once (their builds run concurrently: one build
/// alone does not keep two cores busy).
#[pyfunction]
pub(super) fn build_trees<'py>(
    py: Python<'py>,
    meshes: Vec<(PyReadonlyArray2<'py, f64>, PyReadonlyArray2<'py, u32>)>,
) -> PyResult<Vec<PyTriangleTree>> {
    let views = meshes
        .iter()
        .map(|(v, f)| Ok((triples(v, "vertices")?, triples(f, "faces")?)))
        .collect::<PyResult<Vec<_>>>()?;
    let trees = run_detached(py, || {
        views
            .par_iter()
            .map(|(v, f)| TriangleTree::build(v, f))
            .collect::<Result<Vec<_>, MeshError>>()
    })?;
    Ok(trees
        .into_iter()
        .map(|tree| PyTriangleTree { tree })
        .collect())
}
