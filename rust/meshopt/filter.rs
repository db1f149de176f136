//! The filters of the extensions: unit vectors encoded as octahedral signed normalized
//! integers (Cigolle et al. 2014, the decoder reconstructing the third component), and
//! every filter the decoders undo on the records after the vertex codec.

use super::decoded::Decoded;
use crate::error::MeshError;

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

/// Unit quaternions `(x, y, z, w)` as the `QUATERNION` filter's records (4 shorts,
/// little-endian, 8 bytes a row): the three smallest components times sqrt(2) as signed
/// `bits`-bit integers (4 to 16) in cyclic order after the largest, whose index is in the
/// fourth short's low two bits beside the scale `2^(bits-1) - 1`; the sign is dropped
/// (q and -q are one rotation). The decoder (`meshopt_decodeFilterQuat`) reconstructs the
/// largest component as `sqrt(1 - sum of the others' squares)`, so the rows should be unit
/// quaternions.
pub fn encode_quaternions(quaternions: &[[f32; 4]], bits: u32) -> Result<Vec<u8>, MeshError> {
    if !(4..=16).contains(&bits) {
        return Err(MeshError::Parameter(format!(
            "quaternion bits must be from 4 to 16, got {bits}"
        )));
    }
    if let Some(i) = quaternions
        .iter()
        .position(|q| !q.iter().all(|c| c.is_finite()))
    {
        return Err(MeshError::Parameter(format!(
            "quaternion {i} is not finite"
        )));
    }
    Ok(meshopt::encode_filter_quat(quaternions, bits as i32)
        .into_iter()
        .flat_map(|row| row.into_iter().flat_map(i16::to_le_bytes))
        .collect())
}

/// How the `EXPONENTIAL` filter's encoder chooses each value's exponent.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExponentMode {
    /// Each value its own exponent (the least error).
    Separate,
    /// One exponent per row, the largest its components need.
    SharedVector,
    /// One exponent per component over all rows (the most compressible).
    SharedComponent,
}

impl ExponentMode {
    /// The mode called `name` (`"separate"`, `"vector"`, `"component"`).
    pub fn from_name(name: &str) -> Result<ExponentMode, MeshError> {
        match name {
            "separate" => Ok(ExponentMode::Separate),
            "vector" => Ok(ExponentMode::SharedVector),
            "component" => Ok(ExponentMode::SharedComponent),
            other => Err(MeshError::Parameter(format!(
                "unknown exponent mode {other:?} (separate, vector or component)"
            ))),
        }
    }
}

