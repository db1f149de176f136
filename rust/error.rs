//! Every way a kernel refuses its input.
//!
//! Kernels return `Result<_, MeshError>`; the binding layer (`python/errors.rs`) maps each
//! variant to a Python exception. Nothing in the kernels panics on user data.

use std::fmt;

/// Why a kernel refused its input.
#[derive(Debug, Clone, PartialEq)]
pub enum MeshError {
    /// A slice's length is not a multiple of 3, or two related arrays disagree in length.
    Shape(String),
    /// A vertex coordinate is NaN or infinite.
    NonFinite { vertex: usize },
    /// A face refers to a vertex index outside `0..vertex_count`.
    IndexOutOfRange {
        face: usize,
        index: i64,
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
            MeshError::IndexOutOfRange { face, index, .. } if *index < 0 => {
                write!(f, "face {face} has a negative vertex index ({index})")
            }
            MeshError::IndexOutOfRange {
                face,
                index,
                vertex_count,
            } => write!(
                f,
                "face {face} refers to vertex {index}, out of range: there are only \
                 {vertex_count} vertices"
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

/// Largest extent (length) of a mesh, and distance of a query from a tree's centre, that
/// the kernels accept: recentred coordinates beyond it do not fit the BVH's f32 boxes,
/// and their squares approach the float64 range.
pub const MAX_EXTENT: f64 = 1e36;

/// Refuses a box `[lo, hi]` wider than [`MAX_EXTENT`] on some axis.
pub fn check_extent(lo: [f64; 3], hi: [f64; 3]) -> Result<(), MeshError> {
    let span = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
    if span > MAX_EXTENT {
        return Err(MeshError::Parameter(format!(
            "the mesh spans {span:.3e} (length): more than the supported {MAX_EXTENT:.0e}"
        )));
    }
    Ok(())
}

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
    faces
        .par_iter()
        .with_min_len(1 << 14)
        .map(|t| {
            let ok = t.iter().all(|&i| i.to_usize() < vertex_count);
            ok.then(|| t.map(|i| i as u32))
        })
        .collect()
}

/// An integer type that face arrays arrive in: `u32`, or `i64` (numpy's default integer,
/// trimesh's face dtype) read without a conversion pass.
pub trait VertexIndex: Copy + Send + Sync {
    /// The index as `usize`; a negative `i64` becomes a value above any vertex count, so
    /// one bounds check `index < vertex_count` refuses it too.
    fn to_usize(self) -> usize;
    /// The index as given, for error messages.
    fn to_i64(self) -> i64;
}

impl VertexIndex for u32 {
    #[inline]
    fn to_usize(self) -> usize {
        self as usize
    }
    #[inline]
    fn to_i64(self) -> i64 {
        i64::from(self)
    }
}

impl VertexIndex for i64 {
    #[inline]
    fn to_usize(self) -> usize {
        usize::try_from(self).unwrap_or(usize::MAX)
    }
    #[inline]
    fn to_i64(self) -> i64 {
        self
    }
}

/// Checks that every face index lies in `0..vertex_count`; names the first offending
/// face.
pub fn check_indices<I: VertexIndex>(
    faces: &[[I; 3]],
    vertex_count: usize,
) -> Result<(), MeshError> {
    for (face, tri) in faces.iter().enumerate() {
        for &index in tri {
            if index.to_usize() >= vertex_count {
                return Err(MeshError::IndexOutOfRange {
                    face,
                    index: index.to_i64(),
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

    #[test]
    fn index_checks_name_negative_and_too_large_indices() {
        assert_eq!(check_indices(&[[0i64, 1, 2], [2, 1, 0]], 3), Ok(()));
        let negative = check_indices(&[[0i64, 1, 2], [2, -1, 0]], 3).unwrap_err();
        assert_eq!(
            negative,
            MeshError::IndexOutOfRange {
                face: 1,
                index: -1,
                vertex_count: 3
            }
        );
        assert!(negative.to_string().contains("negative vertex index (-1)"));
        let large = check_indices(&[[0i64, 1, i64::MAX]], 3).unwrap_err();
        assert!(
            large
                .to_string()
                .contains(&format!("vertex {}, out of range", i64::MAX))
        );
        let large = check_indices(&[[0u32, 3, 1]], 3).unwrap_err();
        assert!(
            large
                .to_string()
                .starts_with("face 0 refers to vertex 3, out of range")
        );
    }
}
