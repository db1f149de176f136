//! The Python binding `meshbits._core`: the only module that uses pyo3 or numpy.
//!
//! Each wrapper borrows the numpy arrays (already normalised to C-ordered float64 vertices
//! and uint32 faces by `meshbits/mesh.py`), checks their layout, releases the GIL around
//! the kernel, and converts the result. Kernel errors become subclasses of
//! `meshbits.MeshbitsError` (a `ValueError`), one per [`MeshError`](crate::MeshError)
//! variant (see `errors.rs`); a panic becomes a `RuntimeError` instead of tearing down
//! Python.
//!
//! **Files**, imports running one way (this file registers what the others define; the
//! area files use `arrays`, `pool` and `errors`): `errors.rs` (the exception classes and
//! the conversion from [`MeshError`](crate::MeshError)), `pool.rs` (`run_detached`, the
//! one fork-safe path into a kernel, and the thread count), `arrays.rs` (numpy arrays in
//! and out), and one file per area: `complexity.rs`, `tree.rs`, `hausdorff.rs`,
//! `quantize.rs`, `simplify.rs`, `codecs.rs` (meshopt), `mesh.rs` (welding, face dtypes), `io.rs` (mesh files).

use pyo3::prelude::*;

mod arrays;
mod codecs;
mod complexity;
mod errors;
mod hausdorff;
mod io;
mod mesh;
mod pool;
mod quantize;
mod simplify;
mod tree;

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    errors::register(m)?;
    m.add(
        "BUILD_PROFILE",
        if cfg!(debug_assertions) {
            "debug"
        } else {
            "release"
        },
    )?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_function(wrap_pyfunction!(complexity::shape_complexity, m)?)?;
    m.add_class::<tree::PyTriangleTree>()?;
    m.add_function(wrap_pyfunction!(tree::build_tree, m)?)?;
    m.add_function(wrap_pyfunction!(tree::build_trees, m)?)?;
    m.add_function(wrap_pyfunction!(tree::box_overlap, m)?)?;
    m.add_function(wrap_pyfunction!(hausdorff::hausdorff_directed, m)?)?;
    m.add_function(wrap_pyfunction!(hausdorff::surface_samples, m)?)?;
    m.add_class::<hausdorff::PySampledMesh>()?;
    m.add_function(wrap_pyfunction!(hausdorff::sample_mesh, m)?)?;
    m.add_function(wrap_pyfunction!(hausdorff::hausdorff_from_samples, m)?)?;
    m.add_function(wrap_pyfunction!(simplify::simplify, m)?)?;
    m.add_function(wrap_pyfunction!(quantize::quantize, m)?)?;
    m.add_function(wrap_pyfunction!(quantize::dequantize, m)?)?;
    m.add_function(wrap_pyfunction!(quantize::cluster, m)?)?;
    m.add_function(wrap_pyfunction!(mesh::faces_as_u32, m)?)?;
    m.add_function(wrap_pyfunction!(io::read_mesh, m)?)?;
    m.add_function(wrap_pyfunction!(mesh::weld, m)?)?;
    m.add_function(wrap_pyfunction!(codecs::meshopt_encode_vertices, m)?)?;
    m.add_function(wrap_pyfunction!(codecs::meshopt_encode_triangles, m)?)?;
    m.add_function(wrap_pyfunction!(codecs::meshopt_encode_octahedral, m)?)?;
    m.add_function(wrap_pyfunction!(codecs::meshopt_encode_quaternions, m)?)?;
    m.add_function(wrap_pyfunction!(codecs::meshopt_encode_exponential, m)?)?;
    m.add_function(wrap_pyfunction!(codecs::meshopt_reorder, m)?)?;
    m.add_function(wrap_pyfunction!(codecs::meshopt_decode, m)?)?;
    m.add_function(wrap_pyfunction!(pool::set_num_threads, m)?)?;
    m.add_function(wrap_pyfunction!(pool::get_num_threads, m)?)?;
    Ok(())
}
