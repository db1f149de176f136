//! What the text formats share: the file cut into chunks of whole lines for the worker
//! threads, and numbers parsed from whitespace-separated tokens.

use rayon::prelude::*;

use super::mapped::{CHUNK_BYTES, Mapped};
use super::{FaceCounts, ReadError};

/// `start..data.len()` cut into ranges of about [`CHUNK_BYTES`] that end just after a
/// line break (the last ends with the data).
pub(crate) fn line_chunks(data: &[u8], start: usize) -> Vec<(usize, usize)> {
    let mut chunks = Vec::new();
    let mut from = start.min(data.len());
    while from < data.len() {
        let mut to = (from + CHUNK_BYTES).min(data.len());
        while to < data.len() && data[to - 1] != b'\n' {
            to += 1;
        }
        chunks.push((from, to));
        from = to;
    }
    chunks
}

/// The lines of `bytes` (split at `\n`; a `\r` before it is whitespace to the tokenizer).
pub(crate) fn lines(bytes: &[u8]) -> impl Iterator<Item = &[u8]> {
    bytes.split(|&b| b == b'\n')
}

/// The whitespace-separated tokens of a line.
pub(crate) fn tokens(line: &[u8]) -> impl Iterator<Item = &[u8]> {
    line.split(u8::is_ascii_whitespace)
        .filter(|t| !t.is_empty())
}

/// Whether a line holds nothing but whitespace.
pub(crate) fn is_blank(line: &[u8]) -> bool {
    line.iter().all(u8::is_ascii_whitespace)
}

/// A decimal number, as Python's `float()` reads it (correctly rounded to `f64`).
#[inline]
pub(crate) fn parse_f64(token: &[u8]) -> Option<f64> {
    std::str::from_utf8(token).ok()?.parse::<f64>().ok()
}

/// A whole decimal number.
#[inline]
pub(crate) fn parse_i64(token: &[u8]) -> Option<i64> {
    std::str::from_utf8(token).ok()?.parse::<i64>().ok()
}

/// One chunk's vertices, triangles and counts, as the text readers gather them.
pub(crate) type ChunkRows = (Vec<[f64; 3]>, Vec<[u32; 3]>, FaceCounts);

/// Each chunk of `chunks` parsed by `parse` in parallel (its pages released after), the
/// results joined in file order: one copy of the rows into arrays of their final size.
pub(crate) fn parse_chunks<F>(
    mapped: &Mapped,
    chunks: &[(usize, usize)],
    parse: F,
) -> Result<ChunkRows, ReadError>
where
    F: Fn(usize, &[u8]) -> Result<ChunkRows, ReadError> + Sync,
{
    let data = mapped.bytes();
    let parts: Vec<ChunkRows> = chunks
        .par_iter()
        .enumerate()
        .map(|(index, &(from, to))| {
            let rows = parse(index, &data[from..to]);
            mapped.release(from, to);
            rows
        })
        .collect::<Result<_, _>>()?;
    let vertex_count = parts.iter().map(|p| p.0.len()).sum();
    let face_count = parts.iter().map(|p| p.1.len()).sum();
    let mut vertices = Vec::with_capacity(vertex_count);
    let mut faces = Vec::with_capacity(face_count);
    let mut counts = FaceCounts::default();
    for (v, f, c) in parts {
        vertices.extend_from_slice(&v);
        faces.extend_from_slice(&f);
        counts = counts.add(c);
    }
    Ok((vertices, faces, counts))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chunks_end_at_line_breaks_and_cover_the_data() {
        let data = b"v 1 2 3\nv 4 5 6\nf 1 2 3".to_vec();
        let chunks = line_chunks(&data, 0);
        assert_eq!(chunks, vec![(0, data.len())]);
        assert_eq!(tokens(b" a\tb  c\r").count(), 3);
        assert_eq!(parse_f64(b"1e-3"), Some(1e-3));
        assert_eq!(parse_i64(b"-7"), Some(-7));
        assert!(parse_i64(b"1.5").is_none());
    }
}
