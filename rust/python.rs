//! The Python binding: the only module that uses pyo3 or numpy.
//!
//! Each wrapper borrows the numpy arrays (already normalised to C-ordered float64 vertices
//! and uint32 faces by `meshbits/mesh.py`), checks their layout, releases the GIL around
//! the kernel, and converts the result. Kernel errors become `meshbits.MeshbitsError`
//! (a `ValueError`); a panic becomes a `RuntimeError` instead of tearing down Python.

use std::panic::{AssertUnwindSafe, catch_unwind};

use numpy::{
    IntoPyArray, PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2,
    PyUntypedArrayMethods,
};
use pyo3::create_exception;
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};
use rayon::prelude::*;

use crate::bvh::TriangleTree;
use crate::complexity::{self, Estimator, Tolerances};
use crate::error::{MeshError, VertexIndex, check_indices};
use crate::hausdorff::{self, Options};
use crate::meshopt;
use crate::pool;
use crate::quantize::{Clustering, Duplicates, Grid, GridKind};
use crate::quantize::{
    cluster as cluster_kernel, dequantize as dequantize_kernel, quantize as quantize_kernel,
};
use crate::sampling;

create_exception!(
    meshbits,
    MeshbitsError,
    PyValueError,
    "Invalid input to a meshbits kernel."
);

impl From<MeshError> for PyErr {
    fn from(err: MeshError) -> PyErr {
        MeshbitsError::new_err(err.to_string())
    }
}

/// Runs a kernel with the GIL released on the fork-safe pool of [`crate::pool::run`],
/// turning a panic into a Python `RuntimeError`: the one path from Python into a kernel.
fn run_detached<T, F>(py: Python<'_>, kernel: F) -> PyResult<T>
where
    T: Send,
    F: FnOnce() -> Result<T, MeshError> + Send,
{
    let outcome = py.detach(move || catch_unwind(AssertUnwindSafe(move || pool::run(kernel))));
    match outcome {
        Ok(Ok(result)) => result.map_err(PyErr::from),
        Ok(Err(threads)) => Err(PyRuntimeError::new_err(threads)),
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
/// `faces` may be uint32 or int64; the kernel checks the indices.
#[pyfunction]
#[pyo3(signature = (vertices, faces, estimator, merge_vertices, per_edge, flat_angle, ill_angle, ill_cocircular))]
#[allow(clippy::too_many_arguments)]
fn shape_complexity<'py>(
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

/// A BVH over one mesh's triangles (see `rust/bvh/`); built by `build_tree`.
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
fn build_tree<'py>(
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
fn box_overlap<'py>(
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
    Ok(trees
        .into_iter()
        .map(|tree| PyTriangleTree { tree })
        .collect())
}

/// One-sided sampled Hausdorff distance from a mesh to a tree; a dict of raw results
/// (see `meshbits.hausdorff`).
#[pyfunction]
#[pyo3(signature = (vertices, faces, tree, samples, seed, statistics, bounds, tolerance, refine_budget, return_samples, threshold = None, relative_tolerance = None))]
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
    threshold: Option<f64>,
    relative_tolerance: Option<f64>,
) -> PyResult<Bound<'py, PyDict>> {
    let (v, f) = (triples(&vertices, "vertices")?, triples(&faces, "faces")?);
    let opts = Options {
        area_samples: samples,
        seed,
        statistics,
        bounds,
        tolerance,
        relative_tolerance,
        threshold,
        refine_budget,
        return_samples,
    };
    let r = run_detached(py, || hausdorff::directed(v, f, &tree.tree, &opts))?;
    directed_dict(py, r)
}

/// The raw result of one direction as the Python layer reads it.
fn directed_dict(py: Python<'_>, r: hausdorff::Directed) -> PyResult<Bound<'_, PyDict>> {
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
        let s = sampling::surface_samples_centred(v, f, samples, seed)?;
        Ok((s.absolute_points(), s.faces(), s.vertex_count()))
    })?;
    let out = PyDict::new(py);
    out.set_item("points", triples_to_array(py, points)?)?;
    out.set_item("faces", sample_faces.into_pyarray(py))?;
    out.set_item("n_vertex_samples", nv)?;
    Ok(out)
}

