//! meshoptimizer's glTF codecs (`EXT_meshopt_compression`, `KHR_meshopt_compression`),
//! through the `meshopt` crate: the encoders meshbits writes with (the vertex codec, the
//! index codec, the octahedral filter) and the decoders it reads with (the vertex, index
//! and index sequence codecs and the extensions' filters).
//!
//! The vertex codec encodes a stream of fixed-size records (a multiple of 4 bytes, at most
//! 256) by byte-wise deltas between consecutive records, then entropy codes them; it is
//! lossless. `EXT_meshopt_compression` decoders read its version 0 bitstream, which is
//! what [`encode_vertices`] writes. The index codec encodes a triangle list against a small
//! cache of recent edges and vertices (lossless; version 1, which the extension reads). The
//! octahedral filter stores unit vectors (normals, tangents) as two signed K-bit components
//! of the octahedral map (Cigolle et al. 2014), the decoder reconstructing the third.
//!
//! The decoders ([`decode_buffer_view`] and the functions it calls) take what a glTF
//! `bufferView`'s extension object declares (`count`, `byteStride`, `mode`, `filter`),
//! check it against the extension's rules before calling meshoptimizer's C decoders (whose
//! own checks are debug assertions), and turn every failure of a decoder on a corrupt or
//! truncated stream into a [`MeshError`]. They are safe on untrusted input: meshoptimizer
//! documents them so (a corrupt stream may decode to garbage, such as indices out of
//! range, which the glTF reader checks), and no buffer is allocated before the stream is
//! long enough for what it declares.

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
fn encode_vertices_in(
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

// --- decoding ---------------------------------------------------------------------------

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

/// A filter undone on the records after the vertex codec (the extension object's
/// `filter`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Filter {
    /// `"NONE"`: the records as the vertex codec decodes them.
    None,
    /// `"OCTAHEDRAL"` (`meshopt_decodeFilterOct`): unit vectors from two signed K-bit
    /// octahedral components, the third holding `2^(K-1) - 1` (1.0, which gives K): signed
    /// normalized bytes (stride 4) or shorts (stride 8), the fourth component kept.
    Octahedral,
    /// `"QUATERNION"` (`meshopt_decodeFilterQuat`): unit quaternions from their three
    /// smallest K-bit components and the index of the largest; shorts, stride 8.
    Quaternion,
    /// `"EXPONENTIAL"` (`meshopt_decodeFilterExp`): each 32-bit word an 8-bit signed
    /// exponent `E` over a 24-bit signed mantissa `M`, decoded to the float32 `M * 2^E`;
    /// stride a multiple of 4.
    Exponential,
    /// `"COLOR"` (`meshopt_decodeFilterColor`; `KHR_meshopt_compression` only): RGBA
    /// from K-bit YCoCg and alpha, as unsigned normalized bytes (stride 4) or shorts
    /// (stride 8).
    Color,
}

impl Filter {
    /// The filter the extension calls `name`.
    pub fn from_name(name: &str) -> Result<Filter, MeshError> {
        match name {
            "NONE" => Ok(Filter::None),
            "OCTAHEDRAL" => Ok(Filter::Octahedral),
            "QUATERNION" => Ok(Filter::Quaternion),
            "EXPONENTIAL" => Ok(Filter::Exponential),
            "COLOR" => Ok(Filter::Color),
            other => Err(MeshError::Parameter(format!(
                "unknown meshopt filter {other:?} (NONE, OCTAHEDRAL, QUATERNION, EXPONENTIAL \
                 or COLOR)"
            ))),
        }
    }

    /// The filter's name in the extension.
    pub fn name(self) -> &'static str {
        match self {
            Filter::None => "NONE",
            Filter::Octahedral => "OCTAHEDRAL",
            Filter::Quaternion => "QUATERNION",
            Filter::Exponential => "EXPONENTIAL",
            Filter::Color => "COLOR",
        }
    }

    /// Refuses a record size the filter does not decode (the extension's stride rules).
    fn check_stride(self, stride: usize) -> Result<(), MeshError> {
        let (ok, rule) = match self {
            Filter::None => (true, ""),
            Filter::Octahedral | Filter::Color => (stride == 4 || stride == 8, "4 or 8"),
            Filter::Quaternion => (stride == 8, "8"),
            Filter::Exponential => (stride > 0 && stride.is_multiple_of(4), "a multiple of 4"),
        };
        if ok {
            Ok(())
        } else {
            Err(MeshError::Parameter(format!(
                "the {} filter needs a byteStride of {rule}, got {stride}",
                self.name()
            )))
        }
    }
}

