//! Mesh files read straight into the kernels' arrays: `(n, 3)` `f64` vertices and
//! `(m, 3)` `u32` triangles, through a memory map, parsed in parallel.
//!
//! Formats: PLY (binary little and big endian, ASCII; [`ply`]), STL (binary and ASCII;
//! [`stl`]) and OBJ (`v` and `f` lines; [`obj`]). Polygons are fan-triangulated
//! (`a b c d` gives `a b c` and `a c d`) and counted in [`MeshRead`]; what a reader leaves
//! out (OBJ lines and points) is counted too.
//!
//! A reader never guesses: a file it does not read exactly as the general reader would
//! (a layout it does not handle, a damaged file, an index out of range, a NaN coordinate)
//! gives [`ReadError::Fallback`] with the reason, and the caller hands the file to the
//! general reader (trimesh in the Python package), whose checks and messages then apply.
//!
//! **Memory**: the output arrays are allocated once, at their final size, and written in
//! place by the worker threads (binary formats; the text formats gather each chunk's rows
//! and copy them once). The mapped file's pages are released as each chunk is parsed
//! ([`mapped::Mapped::release`]), so that the resident set holds the arrays and a few
//! chunks of the file, not the whole file.

pub mod mapped;
pub mod obj;
pub mod ply;
pub mod stl;
mod text;

use std::path::Path;

pub use mapped::Mapped;

/// A mesh file as the kernels take it, and what reading it changed or left out.
#[derive(Debug, Clone, Default)]
pub struct MeshRead {
    /// Vertex positions (the file's coordinates, widened to `f64`), in file order.
    pub vertices: Vec<[f64; 3]>,
    /// Triangles (vertex indices from 0), in file order; a polygon's fan in place.
    pub faces: Vec<[u32; 3]>,
    /// Faces of more than three corners, fan-triangulated.
    pub polygons: usize,
    /// Triangles those polygons became.
    pub polygon_triangles: usize,
    /// OBJ lines (`l`) and points (`p`), left out.
    pub skipped_elements: usize,
}

/// Why a file was not read here.
#[derive(Debug)]
pub enum ReadError {
    /// The file is not one this reader reads exactly (its layout, or damage): the general
    /// reader should read or refuse it. The text says why, for the record.
    Fallback(String),
    /// The file could not be opened or mapped.
    Io(std::io::Error),
}

impl From<std::io::Error> for ReadError {
    fn from(err: std::io::Error) -> Self {
        ReadError::Io(err)
    }
}

/// Shorthand for a [`ReadError::Fallback`].
pub(crate) fn fallback<T>(why: impl Into<String>) -> Result<T, ReadError> {
    Err(ReadError::Fallback(why.into()))
}

/// The formats read here, by the name the Python package gives them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    Ply,
    Stl,
    Obj,
}

impl Format {
    /// `"ply"`, `"stl"` or `"obj"`; `None` for another name.
    #[must_use]
    pub fn from_name(name: &str) -> Option<Format> {
        match name {
            "ply" => Some(Format::Ply),
            "stl" => Some(Format::Stl),
            "obj" => Some(Format::Obj),
            _ => None,
        }
    }
}

/// Reads the mesh file at `path` in `format`.
///
/// # Errors
/// [`ReadError::Io`] when the file cannot be opened or mapped; [`ReadError::Fallback`]
/// when it is not one this reader reads exactly.
pub fn read_mesh(path: &Path, format: Format) -> Result<MeshRead, ReadError> {
    let mapped = Mapped::open(path)?;
    if mapped.bytes().is_empty() {
        return fallback("the file is empty");
    }
    let read = match format {
        Format::Ply => ply::read(&mapped)?,
        Format::Stl => stl::read(&mapped)?,
        Format::Obj => obj::read(&mapped)?,
    };
    if read.faces.is_empty() {
        return fallback("no triangles");
    }
    Ok(read)
}

/// Refuses (as a fallback) a vertex with a NaN or infinite coordinate.
pub(crate) fn check_finite(vertices: &[[f64; 3]]) -> Result<(), ReadError> {
    use rayon::prelude::*;
    let bad = vertices
        .par_iter()
        .with_min_len(1 << 14)
        .any(|v| !(v[0].is_finite() && v[1].is_finite() && v[2].is_finite()));
    if bad {
        return fallback("a NaN or infinite coordinate");
    }
    Ok(())
}

/// Pushes the fan of polygon `corners` (`a b c d ...` gives `a b c`, `a c d`, ...) onto
/// `out`, each index checked against `vertex_count`; counts the polygon in `counts`.
/// `None` when an index is out of range or the face has fewer than three corners (the
/// general reader decides what such a file is).
#[inline]
pub(crate) fn push_fan(
    corners: &[u32],
    vertex_count: usize,
    out: &mut Vec<[u32; 3]>,
    counts: &mut FaceCounts,
) -> Option<()> {
    if corners.len() < 3 || corners.iter().any(|&i| i as usize >= vertex_count) {
        return None;
    }
    if corners.len() > 3 {
        counts.polygons += 1;
        counts.polygon_triangles += corners.len() - 2;
    }
    for k in 1..corners.len() - 1 {
        out.push([corners[0], corners[k], corners[k + 1]]);
    }
    Some(())
}