/// A mesh and its sample set, drawn once and measured against any number of targets
/// (see `meshbits.hausdorff.Reference`).
#[pyclass(frozen, name = "SampledMesh", module = "meshbits._core")]
struct PySampledMesh {
    vertices: Vec<[f64; 3]>,
    faces: Vec<[u32; 3]>,
    samples: sampling::SurfaceSamples,
}

#[pymethods]
impl PySampledMesh {
    /// Samples: referenced vertices plus area samples.
    #[getter]
    fn n_samples(&self) -> usize {
        self.samples.points.len()
    }

    /// How many of the samples are vertices.
    #[getter]
    fn n_vertex_samples(&self) -> usize {
        self.samples.vertex_count()
    }
}

/// Samples a mesh once (referenced vertices, then `samples` seeded area samples).
#[pyfunction]
fn sample_mesh<'py>(
    py: Python<'py>,
    vertices: PyReadonlyArray2<'py, f64>,
    faces: PyReadonlyArray2<'py, u32>,
    samples: usize,
    seed: u64,
) -> PyResult<PySampledMesh> {
    let (v, f) = (triples(&vertices, "vertices")?, triples(&faces, "faces")?);
    let s = run_detached(py, || {
        sampling::surface_samples_centred(v, f, samples, seed)
    })?;
    Ok(PySampledMesh {
        vertices: v.to_vec(),
        faces: f.to_vec(),
        samples: s,
    })
}

/// One-sided sampled Hausdorff distance from a sampled mesh to a tree, reusing its samples.
#[pyfunction]
#[pyo3(signature = (source, tree, statistics, bounds, tolerance, refine_budget, return_samples, threshold = None, relative_tolerance = None))]
#[allow(clippy::too_many_arguments)]
fn hausdorff_from_samples<'py>(
    py: Python<'py>,
    source: &PySampledMesh,
    tree: &PyTriangleTree,
    statistics: bool,
    bounds: bool,
    tolerance: Option<f64>,
    refine_budget: usize,
    return_samples: bool,
    threshold: Option<f64>,
    relative_tolerance: Option<f64>,
) -> PyResult<Bound<'py, PyDict>> {
    let opts = Options {
        area_samples: 0,
        seed: 0,
        statistics,
        bounds,
        tolerance,
        relative_tolerance,
        threshold,
        refine_budget,
        return_samples,
    };
    let r = run_detached(py, || {
        hausdorff::directed_from_samples(
            &source.vertices,
            &source.faces,
            &source.samples,
            &tree.tree,
            &opts,
        )
    })?;
    directed_dict(py, r)
}

