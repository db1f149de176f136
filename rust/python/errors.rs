//! The exceptions of `meshbits._core`, and the one conversion from [`MeshError`].

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

impl From<MeshError> for PyErr {
    fn from(err: MeshError) -> PyErr {
        MeshbitsError::new_err(err.to_string())
    }
}
