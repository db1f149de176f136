//! The exceptions of `meshbits._core`, and the one conversion from [`MeshError`].
//!
//! As polars does (`crates/polars-python/src/error.rs`), each [`MeshError`] variant is its
//! own class under one base, `MeshbitsError` (a `ValueError`): `ShapeError`,
//! `NonFiniteError`, `IndexOutOfRangeError`, `EmptyMeshError`, `ParameterError` and
//! `OutsideBoxError`. The binding's own refusals use the same classes (an array's shape,
//! dtype or layout: `ShapeError`; an unknown name: `ParameterError`), so a caller's bad
//! input is always a `MeshbitsError`. A wrong argument type is pyo3's `TypeError`; a panic
//! stays a `RuntimeError` (see `pool.rs`). The subclasses live in `meshbits.errors`
//! (`python/meshbits/errors.py` re-exports them), so that they pickle across processes.

use pyo3::create_exception;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::error::MeshError;

create_exception!(
    meshbits,
    MeshbitsError,
    PyValueError,
    "Invalid input to a meshbits kernel."
);

create_exception!(
    meshbits.errors,
    ShapeError,
    MeshbitsError,
    "An array of the wrong shape, dtype or memory layout, or arrays that disagree in length."
);

create_exception!(
    meshbits.errors,
    NonFiniteError,
    MeshbitsError,
    "A vertex coordinate that is NaN or infinite."
);

create_exception!(
    meshbits.errors,
    IndexOutOfRangeError,
    MeshbitsError,
    "A face index outside 0..vertex_count: negative, or not below the vertex count."
);

create_exception!(
    meshbits.errors,
    EmptyMeshError,
    MeshbitsError,
    "No vertices or no faces where some are required."
);

create_exception!(
    meshbits.errors,
    ParameterError,
    MeshbitsError,
    "A parameter outside its documented range (bits, sample counts, tolerances, names...)."
);

create_exception!(
    meshbits.errors,
    OutsideBoxError,
    MeshbitsError,
    "A point outside a caller-given quantization box."
);

impl From<MeshError> for PyErr {
    fn from(err: MeshError) -> PyErr {
        let message = err.to_string();
        match err {
            MeshError::Shape(_) => ShapeError::new_err(message),
            MeshError::NonFinite { .. } => NonFiniteError::new_err(message),
            MeshError::IndexOutOfRange { .. } => IndexOutOfRangeError::new_err(message),
            MeshError::Empty(_) => EmptyMeshError::new_err(message),
            MeshError::Parameter(_) => ParameterError::new_err(message),
            MeshError::OutsideBox { .. } => OutsideBoxError::new_err(message),
        }
    }
}

/// Adds the exception classes to the module `m`.
pub(super) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("MeshbitsError", py.get_type::<MeshbitsError>())?;
    m.add("ShapeError", py.get_type::<ShapeError>())?;
    m.add("NonFiniteError", py.get_type::<NonFiniteError>())?;
    m.add(
        "IndexOutOfRangeError",
        py.get_type::<IndexOutOfRangeError>(),
    )?;
    m.add("EmptyMeshError", py.get_type::<EmptyMeshError>())?;
    m.add("ParameterError", py.get_type::<ParameterError>())?;
    m.add("OutsideBoxError", py.get_type::<OutsideBoxError>())?;
    Ok(())
}
