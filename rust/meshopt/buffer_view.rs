//! One `bufferView` of `EXT_meshopt_compression` / `KHR_meshopt_compression` decoded as
//! its extension object declares it (`count`, `byteStride`, `mode`, `filter`), the
//! extension's rules checked first.

use super::decoded::Decoded;
use super::filter::{Filter, decode_filter};
use super::index_codec::{decode_index_sequence, decode_triangles};
use super::vertex_codec::{check_vertex_stride, decode_vertices};
use crate::error::MeshError;

/// A compression mode of a `bufferView` (the extension object's `mode`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// `"ATTRIBUTES"`: the vertex codec (`meshopt_decodeVertexBuffer`), `count` records of
    /// `byteStride` bytes (a multiple of 4, at most 256).
    Attributes,
    /// `"TRIANGLES"`: the index codec (`meshopt_decodeIndexBuffer`), a triangle list of
    /// `count` indices (a multiple of 3) of `byteStride` bytes (2 or 4).
    Triangles,
    /// `"INDICES"`: the index sequence codec (`meshopt_decodeIndexSequence`), `count`
    /// indices of any topology, of `byteStride` bytes (2 or 4).
    Indices,
}

impl Mode {
    /// The mode the extension calls `name`.
    pub fn from_name(name: &str) -> Result<Mode, MeshError> {
        match name {
            "ATTRIBUTES" => Ok(Mode::Attributes),
            "TRIANGLES" => Ok(Mode::Triangles),
            "INDICES" => Ok(Mode::Indices),
            other => Err(MeshError::Parameter(format!(
                "unknown meshopt mode {other:?} (ATTRIBUTES, TRIANGLES or INDICES)"
            ))),
        }
    }
}

/// Decodes one `bufferView` of `EXT_meshopt_compression` or `KHR_meshopt_compression`:
/// `data`, the compressed bytes its extension object points at, holding `count` elements
/// of `stride` bytes (`byteStride`) in `mode`, with `filter`; returns the `count * stride`
/// bytes of the plain bufferView. The extension's rules are checked: ATTRIBUTES records
/// are a multiple of 4 bytes up to 256; TRIANGLES and INDICES take 2- or 4-byte indices
/// and no filter; TRIANGLES a multiple of 3 of them; each filter its strides.
pub fn decode_buffer_view(
    data: &[u8],
    count: usize,
    stride: usize,
    mode: Mode,
    filter: Filter,
) -> Result<Decoded, MeshError> {
    if mode != Mode::Attributes && filter != Filter::None {
        return Err(MeshError::Parameter(format!(
            "the {} filter applies to ATTRIBUTES streams only, not index streams",
            filter.name()
        )));
    }
    match mode {
        Mode::Attributes => {
            check_vertex_stride(stride)?;
            filter.check_stride(stride)?;
            let mut rows = decode_vertices(data, count, stride)?;
            decode_filter(&mut rows, stride, filter)?;
            Ok(rows)
        }
        Mode::Triangles => decode_triangles(data, count, stride),
        Mode::Indices => decode_index_sequence(data, count, stride),
    }
}
