//! Grid quantization and vertex clustering ([`crate::quantize`]) for `meshbits.quantize`.

use numpy::{IntoPyArray, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;

use super::arrays::{FaceArray, rows, triples};
use super::errors::ParameterError;
use super::pool::run_detached;
use crate::error::{MeshError, VertexIndex};
use crate::quantize::{Clustering, Duplicates, Grid, GridKind};
use crate::quantize::{
    cluster as cluster_kernel, dequantize as dequantize_kernel, quantize as quantize_kernel,
};

fn parse_grid(name: &str) -> PyResult<GridKind> {
    match name {
        "cube" => Ok(GridKind::Cube),
        "axes" => Ok(GridKind::Axes),
        other => Err(ParameterError::new_err(format!(
            "grid must be 'cube' or 'axes', got {other:?}"
        ))),
    }
}

fn parse_duplicates(name: &str) -> PyResult<Duplicates> {
    match name {
        "keep" => Ok(Duplicates::Keep),
        "oriented" => Ok(Duplicates::Oriented),
        "any" => Ok(Duplicates::Any),
        other => Err(ParameterError::new_err(format!(
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
pub(super) fn quantize<'py>(
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
pub(super) fn dequantize<'py>(
    py: Python<'py>,
    codes: PyReadonlyArray2<'py, i64>,
    origin: [f64; 3],
    step: [f64; 3],
) -> PyResult<Bound<'py, numpy::PyArray2<f64>>> {
    let q = triples(&codes, "codes")?;
    let positions = run_detached(py, || dequantize_kernel(q, origin, step))?;
    rows(py, positions.into_flattened())
}

/// Rossignac-Borrel vertex clustering; returns the new mesh, maps and counts (see
/// `meshbits.cluster`). `faces` may be uint32 or int64; the kernel checks the indices.
#[pyfunction]
#[pyo3(signature = (vertices, faces, bits, grid, box_min, box_max, centered, duplicates))]
#[allow(clippy::too_many_arguments)]
pub(super) fn cluster<'py>(
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