/// Rows of `components` float32 values (1 to 64, row-major in `values`) as the
/// `EXPONENTIAL` filter's words (4 bytes a value, little-endian): each an 8-bit signed
/// exponent `E` over a `bits`-bit (1 to 24) signed mantissa `M`, decoded to `M * 2^E`, with
/// the exponents shared as `mode` says.
pub fn encode_exponential(
    values: &[f32],
    components: usize,
    bits: u32,
    mode: ExponentMode,
) -> Result<Vec<u8>, MeshError> {
    if !(1..=24).contains(&bits) {
        return Err(MeshError::Parameter(format!(
            "exponential bits must be from 1 to 24, got {bits}"
        )));
    }
    if !(1..=64).contains(&components) || !values.len().is_multiple_of(components) {
        return Err(MeshError::Parameter(format!(
            "{} values are not rows of {components} components (1 to 64)",
            values.len()
        )));
    }
    if let Some(i) = values.iter().position(|v| !v.is_finite()) {
        return Err(MeshError::Parameter(format!(
            "value {i} (row {}) is not finite",
            i / components
        )));
    }
    let count = values.len() / components;
    let mut words = vec![0u32; values.len()];
    let mode = match mode {
        ExponentMode::Separate => meshopt::ffi::meshopt_EncodeExpMode_meshopt_EncodeExpSeparate,
        ExponentMode::SharedVector => {
            meshopt::ffi::meshopt_EncodeExpMode_meshopt_EncodeExpSharedVector
        }
        ExponentMode::SharedComponent => {
            meshopt::ffi::meshopt_EncodeExpMode_meshopt_EncodeExpSharedComponent
        }
    };
    // SAFETY: `words` holds `count` rows of `components` u32 (the stride, a multiple of 4
    // of at most 256 bytes), `values` as many finite floats, and `bits` is in 1..=24: the
    // encoder's preconditions (its debug assertions).
    unsafe {
        meshopt::ffi::meshopt_encodeFilterExp(
            words.as_mut_ptr().cast(),
            count,
            components * 4,
            bits as i32,
            values.as_ptr(),
            mode,
        );
    }
    Ok(words.into_iter().flat_map(u32::to_le_bytes).collect())
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
    pub(super) fn check_stride(self, stride: usize) -> Result<(), MeshError> {
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

/// Undoes `filter` in place on `rows`, records of `stride` bytes (see [`Filter`] for what
/// each decodes and the strides it takes). Refuses a stride the filter does not take and
/// rows that are not whole records.
pub fn decode_filter(rows: &mut Decoded, stride: usize, filter: Filter) -> Result<(), MeshError> {
    filter.check_stride(stride)?;
    if filter == Filter::None {
        return Ok(());
    }
    if !rows.len().is_multiple_of(stride) {
        return Err(MeshError::Parameter(format!(
            "{} bytes are not whole records of {stride} bytes",
            rows.len()
        )));
    }
    let count = rows.len() / stride;
    let buffer = rows.as_mut_ptr();
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

#[cfg(test)]
mod tests {
    use super::*;

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
    fn animation_filters_round_trip() {
        let quaternions: Vec<[f32; 4]> = (0..200)
            .map(|i| {
                let t = i as f32 * 0.173;
                let q = [t.sin(), (2.0 * t).cos(), (0.5 * t).sin(), t.cos() - 0.3];
                let n = q.iter().map(|c| c * c).sum::<f32>().sqrt();
                q.map(|c| c / n)
            })
            .collect();
        let bytes = encode_quaternions(&quaternions, 12).unwrap();
        let mut rows: Vec<[i16; 4]> = bytes
            .chunks_exact(8)
            .map(|r| [0, 1, 2, 3].map(|k| i16::from_le_bytes([r[2 * k], r[2 * k + 1]])))
            .collect();
        meshopt::decode_filter_quat(&mut rows);
        for (q, r) in quaternions.iter().zip(&rows) {
            let d = r.map(|c| f32::from(c) / 32767.0);
            let norm = d.iter().map(|c| c * c).sum::<f32>().sqrt();
            let dot: f32 = (0..4).map(|k| q[k] * d[k]).sum::<f32>() / norm;
            // 12 bits: each component within half a step (1 / (2047 sqrt 2)) of its value,
            // the angle between them within 2e-3 radians (about 0.1 degrees).
            let angle = 2.0 * dot.abs().min(1.0).acos();
            assert!(angle < 2e-3, "{q:?} -> {d:?}: {angle}");
        }
        assert!(encode_quaternions(&quaternions, 3).is_err());
        let values: Vec<f32> = (0..300).map(|i| (i as f32 * 0.37).sin() * 40.0).collect();
        for mode in ["separate", "vector", "component"] {
            let mode = ExponentMode::from_name(mode).unwrap();
            let words = encode_exponential(&values, 3, 16, mode).unwrap();
            let mut decoded = Decoded::from_bytes(&words).unwrap();
            decode_filter(&mut decoded, 12, Filter::Exponential).unwrap();
            for (v, b) in values.iter().zip(decoded.as_bytes().chunks_exact(4)) {
                let d = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
                assert!((v - d).abs() <= 40.0 / 16384.0, "{v} -> {d}");
            }
        }
        assert!(encode_exponential(&values, 7, 16, ExponentMode::Separate).is_err());
        assert!(encode_exponential(&[f32::NAN], 1, 16, ExponentMode::Separate).is_err());
    }
}
