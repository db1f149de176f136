//! The Python binding: the only module that uses pyo3 or numpy.
//!
//! Each wrapper borrows the numpy arrays (already normalised to C-ordered float64 vertices
//! and uint32 faces by `meshbits/mesh.py`), checks their layout, releases the GIL around
//! the kernel, and converts the result. Kernel errors become `meshbits.MeshbitsError`
//! (a `ValueError`); a panic becomes a `RuntimeError` instead of tearing down Python.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::atomic::{AtomicUsize, Ordering};

use numpy::{IntoPyArray, PyArray2, PyArrayMethods, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::create_exception;
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;

use crate::bvh::TriangleTree;
use crate::complexity::{self, Estimator, Tolerances};
use crate::error::MeshError;
use crate::hausdorff::{self, Options};
use crate::sampling;

create_exception!(
    _core,
    MeshbitsError,
    PyValueError,
    "Invalid input to a meshbits kernel."
);

/// Worker threads for kernels: 0 means rayon's global pool.
static THREADS: AtomicUsize = AtomicUsize::new(0);

impl From<MeshError> for PyErr {
    fn from(err: MeshError) -> PyErr {
        MeshbitsError::new_err(err.to_string())
    }
}

/// Runs a kernel with the GIL released, on the configured number of threads, turning a
/// panic into a Python `RuntimeError`.
fn run_detached<T, F>(py: Python<'_>, kernel: F) -> PyResult<T>
where
    T: Send,
    F: FnOnce() -> Result<T, MeshError> + Send,
{
    let threads = THREADS.load(Ordering::Relaxed);
    let outcome = py.detach(move || {
        catch_unwind(AssertUnwindSafe(move || {
            if threads == 0 {
                return kernel().map_err(PyErr::from);
            }
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .map_err(|e| PyRuntimeError::new_err(format!("cannot start threads: {e}")))?
                .install(kernel)
                .map_err(PyErr::from)
        }))
    });
    match outcome {
        Ok(result) => result,
        Err(panic) => {
            let what = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".into());
            Err(PyRuntimeError::new_err(format!(
                "meshbits internal error (please report): {what}"
            )))
        }
    }
}

/// Views an `(n, 3)` C-ordered array as `n` triples.
fn triples<'a, T: numpy::Element>(
    array: &'a PyReadonlyArray2<'_, T>,
    name: &str,
) -> PyResult<&'a [[T; 3]]> {
    let shape = array.shape();
    if shape[1] != 3 {
        return Err(PyValueError::new_err(format!(
            "{name} must have shape (n, 3), got ({}, {})",
            shape[0], shape[1]
        )));
    }
    if !array.is_c_contiguous() {
        return Err(PyValueError::new_err(format!(
            "{name} must be C-contiguous"
        )));
    }
    let flat = array
        .as_slice()
        .map_err(|e| PyValueError::new_err(format!("{name} is not contiguous: {e}")))?;
    let (chunks, rest) = flat.as_chunks::<3>();
    debug_assert!(rest.is_empty());
    Ok(chunks)
}

fn parse_estimator(name: &str) -> PyResult<Estimator> {
    match name {
        "circumsphere" => Ok(Estimator::Circumsphere),
        "dihedral" => Ok(Estimator::Dihedral),
        "hybrid" => Ok(Estimator::Hybrid),
        other => Err(PyValueError::new_err(format!(
            "estimator must be 'circumsphere', 'dihedral' or 'hybrid', got {other:?}"
        ))),
    }
}

/// Shape complexity; returns a dict of raw measurements (see `meshbits.complexity`).
#[pyfunction]
#[pyo3(signature = (vertices, faces, estimator, merge_vertices, per_edge, flat_angle, ill_angle, ill_cocircular))]
#[allow(clippy::too_many_arguments)]
fn shape_complexity<'py>(
    py: Python<'py>,
    vertices: PyReadonlyArray2<'py, f64>,
    faces: PyReadonlyArray2<'py, u32>,
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
    let (v, f) = (triples(&vertices, "vertices")?, triples(&faces, "faces")?);
    let c = run_detached(py, || {
        complexity::shape_complexity(v, f, estimator, merge_vertices, per_edge, &tol)
    })?;
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

/// `n` triples as an `(n, 3)` float64 array.
fn triples_to_array<'py>(
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

/// A BVH over one mesh's triangles (see `rust/bvh.rs`); built by `build_tree`.
#[pyclass(frozen, name = "TriangleTree", module = "meshbits._core")]
struct PyTriangleTree {
    tree: TriangleTree,
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
    fn centre(&self) -> [f64; 3] {
        self.tree.centre().to_array()
    }
}

/// Builds the BVH of a mesh.
#[pyfunction]
fn build_tree<'py>(
    py: Python<'py>,
    vertices: PyReadonlyArray2<'py, f64>,
    faces: PyReadonlyArray2<'py, u32>,
) -> PyResult<PyTriangleTree> {
    let (v, f) = (triples(&vertices, "vertices")?, triples(&faces, "faces")?);
    let tree = run_detached(py, || TriangleTree::build(v, f))?;
    Ok(PyTriangleTree { tree })
}

