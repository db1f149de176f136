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

/// Signed 64-bit face indices (numpy's default integer, trimesh's face dtype) as `u32`,
/// in one parallel pass; `None` when an index lies outside `0..vertex_count` (the caller
/// then names the offending face) or `vertex_count` does not fit a `u32`.
#[must_use]
pub fn indices_from_i64(faces: &[[i64; 3]], vertex_count: usize) -> Option<Vec<[u32; 3]>> {
    use rayon::prelude::*;
    if vertex_count > u32::MAX as usize {
        return None;
    }
    let limit = i64::try_from(vertex_count).ok()?;
    faces
        .par_iter()
        .with_min_len(1 << 14)
        .map(|t| {
            let ok = t.iter().all(|&i| (0..limit).contains(&i));
            ok.then(|| t.map(|i| i as u32))
        })
        .collect()
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn i64_indices_convert_or_refuse() {
        let faces = [[0i64, 1, 2], [2, 3, 0]];
        assert_eq!(
            indices_from_i64(&faces, 4),
            Some(vec![[0u32, 1, 2], [2, 3, 0]])
        );
        assert_eq!(indices_from_i64(&faces, 3), None);
        assert_eq!(indices_from_i64(&[[0, -1, 2]], 4), None);
        assert_eq!(indices_from_i64(&[[0, 1, 1 << 40]], 4), None);
        assert_eq!(indices_from_i64(&[[0, 1, 2]], u32::MAX as usize + 1), None);
    }
}