/// Decoded bytes, held in 4-byte-aligned storage: the index decoders and the filters
/// write 16- and 32-bit integers in place.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Decoded {
    words: Vec<u32>,
    len: usize,
}

impl Decoded {
    /// `len` zero bytes; an allocation that fails is refused, not an abort.
    fn zeroed(len: usize) -> Result<Decoded, MeshError> {
        let n = len.div_ceil(4);
        let mut words = Vec::new();
        words.try_reserve_exact(n).map_err(|_| {
            MeshError::Parameter(format!("{len} bytes of decoded data do not fit in memory"))
        })?;
        words.resize(n, 0);
        Ok(Decoded { words, len })
    }

    /// A copy of `bytes` (for [`decode_filter`] on records decoded elsewhere).
    pub fn from_bytes(bytes: &[u8]) -> Result<Decoded, MeshError> {
        let mut out = Decoded::zeroed(bytes.len())?;
        out.as_bytes_mut().copy_from_slice(bytes);
        Ok(out)
    }

    /// The decoded bytes.
    pub fn as_bytes(&self) -> &[u8] {
        // SAFETY: `words` holds `4 * words.len() >= len` initialised bytes; `u8` has no
        // alignment requirement and no invalid values.
        unsafe { std::slice::from_raw_parts(self.words.as_ptr().cast::<u8>(), self.len) }
    }

    fn as_bytes_mut(&mut self) -> &mut [u8] {
        // SAFETY: as in `as_bytes`; the slice borrows `self` mutably.
        unsafe { std::slice::from_raw_parts_mut(self.words.as_mut_ptr().cast::<u8>(), self.len) }
    }