/// meshoptimizer's simplification (see `rust/meshopt/simplify.rs`): a dict with `vertex_ids`
/// (kept input vertices, uint32), `faces` ((m, 3) uint32 over them) and `error` (length).
#[pyfunction]
#[pyo3(signature = (vertices, faces, target_faces, target_error, lock_border, locked, attributes, weights, prune, weld, update_positions))]
#[allow(clippy::too_many_arguments)]
fn simplify<'py>(
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
        .map_err(|e| PyValueError::new_err(format!("locked is not contiguous: {e}")))?;
    let attributes = match (&attributes, &weights) {
        (Some(values), Some(weights)) => Some(meshopt::Attributes {
            values: values
                .as_slice()
                .map_err(|e| PyValueError::new_err(format!("attributes: {e}")))?,
            weights: weights
                .as_slice()
                .map_err(|e| PyValueError::new_err(format!("weights: {e}")))?,
        }),
        (None, None) => None,
        _ => {
            return Err(PyValueError::new_err(
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

fn parse_grid(name: &str) -> PyResult<GridKind> {
    match name {
        "cube" => Ok(GridKind::Cube),
        "axes" => Ok(GridKind::Axes),
        other => Err(PyValueError::new_err(format!(
            "grid must be 'cube' or 'axes', got {other:?}"
        ))),
    }
}

fn parse_duplicates(name: &str) -> PyResult<Duplicates> {
    match name {
        "keep" => Ok(Duplicates::Keep),
        "oriented" => Ok(Duplicates::Oriented),
        "any" => Ok(Duplicates::Any),
        other => Err(PyValueError::new_err(format!(
            "duplicates must be 'keep', 'oriented' or 'any', got {other:?}"
        ))),
    }
}

/// The grid on the caller's box, or on the bounding box of `vertices`.
fn make_grid(
    vertices: &[[f64; 3]],
    bits: u32,
    kind: GridKind,
    box_min: Option<[f64; 3]>,
    box_max: Option<[f64; 3]>,
) -> Result<Grid, MeshError> {
    match (box_min, box_max) {
        (Some(min), Some(max)) => Grid::new(bits, kind, min, max),
        (None, None) => Grid::bounding(vertices, bits, kind),
        _ => Err(MeshError::Parameter(
            "give both box corners or neither".into(),
        )),
    }
}

/// Codes in the dtype of their convention: corner `uint16` (B <= 16) or `uint32`;
/// centred `int16` (B <= 15), `int32` (B <= 31) or `int64`.
enum Codes {
    U16(Vec<u16>),
    U32(Vec<u32>),
    I16(Vec<i16>),
    I32(Vec<i32>),
    I64(Vec<i64>),
}

impl Codes {
    fn new(codes: Vec<[u32; 3]>, grid: &Grid, centered: bool) -> Codes {
        let flat = codes.into_flattened();
        let offset = i64::from(grid.centered_offset());
        match (centered, grid.bits) {
            (false, 1..=16) => Codes::U16(flat.par_iter().map(|&c| c as u16).collect()),
            (false, _) => Codes::U32(flat),
            (true, 1..=15) => Codes::I16(
                flat.par_iter()
                    .map(|&c| (i64::from(c) - offset) as i16)
                    .collect(),
            ),
            (true, 16..=31) => Codes::I32(
                flat.par_iter()
                    .map(|&c| (i64::from(c) - offset) as i32)
                    .collect(),
            ),
            (true, _) => Codes::I64(flat.par_iter().map(|&c| i64::from(c) - offset).collect()),
        }
    }

    fn into_py(self, py: Python<'_>) -> PyResult<Bound<'_, PyAny>> {
        Ok(match self {
            Codes::U16(v) => rows(py, v)?.into_any(),
            Codes::U32(v) => rows(py, v)?.into_any(),
            Codes::I16(v) => rows(py, v)?.into_any(),
            Codes::I32(v) => rows(py, v)?.into_any(),
            Codes::I64(v) => rows(py, v)?.into_any(),
        })
    }
}

/// A flat vector of `3 n` values as an `(n, 3)` array, without copying.
fn rows<T: numpy::Element>(
    py: Python<'_>,
    flat: Vec<T>,
) -> PyResult<Bound<'_, numpy::PyArray2<T>>> {
    let n = flat.len() / 3;
    flat.into_pyarray(py).reshape([n, 3])
}

/// Grid description shared by `quantize` and `cluster` results.
fn set_grid_items(out: &Bound<'_, PyDict>, grid: &Grid, centered: bool) -> PyResult<()> {
    let offset = if centered {
        f64::from(grid.centered_offset())
    } else {
        0.0
    };
    let origin: Vec<f64> = (0..3)
        .map(|a| grid.min[a] + offset * grid.step[a])
        .collect();
    out.set_item("origin", origin)?;
    out.set_item("step", grid.step.to_vec())?;
    out.set_item("box_min", grid.min.to_vec())?;
    out.set_item("box_max", grid.max.to_vec())?;
    out.set_item("grid_size", grid.grid_size())?;
    out.set_item("bound", grid.bound())?;
    out.set_item("bits", grid.bits)?;
    Ok(())
}

/// Quantizes points on a grid; returns codes, positions and the grid (see `meshbits.quantize`).
#[pyfunction]
#[pyo3(signature = (vertices, bits, grid, box_min, box_max, centered))]
fn quantize<'py>(
    py: Python<'py>,
    vertices: PyReadonlyArray2<'py, f64>,
    bits: u32,
    grid: &str,
    box_min: Option<[f64; 3]>,
    box_max: Option<[f64; 3]>,
    centered: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let kind = parse_grid(grid)?;
    let v = triples(&vertices, "vertices")?;
    let (grid, codes, positions, max_displacement) = run_detached(py, || {
        let grid = make_grid(v, bits, kind, box_min, box_max)?;
        let q = quantize_kernel(v, &grid)?;
        Ok((
            grid,
            Codes::new(q.codes, &grid, centered),
            q.positions,
            q.max_displacement,
        ))
    })?;
    let out = PyDict::new(py);
    out.set_item("codes", codes.into_py(py)?)?;
    out.set_item("positions", rows(py, positions.into_flattened())?)?;
    out.set_item("max_displacement", max_displacement)?;
    set_grid_items(&out, &grid, centered)?;
    Ok(out)
}

/// Positions `origin + codes * step` of `(n, 3)` int64 codes.
#[pyfunction]
fn dequantize<'py>(
    py: Python<'py>,
    codes: PyReadonlyArray2<'py, i64>,
    origin: [f64; 3],
    step: [f64; 3],
) -> PyResult<Bound<'py, numpy::PyArray2<f64>>> {
    let q = triples(&codes, "codes")?;
    let positions = run_detached(py, || dequantize_kernel(q, origin, step))?;
    rows(py, positions.into_flattened())
}

/// Face indices as numpy holds them: uint32, or int64 (numpy's default integer) read in
/// place by kernels generic over [`VertexIndex`].
#[derive(FromPyObject)]
enum FaceArray<'py> {
    U32(PyReadonlyArray2<'py, u32>),
    I64(PyReadonlyArray2<'py, i64>),
}

/// Rossignac-Borrel vertex clustering; returns the new mesh, maps and counts (see
/// `meshbits.cluster`). `faces` may be uint32 or int64; the kernel checks the indices.
#[pyfunction]
#[pyo3(signature = (vertices, faces, bits, grid, box_min, box_max, centered, duplicates))]
#[allow(clippy::too_many_arguments)]
fn cluster<'py>(
    py: Python<'py>,
    vertices: PyReadonlyArray2<'py, f64>,
    faces: FaceArray<'py>,
    bits: u32,
    grid: &str,
    box_min: Option<[f64; 3]>,
    box_max: Option<[f64; 3]>,
    centered: bool,
    duplicates: &str,
) -> PyResult<Bound<'py, PyDict>> {
    /// Everything but the arrays, the same for both face dtypes.
    #[derive(Clone, Copy)]
    struct ClusterOptions {
        bits: u32,
        kind: GridKind,
        box_min: Option<[f64; 3]>,
        box_max: Option<[f64; 3]>,
        centered: bool,
        duplicates: Duplicates,
    }
    fn run<I: VertexIndex>(
        py: Python<'_>,
        v: &[[f64; 3]],
        f: &[[I; 3]],
        o: ClusterOptions,
    ) -> PyResult<(Grid, Clustering, Codes)> {
        run_detached(py, || {
            let grid = make_grid(v, o.bits, o.kind, o.box_min, o.box_max)?;
            let mut c = cluster_kernel(v, f, &grid, o.duplicates)?;
            let codes = Codes::new(std::mem::take(&mut c.codes), &grid, o.centered);
            Ok((grid, c, codes))
        })
    }
    let options = ClusterOptions {
        bits,
        kind: parse_grid(grid)?,
        box_min,
        box_max,
        centered,
        duplicates: parse_duplicates(duplicates)?,
    };
    let v = triples(&vertices, "vertices")?;
    let (grid, mut c, codes) = match &faces {
        FaceArray::U32(f) => run(py, v, triples(f, "faces")?, options)?,
        FaceArray::I64(f) => run(py, v, triples(f, "faces")?, options)?,
    };
    let out = PyDict::new(py);
    out.set_item("vertices", rows(py, c.vertices.into_flattened())?)?;
    out.set_item(
        "faces",
        rows(py, std::mem::take(&mut c.faces).into_flattened())?,
    )?;
    out.set_item("codes", codes.into_py(py)?)?;
    out.set_item("vertex_map", c.vertex_map.into_pyarray(py))?;
    out.set_item(
        "face_index",
        std::mem::take(&mut c.face_index).into_pyarray(py),
    )?;
    out.set_item("merged_vertices", c.merged_vertices)?;
    out.set_item("unreferenced_vertices", c.unreferenced_vertices)?;
    out.set_item("degenerate_faces", c.degenerate_faces)?;
    out.set_item("duplicate_faces", c.duplicate_faces)?;
    out.set_item("max_displacement", c.max_displacement)?;
    set_grid_items(&out, &grid, centered)?;
    Ok(out)
}

