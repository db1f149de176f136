//! meshoptimizer's glTF codecs (`EXT_meshopt_compression`): the vertex codec, the index
//! codec and the octahedral filter, through the `meshopt` crate.
//!
//! The vertex codec encodes a stream of fixed-size records (a multiple of 4 bytes, at most
//! 256) by byte-wise deltas between consecutive records, then entropy codes them; it is
//! lossless. `EXT_meshopt_compression` decoders read its version 0 bitstream, which is
//! what [`encode_vertices`] writes. The index codec encodes a triangle list against a small
//! cache of recent edges and vertices (lossless; version 1, which the extension reads). The
//! octahedral filter stores unit vectors (normals, tangents) as two signed K-bit components
//! of the octahedral map (Cigolle et al. 2014), the decoder reconstructing the third.

use crate::error::MeshError;

/// `EXT_meshopt_compression` reads the vertex codec's version 0 bitstream.
const VERTEX_VERSION: i32 = 0;

/// Compression level of the vertex codec (ignored by version 0, which has one).
const VERTEX_LEVEL: i32 = 2;

/// Encodes `count` records of `stride` bytes each (`data.len() == count * stride`) with
/// the vertex codec. Refuses a stride that is not a multiple of 4 in `4..=256`.
pub fn encode_vertices(data: &[u8], stride: usize) -> Result<Vec<u8>, MeshError> {
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
            VERTEX_LEVEL,
            VERTEX_VERSION,
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

/// Encodes a triangle list over `vertex_count` vertices with the index codec.
pub fn encode_triangles(indices: &[u32], vertex_count: usize) -> Result<Vec<u8>, MeshError> {
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
    meshopt::encode_index_buffer(indices, vertex_count)
        .map_err(|e| MeshError::Parameter(format!("the index codec refused the triangles: {e}")))
}

/// Unit vectors `(x, y, z, w)` (w, a tangent's handedness, kept) as octahedral signed
/// normalized integers of `bits` bits (2 to 16), 1 byte per component for `bits <= 8`,
/// else 2: 4 components per row.
pub fn encode_octahedral(vectors: &[[f32; 4]], bits: u32) -> Result<Vec<u8>, MeshError> {
    if !(2..=16).contains(&bits) {
        return Err(MeshError::Parameter(format!(
            "octahedral bits must be from 2 to 16, got {bits}"
        )));
    }
    if let Some(i) = vectors
        .iter()
        .position(|v| !v.iter().all(|c| c.is_finite()))
    {
        return Err(MeshError::Parameter(format!("vector {i} is not finite")));
    }
    let bits = bits as i32;
    Ok(if bits <= 8 {
        meshopt::encode_filter_oct::<i8>(vectors, bits)
            .into_iter()
            .flat_map(|row| row.map(|c| c as u8))
            .collect()
    } else {
        meshopt::encode_filter_oct::<i16>(vectors, bits)
            .into_iter()
            .flat_map(|row| row.into_iter().flat_map(i16::to_le_bytes))
            .collect()
    })
}

/// A triangle list reordered for the vertex cache, and its vertices renumbered in the
/// order the triangles first use them (meshoptimizer's `optimizeVertexCache`, then
/// first-use order as its `optimizeVertexFetchRemap`), the order its codecs compress best: returns the new
/// triangles and, for each new vertex, the old vertex it is. Unused vertices are dropped.
pub fn reorder_for_codecs(
    indices: &[u32],
    vertex_count: usize,
) -> Result<(Vec<u32>, Vec<u32>), MeshError> {
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
    let cached = meshopt::optimize_vertex_cache(indices, vertex_count);
    // Vertices in the order of first use (meshoptimizer's fetch remap; the crate's
    // wrapper truncates the table it returns, so the loop is here).
    let mut new_of_old = vec![u32::MAX; vertex_count];
    let mut old_of_new = Vec::with_capacity(vertex_count);
    for &i in &cached {
        if new_of_old[i as usize] == u32::MAX {
            new_of_old[i as usize] = old_of_new.len() as u32;
            old_of_new.push(i);
        }
    }
    let triangles = cached.iter().map(|&i| new_of_old[i as usize]).collect();
    Ok((triangles, old_of_new))
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

    #[test]
    fn reordering_keeps_the_triangles() {
        let indices: Vec<u32> = (0..600u32).map(|i| (i * 37) % 150).collect();
        let (triangles, old_of_new) = reorder_for_codecs(&indices, 160).unwrap();
        assert_eq!(old_of_new.len(), 150); // vertices 150..160 are unused
        let canonical = |t: [u32; 3]| {
            let k = (0..3).min_by_key(|&k| t[k]).unwrap();
            [t[k], t[(k + 1) % 3], t[(k + 2) % 3]]
        };
        let mut before: Vec<[u32; 3]> = indices
            .chunks_exact(3)
            .map(|t| canonical([t[0], t[1], t[2]]))
            .collect();
        let mut after: Vec<[u32; 3]> = triangles
            .chunks_exact(3)
            .map(|t| {
                canonical(
                    t.iter()
                        .map(|&i| old_of_new[i as usize])
                        .collect::<Vec<_>>()
                        .try_into()
                        .unwrap(),
                )
            })
            .collect();
        before.sort_unstable();
        after.sort_unstable();
        assert_eq!(before, after);
    }

    #[test]
    fn octahedral_normals_keep_their_direction() {
        let vectors: Vec<[f32; 4]> = (0..500)
            .map(|i| {
                let t = i as f32 * 0.37;
                let (x, y, z) = (t.sin() * t.cos(), (2.0 * t).sin(), t.cos());
                let n = (x * x + y * y + z * z).sqrt();
                [x / n, y / n, z / n, 1.0]
            })
            .collect();
        for (bits, tolerance_degrees) in [(8u32, 1.0f32), (12, 0.1)] {
            let mut rows: Vec<[i16; 4]> = if bits <= 8 {
                encode_octahedral(&vectors, bits)
                    .unwrap()
                    .chunks_exact(4)
                    .map(|r| [0, 1, 2, 3].map(|k| i16::from(r[k] as i8)))
                    .collect()
            } else {
                encode_octahedral(&vectors, bits)
                    .unwrap()
                    .chunks_exact(8)
                    .map(|r| [0, 1, 2, 3].map(|k| i16::from_le_bytes([r[2 * k], r[2 * k + 1]])))
                    .collect()
            };
            if bits <= 8 {
                let mut bytes: Vec<[i8; 4]> = rows.iter().map(|r| r.map(|c| c as i8)).collect();
                meshopt::decode_filter_oct(&mut bytes);
                rows = bytes.iter().map(|r| r.map(i16::from)).collect();
            } else {
                meshopt::decode_filter_oct(&mut rows);
            }
            let scale = if bits <= 8 { 127.0 } else { 32767.0 };
            for (v, r) in vectors.iter().zip(&rows) {
                let d = [r[0], r[1], r[2]].map(|c| f32::from(c) / scale);
                let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                let cos = (v[0] * d[0] + v[1] * d[1] + v[2] * d[2]) / n;
                let angle = cos.clamp(-1.0, 1.0).acos().to_degrees();
                assert!(angle < tolerance_degrees, "{bits} bits: {angle} degrees");
            }
        }
        assert!(encode_octahedral(&vectors, 1).is_err());
    }
}
