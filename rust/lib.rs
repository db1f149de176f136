//! meshbits: optimal bit allocation for triangle meshes (King & Rossignac, "Optimal Bit
//! Allocation in 3D Compression", 1999).
//!
//! The crate holds the hot paths: shape complexity K ([`complexity`]) over the unique-edge
//! table ([`adjacency`]); the sampled Hausdorff distance ([`hausdorff`]) over seeded surface
//! samples ([`sampling`]), a triangle BVH ([`bvh`]) and exact point-triangle distances
//! ([`closest`]). Kernels take plain slices (`&[[f64; 3]]` vertices,
//! `&[[u32; 3]]` faces), return `Result<_, MeshError>` and never panic on user data. The
//! only module that knows Python is `python/`, built with the `python` feature (the
//! extension module `meshbits._core`, which maturin builds); without it the crate builds
//! and tests from Rust alone.
//!
//! Grid quantization to B bits and vertex clustering: [`quantize`]. Vertex welding:
//! [`weld`]. Mesh files read into those arrays: [`io`]. meshoptimizer's simplifier and glTF codecs: [`meshopt`].

pub mod adjacency;
pub mod alloc;
pub mod bvh;
pub mod closest;
pub mod complexity;
pub mod error;
pub mod hausdorff;
pub mod io;
pub mod meshopt;
pub mod pool;
#[cfg(feature = "python")]
mod python;
pub mod quantize;
pub mod reduce;
pub mod sampling;
#[cfg(test)]
mod test_meshes;
pub mod weld;

pub use error::MeshError;

/// The extension's allocator (see [`alloc`]); a crate linking this library keeps its own.
#[cfg(feature = "python")]
#[global_allocator]
static GLOBAL: alloc::HugePageAlloc = alloc::HugePageAlloc;