/// meshoptimizer's vertex codec (`EXT_meshopt_compression`, version 0) over rows of
/// `stride` bytes.
#[pyfunction]
fn meshopt_encode_vertices<'py>(
    py: Python<'py>,
    data: PyReadonlyArray1<'py, u8>,
    stride: usize,
) -> PyResult<Bound<'py, PyBytes>> {
    let bytes = data
        .as_slice()
        .map_err(|e| PyValueError::new_err(format!("data is not contiguous: {e}")))?;
    let encoded = run_detached(py, || meshopt::encode_vertices(bytes, stride))?;
    Ok(PyBytes::new(py, &encoded))
}

/// meshoptimizer's index codec over a triangle list of `vertex_count` vertices.
#[pyfunction]
fn meshopt_encode_triangles<'py>(
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
fn meshopt_reorder<'py>(
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
fn meshopt_encode_octahedral<'py>(
    py: Python<'py>,
    vectors: PyReadonlyArray2<'py, f32>,
    bits: u32,
) -> PyResult<Bound<'py, PyArray2<u8>>> {
    if vectors.shape()[1] != 4 || !vectors.is_c_contiguous() {
        return Err(PyValueError::new_err(
            "vectors must be a C-contiguous (n, 4) float32 array",
        ));
    }
    let flat = vectors
        .as_slice()
        .map_err(|e| PyValueError::new_err(format!("vectors: {e}")))?;
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
fn meshopt_decode<'py>(
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

