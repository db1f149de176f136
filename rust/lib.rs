//! meshbits: optimal bit allocation for triangle meshes (King & Rossignac, "Optimal Bit
//! Allocation in 3D Compression", 1999).
//!
//! The crate holds the hot paths: shape complexity K ([`complexity`]) over the unique-edge
//! table ([`adjacency`]); the sampled Hausdorff distance ([`hausdorff`]) over seeded surface
//! samples ([`sampling`]), a triangle BVH ([`bvh`]) and exact point-triangle distances
//! ([`closest`]). Kernels take plain slices (`&[[f64; 3]]` vertices,
//! `&[[u32; 3]]` faces), return `Result<_, MeshError>` and never panic on user data; the
//! only file that knows Python is [`python`].
//!
//! Grid quantization to B bits and vertex clustering: [`quantize`].

pub mod adjacency;
pub mod alloc;
pub mod bvh;
pub mod closest;
pub mod codec;
pub mod complexity;
pub mod error;
pub mod hausdorff;
pub mod pool;
mod python;
pub mod quantize;
pub mod sampling;
pub mod simplify;

pub use error::MeshError;

#[global_allocator]
static GLOBAL: alloc::HugePageAlloc = alloc::HugePageAlloc;
