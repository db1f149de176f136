//! The sampled Hausdorff distance ([`crate::hausdorff`]) and the sample sets
//! ([`crate::sampling`]) for `meshbits.hausdorff`.

use numpy::{IntoPyArray, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use super::arrays::{triples, triples_to_array};
use super::pool::run_detached;
use super::tree::PyTriangleTree;
use crate::hausdorff::{self, Options};
use crate::sampling;

/// One-sided sampled Hausdorff distance from a mesh to a tree; a dict of raw results
/// (see `meshbits.hausdorff`).
#[pyfunction]
#[pyo3(signature = (vertices, faces, tree, samples, seed, statistics, bounds, tolerance, refine_budget, return_samples, threshold = None, relative_tolerance = None))]
#[allow(clippy::too_many_arguments)]
pub(super) fn hausdorff_directed<'py>(
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
pub(super) fn surface_samples<'py>(
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
pub(super) struct PySampledMesh {
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
pub(super) fn sample_mesh<'py>(
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
pub(super) fn hausdorff_from_samples<'py>(
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