/// Faces with every vertex replaced by the smallest-index vertex of identical coordinates
/// (see [`crate::weld::weld_faces`]), and how many vertices were merged.
#[pyfunction]
fn weld<'py>(
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
fn faces_as_u32<'py>(
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

/// Sets the number of worker threads for every kernel (0 restores the default).
#[pyfunction]
fn set_num_threads(threads: usize) {
    pool::set_threads(threads);
}

/// The number of worker threads set by `set_num_threads` (0: the default).
#[pyfunction]
fn get_num_threads() -> usize {
    pool::threads()
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
    m.add_function(wrap_pyfunction!(box_overlap, m)?)?;
    m.add_function(wrap_pyfunction!(hausdorff_directed, m)?)?;
    m.add_function(wrap_pyfunction!(surface_samples, m)?)?;
    m.add_class::<PySampledMesh>()?;
    m.add_function(wrap_pyfunction!(sample_mesh, m)?)?;
    m.add_function(wrap_pyfunction!(hausdorff_from_samples, m)?)?;
    m.add_function(wrap_pyfunction!(simplify, m)?)?;
    m.add_function(wrap_pyfunction!(quantize, m)?)?;
    m.add_function(wrap_pyfunction!(dequantize, m)?)?;
    m.add_function(wrap_pyfunction!(cluster, m)?)?;
    m.add_function(wrap_pyfunction!(faces_as_u32, m)?)?;
    m.add_function(wrap_pyfunction!(weld, m)?)?;
    m.add_function(wrap_pyfunction!(meshopt_encode_vertices, m)?)?;
    m.add_function(wrap_pyfunction!(meshopt_encode_triangles, m)?)?;
    m.add_function(wrap_pyfunction!(meshopt_encode_octahedral, m)?)?;
    m.add_function(wrap_pyfunction!(meshopt_reorder, m)?)?;
    m.add_function(wrap_pyfunction!(meshopt_decode, m)?)?;
    m.add_function(wrap_pyfunction!(set_num_threads, m)?)?;
    m.add_function(wrap_pyfunction!(get_num_threads, m)?)?;
    Ok(())
}