/// Builds the BVHs of several meshes at once (their builds run concurrently: one build
/// alone does not keep two cores busy).
#[pyfunction]
fn build_trees<'py>(
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
    Ok(trees.into_iter().map(|tree| PyTriangleTree { tree }).collect())
}

/// One-sided sampled Hausdorff distance from a mesh to a tree; a dict of raw results
/// (see `meshbits.hausdorff`).
#[pyfunction]
#[pyo3(signature = (vertices, faces, tree, samples, seed, statistics, bounds, tolerance, refine_budget, return_samples))]
#[allow(clippy::too_many_arguments)]
fn hausdorff_directed<'py>(
    py: Python<'py>,
    vertices: PyReadonlyArray2<'py, f64>,
    faces: PyReadonlyArray2<'py, u32>,
    tree: &PyTriangleTree,
    samples: usize,
    seed: u64,
    statistics: bool,
    bounds: bool,
    tolerance: Option<f64>,
    refine_budget: usize,
    return_samples: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let (v, f) = (triples(&vertices, "vertices")?, triples(&faces, "faces")?);
    let opts = Options {
        area_samples: samples,
        seed,
        statistics,
        bounds,
        tolerance,
        refine_budget,
        return_samples,
    };
    let r = run_detached(py, || hausdorff::directed(v, f, &tree.tree, &opts))?;
    let out = PyDict::new(py);
    out.set_item("n_samples", r.n_samples)?;
    out.set_item("n_vertex_samples", r.n_vertex_samples)?;
    out.set_item("max", r.max)?;
    out.set_item("argmax", r.argmax.to_vec())?;
    out.set_item("argmax_closest", r.argmax_closest.to_vec())?;
    out.set_item("argmax_face", r.argmax_face)?;
    if let Some(s) = r.statistics {
        out.set_item("mean", s.mean)?;
        out.set_item("rms", s.rms)?;
        out.set_item("p50", s.p50)?;
        out.set_item("p95", s.p95)?;
        out.set_item("p99", s.p99)?;
    }
    if let Some(b) = r.bounds {
        out.set_item("upper", b.upper)?;
        out.set_item("refined_points", b.refined_points)?;
        out.set_item("refined_cells", b.refined_cells)?;
        out.set_item("converged", b.converged)?;
    }
    if let Some(s) = r.samples {
        out.set_item("samples", triples_to_array(py, s.points)?)?;
        out.set_item("sample_faces", s.faces.into_pyarray(py))?;
        out.set_item("distances", s.distances.into_pyarray(py))?;
        out.set_item("vertex_distances", s.vertex_distances.into_pyarray(py))?;
    }
    Ok(out)
}

/// The sample set of a mesh (referenced vertices, then area samples): a dict with
/// `points` (n, 3), `faces` (n,) (`2**32 - 1` for vertex samples) and `n_vertex_samples`.
#[pyfunction]
fn surface_samples<'py>(
    py: Python<'py>,
    vertices: PyReadonlyArray2<'py, f64>,
    faces: PyReadonlyArray2<'py, u32>,
    samples: usize,
    seed: u64,
) -> PyResult<Bound<'py, PyDict>> {
    let (v, f) = (triples(&vertices, "vertices")?, triples(&faces, "faces")?);
    let (points, sample_faces, nv) = run_detached(py, || {
        crate::error::check_finite(v)?;
        crate::error::check_indices(f, v.len())?;
        let (lo, hi) = complexity::referenced_bbox(v, f);
        let centre = (glam::DVec3::from_array(lo) + glam::DVec3::from_array(hi)) * 0.5;
        let s = sampling::surface_samples(v, f, centre, samples, seed)?;
        let points: Vec<[f64; 3]> = s.points.iter().map(|p| (*p + centre).to_array()).collect();
        Ok((points, s.faces(), s.vertex_count()))
    })?;
    let out = PyDict::new(py);
    out.set_item("points", triples_to_array(py, points)?)?;
    out.set_item("faces", sample_faces.into_pyarray(py))?;
    out.set_item("n_vertex_samples", nv)?;
    Ok(out)
}

/// Sets the number of worker threads for every kernel (0 restores rayon's default pool).
#[pyfunction]
fn set_num_threads(threads: usize) {
    THREADS.store(threads, Ordering::Relaxed);
}

/// The number of worker threads set by `set_num_threads` (0: rayon's default pool).
#[pyfunction]
fn get_num_threads() -> usize {
    THREADS.load(Ordering::Relaxed)
}

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("MeshbitsError", m.py().get_type::<MeshbitsError>())?;
    m.add(
        "BUILD_PROFILE",
        if cfg!(debug_assertions) {
            "debug"
        } else {
            "release"
        },
    )?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_function(wrap_pyfunction!(shape_complexity, m)?)?;
    m.add_class::<PyTriangleTree>()?;
    m.add_function(wrap_pyfunction!(build_tree, m)?)?;
    m.add_function(wrap_pyfunction!(build_trees, m)?)?;
    m.add_function(wrap_pyfunction!(hausdorff_directed, m)?)?;
    m.add_function(wrap_pyfunction!(surface_samples, m)?)?;
    m.add_function(wrap_pyfunction!(set_num_threads, m)?)?;
    m.add_function(wrap_pyfunction!(get_num_threads, m)?)?;
    Ok(())
}
