//! OBJ: `v` and `f` lines, the rest skipped (`l` and `p` counted).
//!
//! Two passes over chunks of lines in parallel: the first counts each chunk's `v` lines,
//! so that the second knows how many vertices come before each chunk and resolves a
//! negative (relative) index where it stands. A face corner is `a`, `a/b`, `a//c` or
//! `a/b/c`; only the position `a` is read. Polygons are fan-triangulated and counted.
//! What this reader does not read (a line continued with `\`, a number it cannot parse,
//! an index out of range) is left to the general reader.

use rayon::prelude::*;

use super::mapped::Mapped;
use super::text::{ChunkRows, line_chunks, lines, parse_chunks, parse_f64, parse_i64, tokens};
use super::{FaceCounts, MeshRead, ReadError, check_finite, fallback, push_fan};

/// What a line holds, from its first word.
fn is_vertex(line: &[u8]) -> bool {
    let line = line.trim_ascii_start();
    line.len() > 1 && line[0] == b'v' && line[1].is_ascii_whitespace()
}

/// Reads an OBJ file.
pub(crate) fn read(mapped: &Mapped) -> Result<MeshRead, ReadError> {
    let data = mapped.bytes();
    let chunks = line_chunks(data, 0);
    let counts: Vec<usize> = chunks
        .par_iter()
        .map(|&(from, to)| lines(&data[from..to]).filter(|l| is_vertex(l)).count())
        .collect();
    let mut before = Vec::with_capacity(counts.len());
    let mut total = 0usize;
    for n in counts {
        before.push(total);
        total += n;
    }
    if total > u32::MAX as usize {
        return fallback("more vertices than u32 indices reach");
    }
    let (vertices, faces, counts): ChunkRows = parse_chunks(mapped, &chunks, |chunk, bytes| {
        let mut out: ChunkRows = (Vec::new(), Vec::new(), FaceCounts::default());
        let mut corners = Vec::new();
        for line in lines(bytes) {
            if line.last() == Some(&b'\\') || line.ends_with(b"\\\r") {
                return fallback("a line continued with a backslash");
            }
            let mut words = tokens(line);
            match words.next() {
                Some(b"v") => {
                    let mut xyz = [0.0; 3];
                    for value in &mut xyz {
                        let Some(v) = words.next().and_then(parse_f64) else {
                            return fallback("a v line without three numbers");
                        };
                        *value = v;
                    }
                    out.0.push(xyz);
                }
                Some(b"f") => {
                    let seen = before[chunk] + out.0.len();
                    corners.clear();
                    for word in words {
                        let position = word.split(|&b| b == b'/').next().unwrap_or(word);
                        let Some(i) = parse_i64(position) else {
                            return fallback("a face corner that is not a whole number");
                        };
                        let resolved = match i {
                            0 => return fallback("a face index 0"),
                            1.. => i - 1,
                            _ => seen as i64 + i,
                        };
                        let Ok(resolved) = u32::try_from(resolved) else {
                            return fallback("a face index out of range");
                        };
                        corners.push(resolved);
                    }
                    if push_fan(&corners, total, &mut out.1, &mut out.2).is_none() {
                        return fallback("a face of fewer than 3 corners or an index out of range");
                    }
                }
                Some(b"l" | b"p") => out.2.skipped_elements += 1,
                _ => {}
            }
        }
        Ok(out)
    })?;
    if vertices.len() != total {
        return fallback("v lines the first pass counted otherwise");
    }
    check_finite(&vertices)?;
    Ok(counts.into_read(vertices, faces))
}