/// What a chunk of faces changed or left out (summed over chunks into [`MeshRead`]).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct FaceCounts {
    pub polygons: usize,
    pub polygon_triangles: usize,
    pub skipped_elements: usize,
}

impl FaceCounts {
    pub(crate) fn add(mut self, other: FaceCounts) -> FaceCounts {
        self.polygons += other.polygons;
        self.polygon_triangles += other.polygon_triangles;
        self.skipped_elements += other.skipped_elements;
        self
    }

    pub(crate) fn into_read(self, vertices: Vec<[f64; 3]>, faces: Vec<[u32; 3]>) -> MeshRead {
        MeshRead {
            vertices,
            faces,
            polygons: self.polygons,
            polygon_triangles: self.polygon_triangles,
            skipped_elements: self.skipped_elements,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read_bytes(data: &[u8], format: Format) -> Result<MeshRead, ReadError> {
        let mapped = Mapped::from_bytes(data.to_vec());
        match format {
            Format::Ply => ply::read(&mapped),
            Format::Stl => stl::read(&mapped),
            Format::Obj => obj::read(&mapped),
        }
    }

    const HEAD: &str = "ply\nformat binary_big_endian 1.0\nelement vertex 4\n\
        property double y\nproperty float x\nproperty double z\nelement face 2\n\
        property list ushort uint vertex_indices\nend_header\n";

    fn quad_and_triangle() -> Vec<u8> {
        let mut data = HEAD.as_bytes().to_vec();
        for (x, y, z) in [
            (0.0f32, 0.0, 0.0),
            (1.0, 0.0, 0.0),
            (1.0, 1.0, 0.0),
            (0.0, 1.0, 0.5),
        ] {
            data.extend(f64::to_be_bytes(y));
            data.extend(f32::to_be_bytes(x));
            data.extend(f64::to_be_bytes(z));
        }
        for face in [&[0u32, 1, 2, 3][..], &[0, 2, 3]] {
            data.extend((face.len() as u16).to_be_bytes());
            for i in face {
                data.extend(i.to_be_bytes());
            }
        }
        data
    }

    #[test]
    fn a_big_endian_ply_of_mixed_polygons_is_read_and_counted() {
        let read = read_bytes(&quad_and_triangle(), Format::Ply).unwrap();
        assert_eq!(read.vertices[3], [0.0, 1.0, 0.5]);
        assert_eq!(read.faces, vec![[0, 1, 2], [0, 2, 3], [0, 2, 3]]);
        assert_eq!((read.polygons, read.polygon_triangles), (1, 2));
    }

    #[test]
    fn truncated_or_out_of_range_files_fall_back() {
        let data = quad_and_triangle();
        for cut in [data.len() - 1, HEAD.len() + 10, 20] {
            assert!(matches!(
                read_bytes(&data[..cut], Format::Ply),
                Err(ReadError::Fallback(_))
            ));
        }
        let mut bad = data.clone();
        let last = bad.len() - 4;
        bad[last..].copy_from_slice(&9u32.to_be_bytes());
        assert!(matches!(
            read_bytes(&bad, Format::Ply),
            Err(ReadError::Fallback(_))
        ));
    }

    #[test]
    fn huge_declared_counts_fall_back_without_allocating() {
        for count in ["9223372036854775807", "18446744073709551615", "4294967295"] {
            let data = HEAD.replace("element face 2", &format!("element face {count}"));
            let mut bytes = data.into_bytes();
            bytes.extend(&quad_and_triangle()[HEAD.len()..]);
            assert!(matches!(
                read_bytes(&bytes, Format::Ply),
                Err(ReadError::Fallback(_))
            ));
        }
    }

    #[test]
    fn obj_negative_indices_and_corner_forms() {
        let text =
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf -4/1 -3/2 -2/3 -1/1\nl 1 2\nf 1//1 2//1 4//1\n";
        let read = read_bytes(text, Format::Obj).unwrap();
        assert_eq!(read.faces, vec![[0, 1, 2], [0, 2, 3], [0, 1, 3]]);
        assert_eq!((read.polygons, read.skipped_elements), (1, 1));
        assert!(matches!(
            read_bytes(b"v 0 0 0\nf 1 2 3\n", Format::Obj),
            Err(ReadError::Fallback(_))
        ));
    }

    #[test]
    fn binary_and_ascii_stl_read_as_soups() {
        let mut data = vec![0u8; 80];
        data.extend(1u32.to_le_bytes());
        for value in [
            0.0f32, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0,
        ] {
            data.extend(value.to_le_bytes());
        }
        data.extend([0, 0]);
        let read = read_bytes(&data, Format::Stl).unwrap();
        assert_eq!(
            read.vertices,
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
        );
        let text = b"solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n\
            vertex 0 1 0\nendloop\nendfacet\nendsolid t\n";
        let ascii = read_bytes(text, Format::Stl).unwrap();
        assert_eq!(
            (ascii.vertices, ascii.faces),
            (read.vertices, vec![[0, 1, 2]])
        );
    }
}
