//! STL, binary and ASCII: a triangle soup, three vertices per triangle in file order,
//! as trimesh reads it (the kernels weld equal positions: [`crate::weld`]).
//!
//! A file is binary when its 84-byte header's triangle count matches its length (even
//! when the header starts with `solid`), else ASCII when it starts with `solid` and holds
//! no NUL byte in its first 4 KB: the rule of the Python header check.

use rayon::prelude::*;

use super::mapped::{CHUNK_BYTES, Mapped};
use super::text::{ChunkRows, line_chunks, lines, parse_chunks, parse_f64, tokens};
use super::{FaceCounts, MeshRead, ReadError, check_finite, fallback};

/// Bytes of a binary STL record: normal, three corners (`f32`), attribute count.
const RECORD: usize = 50;

/// Reads an STL file.
pub(crate) fn read(mapped: &Mapped) -> Result<MeshRead, ReadError> {
    let data = mapped.bytes();
    let read = if data.len() >= 84 {
        let count = u32::from_le_bytes([data[80], data[81], data[82], data[83]]) as usize;
        if 84 + RECORD * count == data.len() {
            read_binary(mapped, count)?
        } else {
            read_ascii(mapped)?
        }
    } else {
        read_ascii(mapped)?
    };
    check_finite(&read.vertices)?;
    Ok(read)
}

/// The soup's faces: `[3 i, 3 i + 1, 3 i + 2]` for each triangle `i`.
fn soup_faces(triangles: usize) -> Result<Vec<[u32; 3]>, ReadError> {
    if triangles
        .checked_mul(3)
        .is_none_or(|n| n > u32::MAX as usize)
    {
        return fallback("more corners than u32 indices reach");
    }
    Ok((0..triangles as u32)
        .into_par_iter()
        .with_min_len(1 << 14)
        .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
        .collect())
}

fn read_binary(mapped: &Mapped, count: usize) -> Result<MeshRead, ReadError> {
    let data = mapped.bytes();
    let faces = soup_faces(count)?;
    let mut vertices: Vec<[f64; 3]> = Vec::with_capacity(3 * count);
    let per_chunk = (CHUNK_BYTES / RECORD).max(1);
    vertices.spare_capacity_mut()[..3 * count]
        .par_chunks_mut(3 * per_chunk)
        .enumerate()
        .for_each(|(chunk, slots)| {
            let first = 84 + chunk * per_chunk * RECORD;
            for (k, slot) in slots.iter_mut().enumerate() {
                let at = first + (k / 3) * RECORD + 12 + 12 * (k % 3);
                let f = |o: usize| {
                    let b = [
                        data[at + o],
                        data[at + o + 1],
                        data[at + o + 2],
                        data[at + o + 3],
                    ];
                    f64::from(f32::from_le_bytes(b))
                };
                slot.write([f(0), f(4), f(8)]);
            }
            mapped.release(first, first + slots.len() / 3 * RECORD);
        });
    // SAFETY: every slot of `0..3 count` was written above.
    unsafe { vertices.set_len(3 * count) };
    Ok(FaceCounts::default().into_read(vertices, faces))
}

fn read_ascii(mapped: &Mapped) -> Result<MeshRead, ReadError> {
    let data = mapped.bytes();
    let sample = &data[..data.len().min(4096)];
    let text_start = sample
        .iter()
        .position(|b| !b.is_ascii_whitespace())
        .unwrap_or(0);
    if !sample[text_start..].starts_with(b"solid") || sample.contains(&0) {
        return fallback("neither a binary STL of its length nor an ASCII STL");
    }
    let chunks = line_chunks(data, 0);
    let (vertices, _, _): ChunkRows = parse_chunks(mapped, &chunks, |_, bytes| {
        let mut out: ChunkRows = (Vec::new(), Vec::new(), FaceCounts::default());
        for line in lines(bytes) {
            let mut words = tokens(line);
            match words.next() {
                Some(b"vertex") => {
                    let mut xyz = [0.0; 3];
                    for value in &mut xyz {
                        let Some(v) = words.next().and_then(parse_f64) else {
                            return fallback("a vertex line without three numbers");
                        };
                        *value = v;
                    }
                    if words.next().is_some() {
                        return fallback("a vertex line with more than three numbers");
                    }
                    out.0.push(xyz);
                }
                None
                | Some(b"solid" | b"endsolid" | b"facet" | b"outer" | b"endloop" | b"endfacet") => {
                }
                Some(_) => return fallback("a line an ASCII STL does not hold"),
            }
        }
        Ok(out)
    })?;
    if vertices.len() % 3 != 0 {
        return fallback("a vertex count that is not a multiple of 3");
    }
    let faces = soup_faces(vertices.len() / 3)?;
    Ok(FaceCounts::default().into_read(vertices, faces))
}