    /// How many bytes.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

/// `count * size`, refused when it overflows.
fn decoded_len(count: usize, size: usize) -> Result<usize, MeshError> {
    count.checked_mul(size).ok_or_else(|| {
        MeshError::Parameter(format!(
            "{count} elements of {size} bytes overflow the address space"
        ))
    })
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

/// Refuses a vertex record size the vertex codec does not take.
fn check_vertex_stride(stride: usize) -> Result<(), MeshError> {
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

/// A stream shorter than the fewest bytes its declared elements need.
fn too_short(codec: &str, data: &[u8], count: usize, what: &str, minimum: usize) -> MeshError {
    MeshError::Parameter(format!(
        "the meshopt {codec} stream has {} bytes, fewer than the {minimum} its {count} {what} \
         need at least: truncated or corrupt",
        data.len()
    ))
}

/// A C decoder's failure (its nonzero return code) in words.
fn decoder_error(code: i32, codec: &str, data: &[u8], count: usize, what: &str) -> MeshError {
    let reason = match code {
        -1 => format!(
            "its header byte (0x{:02x}) is not one this decoder reads: not {codec} codec \
             data, or a newer version of it",
            data.first().copied().unwrap_or(0)
        ),
        -2 => format!("it ends before its {count} {what} are decoded: truncated or corrupt"),
        -3 => format!(
            "its bytes do not end where its {count} {what} do: truncated, corrupt, or its \
             count or byteStride is not the one it was written with"
        ),
        other => format!("the decoder failed (code {other}): corrupt"),
    };
    MeshError::Parameter(format!(
        "the meshopt {codec} stream ({} bytes) cannot be decoded: {reason}",
        data.len()
    ))
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
            out.words.as_mut_ptr().cast(),
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
    let code = decode(out.words.as_mut_ptr().cast());
    if code != 0 {
        return Err(decoder_error(code, codec, data, count, "indices"));
    }
    Ok(out)
}

/// Undoes `filter` in place on `rows`, records of `stride` bytes (see [`Filter`] for what
/// each decodes and the strides it takes). Refuses a stride the filter does not take and
/// rows that are not whole records.
pub fn decode_filter(rows: &mut Decoded, stride: usize, filter: Filter) -> Result<(), MeshError> {
    filter.check_stride(stride)?;
    if filter == Filter::None {
        return Ok(());
    }
    if !rows.len.is_multiple_of(stride) {
        return Err(MeshError::Parameter(format!(
            "{} bytes are not whole records of {stride} bytes",
            rows.len
        )));
    }
    let count = rows.len / stride;
    let buffer = rows.words.as_mut_ptr().cast::<std::ffi::c_void>();
    // SAFETY: `buffer` holds `count * stride` bytes, 4-byte aligned (the filters read and
    // write 8-, 16- and 32-bit integers in place), and `stride` is one the filter takes
    // (checked above: the filters' debug assertions).
    unsafe {
        match filter {
            Filter::None => {}
            Filter::Octahedral => meshopt::ffi::meshopt_decodeFilterOct(buffer, count, stride),
            Filter::Quaternion => meshopt::ffi::meshopt_decodeFilterQuat(buffer, count, stride),
            Filter::Exponential => meshopt::ffi::meshopt_decodeFilterExp(buffer, count, stride),
            Filter::Color => meshopt::ffi::meshopt_decodeFilterColor(buffer, count, stride),
        }
    }
    Ok(())
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

    /// A vertex codec stream in bitstream version 1 (what `KHR_meshopt_compression` may
    /// hold; meshbits writes version 0).
    fn encode_vertices_v1(records: &[u8], stride: usize) -> Vec<u8> {
        encode_vertices_in(records, stride, 1, 3).unwrap()
    }

    /// Deterministic pseudo-random bytes (xorshift).
    fn noise(n: usize, seed: u64) -> Vec<u8> {
        let mut x = seed | 1;
        (0..n)
            .map(|_| {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                (x >> 24) as u8
            })
            .collect()
    }

    #[test]
    fn decoded_vertices_equal_the_encoded_ones() {
        for (count, stride) in [(0usize, 4usize), (1, 4), (17, 8), (1000, 12), (333, 256)] {
            let records: Vec<u8> = (0..count * stride)
                .map(|i| ((i / stride) * 3 + (i % stride) * 7) as u8 ^ (i % 5) as u8)
                .collect();
            let v0 = encode_vertices(&records, stride).unwrap();
            assert_eq!(meshopt::decode_vertex_version(&v0), Some(0));
            let decoded = decode_vertices(&v0, count, stride).unwrap();
            assert_eq!(decoded.as_bytes(), &records[..], "v0, {count} x {stride}");
            let v1 = encode_vertices_v1(&records, stride);
            assert_eq!(meshopt::decode_vertex_version(&v1), Some(1));
            let decoded =
                decode_buffer_view(&v1, count, stride, Mode::Attributes, Filter::None).unwrap();
            assert_eq!(decoded.as_bytes(), &records[..], "v1, {count} x {stride}");
        }
    }

    #[test]
    fn decoded_triangles_equal_the_encoded_ones() {
        let indices: Vec<u32> = (0..3000u32).map(|i| (i * 13 + i / 7) % 1000).collect();
        let encoded = encode_triangles(&indices, 1000).unwrap();
        let canonical = |t: &[u32]| {
            let k = (0..3).min_by_key(|&k| t[k]).unwrap();
            [t[k], t[(k + 1) % 3], t[(k + 2) % 3]]
        };
        let expected: Vec<[u32; 3]> = indices.chunks_exact(3).map(canonical).collect();
        for size in [2usize, 4] {
            let decoded =
                decode_buffer_view(&encoded, indices.len(), size, Mode::Triangles, Filter::None)
                    .unwrap();
            assert_eq!(decoded.len(), indices.len() * size);
            let values: Vec<u32> = decoded
                .as_bytes()
                .chunks_exact(size)
                .map(|b| match size {
                    2 => u32::from(u16::from_le_bytes([b[0], b[1]])),
                    _ => u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
                })
                .collect();
            // The codec may rotate a triangle's corners (its winding stays).
            let got: Vec<[u32; 3]> = values.chunks_exact(3).map(canonical).collect();
            assert_eq!(got, expected, "{size}-byte indices");
        }
    }

    #[test]
    fn decoded_index_sequences_equal_the_encoded_ones() {
        let indices: Vec<u32> = (0..999u32).map(|i| (i * 31) % 400 + i % 3).collect();
        let encoded = meshopt::encode_index_sequence(&indices, 402).unwrap();
        let decoded = decode_index_sequence(&encoded, indices.len(), 4).unwrap();
        let values: Vec<u32> = decoded
            .as_bytes()
            .chunks_exact(4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        assert_eq!(values, indices);
        let short =
            decode_buffer_view(&encoded, indices.len(), 2, Mode::Indices, Filter::None).unwrap();
        let shorts: Vec<u32> = short
            .as_bytes()
            .chunks_exact(2)
            .map(|b| u32::from(u16::from_le_bytes([b[0], b[1]])))
            .collect();
        assert_eq!(shorts, indices);
    }

    #[test]
    fn corrupt_streams_are_refused_with_a_reason() {
        let records: Vec<u8> = (0..4000u32)
            .flat_map(|i| (i * 7 % 251).to_le_bytes())
            .collect();
        let good = encode_vertices(&records, 8).unwrap();
        let mut header = good.clone();
        header[0] = 0x55;
        let err = decode_vertices(&header, 2000, 8).unwrap_err().to_string();
        assert!(err.contains("header byte (0x55)"), "{err}");
        let err = decode_vertices(&good[..good.len() - 40], 2000, 8)
            .unwrap_err()
            .to_string();
        assert!(err.contains("truncated"), "{err}");
        // Declaring fewer records than were written leaves bytes over.
        let err = decode_vertices(&good, 1000, 8).unwrap_err().to_string();
        assert!(err.contains("corrupt"), "{err}");
        // A count no stream this short can hold is refused before anything is allocated.
        let err = decode_vertices(&good, usize::MAX / 256, 8)
            .unwrap_err()
            .to_string();
        assert!(err.contains("fewer than"), "{err}");
        assert!(decode_vertices(&[], 0, 4).is_err());

        let indices: Vec<u32> = (0..300u32).map(|i| (i * 13) % 100).collect();
        let triangles = encode_triangles(&indices, 100).unwrap();
        let mut bad = triangles.clone();
        bad[0] = 0x00;
        let err = decode_triangles(&bad, 300, 4).unwrap_err().to_string();
        assert!(
            err.contains("index stream") && err.contains("header"),
            "{err}"
        );
        assert!(decode_triangles(&triangles[..20], 300, 4).is_err());
        assert!(decode_triangles(&triangles, 3 << 40, 4).is_err());
        let sequence = meshopt::encode_index_sequence(&indices, 100).unwrap();
        assert!(decode_index_sequence(&sequence[..sequence.len() - 1], 300, 4).is_err());
        assert!(decode_index_sequence(&triangles, 300, 4).is_err()); // another codec's header

        // Damage anywhere: refused or decoded to something, never a crash.
        for seed in 0..300u64 {
            let mut damaged = good.clone();
            let flips = noise(4, seed);
            let at = usize::from(flips[0]) * 256 + usize::from(flips[1]);
            let at = at % damaged.len();
            damaged[at] ^= flips[2] | 1;
            if let Ok(d) = decode_vertices(&damaged, 2000, 8) {
                assert_eq!(d.len(), 16_000);
            }
            let mut damaged = triangles.clone();
            let at = usize::from(flips[3]) % damaged.len();
            damaged[at] ^= flips[2] | 1;
            let _ = decode_triangles(&damaged, 300, 2);
            let garbage = noise(64 + seed as usize, seed);
            let _ = decode_vertices(&garbage, 100, 4);
            let _ = decode_triangles(&garbage, 30, 4);
            let _ = decode_index_sequence(&garbage, 30, 2);
        }
    }

    #[test]
    fn the_extension_rules_are_checked() {
        let stream = encode_vertices(&[0u8; 48], 8).unwrap();
        for (stride, mode, filter) in [
            (6, Mode::Attributes, Filter::None),
            (260, Mode::Attributes, Filter::None),
            (3, Mode::Triangles, Filter::None),
            (4, Mode::Triangles, Filter::Octahedral),
            (2, Mode::Indices, Filter::Exponential),
            (12, Mode::Attributes, Filter::Octahedral),
            (4, Mode::Attributes, Filter::Quaternion),
            (12, Mode::Attributes, Filter::Color),
        ] {
            assert!(
                decode_buffer_view(&stream, 6, stride, mode, filter).is_err(),
                "{stride} {mode:?} {filter:?}"
            );
        }
        assert!(decode_buffer_view(&stream, 6, 8, Mode::Attributes, Filter::Quaternion).is_ok());
        assert!(decode_triangles(&stream, 4, 4).is_err()); // not a multiple of 3
        assert!(Mode::from_name("STRIPS").is_err());
        assert!(Filter::from_name("octahedral").is_err());
        assert_eq!(Filter::from_name("COLOR"), Ok(Filter::Color));
        assert_eq!(Mode::from_name("INDICES"), Ok(Mode::Indices));
    }

    /// Runs `filter` on `rows` given as little-endian words of `size` bytes.
    fn filtered(rows: &[i64], size: usize, stride: usize, filter: Filter) -> Vec<i64> {
        let bytes: Vec<u8> = rows
            .iter()
            .flat_map(|&v| v.to_le_bytes()[..size].to_vec())
            .collect();
        let mut decoded = Decoded::from_bytes(&bytes).unwrap();
        decode_filter(&mut decoded, stride, filter).unwrap();
        decoded
            .as_bytes()
            .chunks_exact(size)
            .map(|b| match size {
                1 => i64::from(b[0] as i8),
                2 => i64::from(i16::from_le_bytes([b[0], b[1]])),
                _ => i64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            })
            .collect()
    }

    #[test]
    fn filters_decode_known_values() {
        // Octahedral, 8-bit (K = 8: the third component 127): +z, +x, -x, and -z (the
        // folded corner), w kept.
        let rows = [
            0, 0, 127, 9, 127, 0, 127, -3, -127, 0, 127, 0, 127, 127, 127, 1,
        ];
        assert_eq!(
            filtered(&rows, 1, 4, Filter::Octahedral),
            [0, 0, 127, 9, 127, 0, 0, -3, -127, 0, 0, 0, 0, 0, -127, 1]
        );
        // 16-bit with K = 12 (2047): +y, scaled to the full short range.
        assert_eq!(
            filtered(&[0, 2047, 2047, 7], 2, 8, Filter::Octahedral),
            [0, 32767, 0, 7]
        );
        // Quaternion: the identity, the largest component w (index 3) or x (index 0),
        // K = 12 (scale 2047 in the fourth short, the index in its low two bits).
        assert_eq!(
            filtered(&[0, 0, 0, 2044 | 3], 2, 8, Filter::Quaternion),
            [0, 0, 0, 32767]
        );
        assert_eq!(
            filtered(&[0, 0, 0, 2044], 2, 8, Filter::Quaternion),
            [32767, 0, 0, 0]
        );
        // Exponential: M * 2^E from E in the top byte and M in the low 24 bits.
        let exp = |e: i32, m: i32| i64::from(((e as u32) << 24) | (m as u32 & 0x00ff_ffff));
        let words = filtered(
            &[exp(-2, 3), exp(4, -5), exp(0, 0), exp(-10, 1 << 20)],
            4,
            16,
            Filter::Exponential,
        );
        let values: Vec<f32> = words.iter().map(|&w| f32::from_bits(w as u32)).collect();
        assert_eq!(values, [0.75, -80.0, 0.0, 1024.0]);
        // Colour, 8-bit YCoCg with 7-bit alpha: white, black, and Y 50, Co 20, Cg -10
        // (R 80, G 40, B 40 of 127).
        let colour = |rows: &[i64]| -> Vec<i64> {
            filtered(rows, 1, 4, Filter::Color)
                .iter()
                .map(|&c| c & 0xff)
                .collect()
        };
        assert_eq!(
            colour(&[127, 0, 0, 127, 0, 0, 0, 127, 50, 20, -10, 127]),
            [255, 255, 255, 255, 0, 0, 0, 255, 161, 80, 80, 255]
        );
        // Filters refuse records they do not decode.
        let mut rows = Decoded::from_bytes(&[0u8; 12]).unwrap();
        assert!(decode_filter(&mut rows, 8, Filter::Octahedral).is_err()); // not whole rows
        assert!(decode_filter(&mut rows, 12, Filter::Octahedral).is_err());
        assert!(decode_filter(&mut rows, 12, Filter::Exponential).is_ok());
    }

    #[test]
    fn octahedral_rows_decode_to_the_encoded_directions() {
        let vectors: Vec<[f32; 4]> = (0..300)
            .map(|i| {
                let t = i as f32 * 0.61;
                let (x, y, z) = (t.cos() * (0.3 * t).sin(), t.sin(), (1.7 * t).cos());
                let n = (x * x + y * y + z * z).sqrt();
                [x / n, y / n, z / n, if i % 2 == 0 { 1.0 } else { -1.0 }]
            })
            .collect();
        for (bits, stride, scale, degrees) in
            [(8u32, 4usize, 127.0f32, 1.0f32), (14, 8, 32767.0, 0.05)]
        {
            let rows = encode_octahedral(&vectors, bits).unwrap();
            let stream = encode_vertices(&rows, stride).unwrap();
            let decoded = decode_buffer_view(
                &stream,
                vectors.len(),
                stride,
                Mode::Attributes,
                Filter::Octahedral,
            )
            .unwrap();
            let size = stride / 4;
            for (v, row) in vectors.iter().zip(decoded.as_bytes().chunks_exact(stride)) {
                let c: Vec<f32> = row
                    .chunks_exact(size)
                    .map(|b| match size {
                        1 => f32::from(b[0] as i8),
                        _ => f32::from(i16::from_le_bytes([b[0], b[1]])),
                    })
                    .collect();
                let n = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
                assert!((n / scale - 1.0).abs() < 0.02, "{bits} bits: length {n}");
                let cos = (v[0] * c[0] + v[1] * c[1] + v[2] * c[2]) / n;
                assert!(
                    cos.clamp(-1.0, 1.0).acos().to_degrees() < degrees,
                    "{bits} bits"
                );
                assert_eq!(c[3].signum(), v[3].signum());
            }
        }
    }
}
