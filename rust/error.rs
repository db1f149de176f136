//! Every way a kernel refuses its input.
//!
//! Kernels return `Result<_, MeshError>`; the binding layer (`python.rs`) maps each
//! variant to a Python exception. Nothing in the kernels panics on user data.

use std::fmt;

/// Why a kernel refused its input.
#[derive(Debug, Clone, PartialEq)]
pub enum MeshError {
    /// A slice's length is not a multiple of 3, or two related arrays disagree in length.
    Shape(String),
    /// A vertex coordinate is NaN or infinite.
    NonFinite { vertex: usize },
    /// A face refers to a vertex index `>= vertex_count`.
    IndexOutOfRange {
        face: usize,
        index: u64,
        vertex_count: usize,
    },
    /// No vertices or no faces where some are required.
    Empty(String),
    /// A parameter outside its documented range (bits, sample counts, tolerances...).
    Parameter(String),
    /// A point lies outside a caller-given quantization box.
    OutsideBox { point: usize },
}

impl fmt::Display for MeshError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MeshError::Shape(msg) => write!(f, "{msg}"),
            MeshError::NonFinite { vertex } => {
                write!(f, "vertex {vertex} has a NaN or infinite coordinate")
            }
            MeshError::IndexOutOfRange {
                face,
                index,
                vertex_count,
            } => write!(
                f,
                "face {face} refers to vertex {index}, but there are only {vertex_count} vertices"
            ),
            MeshError::Empty(msg) => write!(f, "{msg}"),
            MeshError::Parameter(msg) => write!(f, "{msg}"),
            MeshError::OutsideBox { point } => {
                write!(f, "point {point} lies outside the quantization box")
            }
        }
    }
}

impl std::error::Error for MeshError {}

/// Checks that every coordinate is finite; names the first offending vertex.
pub fn check_finite(vertices: &[[f64; 3]]) -> Result<(), MeshError> {
    match vertices
        .iter()
        .position(|v| !v.iter().all(|c| c.is_finite()))
    {
        Some(vertex) => Err(MeshError::NonFinite { vertex }),
        None => Ok(()),
    }
}

/// Checks that every face index is `< vertex_count`; names the first offending face.
pub fn check_indices(faces: &[[u32; 3]], vertex_count: usize) -> Result<(), MeshError> {
    for (face, tri) in faces.iter().enumerate() {
        for &index in tri {
            if index as usize >= vertex_count {
                return Err(MeshError::IndexOutOfRange {
                    face,
                    index: u64::from(index),
                    vertex_count,
                });
            }
        }
    }
    Ok(())
}
