//! The decoders through [`decode_buffer_view`]: what the encoders wrote (vertex codec
//! versions 0 and 1, triangles, index sequences), corrupt streams refused with a reason,
//! the extension's rules, octahedral rows through the vertex codec and back.

use super::vertex_codec::encode_vertices_in;
use super::*;

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
    for (bits, stride, scale, degrees) in [(8u32, 4usize, 127.0f32, 1.0f32), (14, 8, 32767.0, 0.05)]
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
