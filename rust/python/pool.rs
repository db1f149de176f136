//! Where kernels run: [`run_detached`], the one path from Python into a kernel (the GIL
//! released, on the fork-safe pool of [`crate::pool`], a panic turned into a
//! `RuntimeError`), and the thread count.

use std::panic::{AssertUnwindSafe, catch_unwind};

use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;

use crate::error::MeshError;
use crate::pool;

/// Runs a kernel with the GIL released on the fork-safe pool of [`crate::pool::run`],
/// turning a panic into a Python `RuntimeError`: the one path from Python into a kernel.
pub(super) fn run_detached<T, F>(py: Python<'_>, kernel: F) -> PyResult<T>
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

/// Sets the number of worker threads for every kernel (0 restores the default).
#[pyfunction]
pub(super) fn set_num_threads(threads: usize) {
    pool::set_threads(threads);
}

/// The number of worker threads set by `set_num_threads` (0: the default).
#[pyfunction]
pub(super) fn get_num_threads() -> usize {
    pool::threads()
}
