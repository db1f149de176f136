//! The index codecs: a triangle list encoded against a small cache of recent edges and
//! vertices (lossless; version 1, which the extension reads; its `TRIANGLES` mode), and
//! the index sequence codec (any topology; its `INDICES` mode), decoded only.

use super::decoded::{Decoded, decoded_len, decoder_error, too_short};
use crate::error::MeshError;

/// Refuses an index list that is not a triangle list over `vertex_count` vertices: a
/// length that is not a multiple of 3, or an index out of range (naming its face).
pub(super) fn check_triangle_list(indices: &[u32], vertex_count: usize) -> Result<(), MeshError> {
    if !indices.len().is_multiple_of(3) {
        return Err(MeshError::Parameter(format!(
            "a triangle list has a multiple of 3 indices, got {}",
            indices.len()
        )));
    }
    if let Some(i) = indices.iter().position(|&i| i as usize >= vertex_count) {
        return Err(MeshError::IndexOutOfRange {
            face: i / 3,
            index: i64::from(indices[i]),
            vertex_count,
        });
    }
    Ok(())
}

/// Encodes a triangle list over `vertex_count` vertices with the index codec.
pub fn encode_triangles(indices: &[u32], vertex_count: usize) -> Result<Vec<u8>, MeshError> {
    check_triangle_list(indices, vertex_count)?;
    meshopt::encode_index_buffer(indices, vertex_count)
        .map_err(|e| MeshError::Parameter(format!("the index codec refused the triangles: {e}")))
}

/// Refuses an index size other than 2 or 4 bytes.
fn check_index_size(size: usize) -> Result<(), MeshError> {
    if size == 2 || size == 4 {
        Ok(())
    } else {
        Err(MeshError::Parameter(format!(
            "meshopt indices are 2 or 4 bytes (byteStride), got {size}"
        )))
    }
}

/// Decodes a triangle list of `count` indices (a multiple of 3) of `index_size` bytes (2
/// or 4, little-endian) from an index codec stream (`meshopt_decodeIndexBuffer`, the
/// extension's `TRIANGLES` mode). The indices are not checked against any vertex count: a
/// corrupt stream may decode to indices out of range.
pub fn decode_triangles(
    data: &[u8],
    count: usize,
    index_size: usize,
) -> Result<Decoded, MeshError> {
    check_index_size(index_size)?;
    if !count.is_multiple_of(3) {
        return Err(MeshError::Parameter(format!(
            "a meshopt TRIANGLES stream has a multiple of 3 indices, got a count of {count}"
        )));
    }
    // The decoder's own minimum: the header, a byte a triangle, a 16-byte table.
    let minimum = 1 + count / 3 + 16;
    // SAFETY: `out` holds `count * index_size` writable bytes, 4-byte aligned; `count` is
    // a multiple of 3 and `index_size` 2 or 4 (the decoder's debug assertions); it reads
    // at most `data.len()` bytes of `data`.
    decode_indices("index", data, count, index_size, minimum, |out| unsafe {
        meshopt::ffi::meshopt_decodeIndexBuffer(out, count, index_size, data.as_ptr(), data.len())
    })
}

/// Decodes `count` indices of `index_size` bytes (2 or 4, little-endian) from an index
/// sequence codec stream (`meshopt_decodeIndexSequence`, the extension's `INDICES` mode:
/// any topology). The indices are not checked against any vertex count.
pub fn decode_index_sequence(
    data: &[u8],
    count: usize,
    index_size: usize,
) -> Result<Decoded, MeshError> {
    // The decoder's own minimum: the header, a byte an index, a 4-byte tail.
    let minimum = count.saturating_add(5);
    // SAFETY: `out` holds `count * index_size` writable bytes, 4-byte aligned, and
    // `index_size` is 2 or 4; the decoder reads at most `data.len()` bytes of `data`.
    decode_indices(
        "index sequence",
        data,
        count,
        index_size,
        minimum,
        |out| unsafe {
            meshopt::ffi::meshopt_decodeIndexSequence(
                out,
                count,
                index_size,
                data.as_ptr(),
                data.len(),
            )
        },
    )
}

/// `count` indices of `index_size` bytes (2 or 4) from `data` by `decode`, which writes
/// them to the buffer it is given and returns the C decoder's code: the checks both index
/// codecs share (the index size, the stream's `minimum` length, the code).
fn decode_indices(
    codec: &str,
    data: &[u8],
    count: usize,
    index_size: usize,
    minimum: usize,
    decode: impl FnOnce(*mut std::ffi::c_void) -> i32,
) -> Result<Decoded, MeshError> {
    check_index_size(index_size)?;
    let len = decoded_len(count, index_size)?;
    if data.len() < minimum {
        return Err(too_short(codec, data, count, "indices", minimum));
    }
    let mut out = Decoded::zeroed(len)?;
    let code = decode(out.as_mut_ptr());
    if code != 0 {
        return Err(decoder_error(code, codec, data, count, "indices"));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn triangles_round_trip() {
        let indices: Vec<u32> = (0..300u32).map(|i| (i * 13) % 100).collect();
        let encoded = encode_triangles(&indices, 100).unwrap();
        let decoded: Vec<u32> = meshopt::decode_index_buffer(&encoded, indices.len()).unwrap();
        // The codec may rotate a triangle's corners (its winding stays).
        let canonical = |t: &[u32]| {
            let k = (0..3).min_by_key(|&k| t[k]).unwrap();
            [t[k], t[(k + 1) % 3], t[(k + 2) % 3]]
        };
        let rotated: Vec<[u32; 3]> = decoded.chunks_exact(3).map(canonical).collect();
        let expected: Vec<[u32; 3]> = indices.chunks_exact(3).map(canonical).collect();
        assert_eq!(rotated, expected);
        assert!(encode_triangles(&indices, 50).is_err());
        assert!(encode_triangles(&indices[..4], 100).is_err());
    }
}
