//! The vertex codec: fixed-size records (a multiple of 4 bytes, at most 256) encoded by
//! byte-wise deltas between consecutive records, then entropy coded; lossless. meshbits
//! writes bitstream version 0 (what `EXT_meshopt_compression` reads) and reads 0 and 1.

use super::decoded::{Decoded, decoded_len, decoder_error, too_short};
use crate::error::MeshError;

/// `EXT_meshopt_compression` reads the vertex codec's version 0 bitstream.
const VERTEX_VERSION: i32 = 0;

/// Compression level of the vertex codec (ignored by version 0, which has one).
const VERTEX_LEVEL: i32 = 2;

/// Encodes `count` records of `stride` bytes each (`data.len() == count * stride`) with
/// the vertex codec. Refuses a stride that is not a multiple of 4 in `4..=256`.
pub fn encode_vertices(data: &[u8], stride: usize) -> Result<Vec<u8>, MeshError> {
    encode_vertices_in(data, stride, VERTEX_VERSION, VERTEX_LEVEL)
}

/// [`encode_vertices`] in bitstream `version` (0 or 1) at compression `level` (0 to 3,
/// version 1 only).
pub(super) fn encode_vertices_in(
    data: &[u8],
    stride: usize,
    version: i32,
    level: i32,
) -> Result<Vec<u8>, MeshError> {
    if stride == 0 || !stride.is_multiple_of(4) || stride > 256 {
        return Err(MeshError::Parameter(format!(
            "vertex records must be a multiple of 4 bytes, at most 256, got {stride}"
        )));
    }
    if !data.len().is_multiple_of(stride) {
        return Err(MeshError::Parameter(format!(
            "{} bytes are not whole records of {stride} bytes",
            data.len()
        )));
    }
    let count = data.len() / stride;
    // SAFETY: the bound is computed for exactly these records; the encoder writes at
    // most `bound` bytes into `out`, which holds that many, and reads `count * stride`
    // bytes from `data`.
    unsafe {
        let bound = meshopt::ffi::meshopt_encodeVertexBufferBound(count, stride);
        let mut out = vec![0u8; bound];
        let size = meshopt::ffi::meshopt_encodeVertexBufferLevel(
            out.as_mut_ptr(),
            out.len(),
            data.as_ptr().cast(),
            count,
            stride,
            level,
            version,
        );
        if size == 0 && count > 0 {
            return Err(MeshError::Parameter(
                "the vertex codec could not encode the records".into(),
            ));
        }
        out.truncate(size);
        Ok(out)
    }
}

/// Refuses a vertex record size the vertex codec does not take.
pub(super) fn check_vertex_stride(stride: usize) -> Result<(), MeshError> {
    if stride == 0 || !stride.is_multiple_of(4) || stride > 256 {
        return Err(MeshError::Parameter(format!(
            "meshopt vertex records (byteStride) are a multiple of 4 bytes from 4 to 256, got \
             {stride}"
        )));
    }
    Ok(())
}

/// The fewest bytes a vertex codec stream of `count` records of `stride` bytes can have,
/// in any bitstream version: the header byte; per block of records (at most 8 KiB and
/// 256 records), `stride / 4` bytes at least (version 1's control bytes; version 0's group
/// headers take `stride`); the tail of at least 24 bytes (32 in version 0). A shorter
/// stream is refused before anything is allocated for the records it declares.
fn min_vertex_stream(count: usize, stride: usize) -> usize {
    let block = ((8192 / stride) & !15).min(256);
    let blocks = count.div_ceil(block);
    1usize
        .saturating_add(blocks.saturating_mul(stride / 4))
        .saturating_add(24)
}

/// Decodes `count` records of `stride` bytes from a vertex codec stream
/// (`meshopt_decodeVertexBuffer`), in any bitstream version meshoptimizer reads: 0 (what
/// `EXT_meshopt_compression` holds and [`encode_vertices`] writes) and 1
/// (`KHR_meshopt_compression`). Refuses a stride that is not a multiple of 4 in
/// `4..=256`, a stream too short for `count` records, and a stream the decoder refuses
/// (an unknown header, truncated, or bytes left over).
pub fn decode_vertices(data: &[u8], count: usize, stride: usize) -> Result<Decoded, MeshError> {
    check_vertex_stride(stride)?;
    let len = decoded_len(count, stride)?;
    let minimum = min_vertex_stream(count, stride);
    if data.len() < minimum {
        return Err(too_short("vertex", data, count, "records", minimum));
    }
    let mut out = Decoded::zeroed(len)?;
    // SAFETY: `out` holds `count * stride` writable bytes; the stride is one the decoder
    // takes (its debug assertions); the decoder reads at most `data.len()` bytes of `data`
    // and is documented safe on untrusted input.
    let code = unsafe {
        meshopt::ffi::meshopt_decodeVertexBuffer(
            out.as_mut_ptr(),
            count,
            stride,
            data.as_ptr(),
            data.len(),
        )
    };
    if code != 0 {
        return Err(decoder_error(code, "vertex", data, count, "records"));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vertices_round_trip() {
        let records: Vec<u8> = (0..4000u32)
            .flat_map(|i| (i * 7 % 251).to_le_bytes())
            .collect();
        let encoded = encode_vertices(&records, 8).unwrap();
        assert!(encoded.len() < records.len());
        let decoded: Vec<[u8; 8]> = meshopt::decode_vertex_buffer(&encoded, 2000).unwrap();
        assert_eq!(decoded.as_flattened(), &records[..]);
        assert!(encode_vertices(&records, 6).is_err());
        assert!(encode_vertices(&records[..10], 8).is_err());
    }
}
