//! ASCII PLY data: one row per non-blank line, chunks of lines parsed in parallel.

use rayon::prelude::*;

use super::{Element, Kind, coordinates, index_list};
use crate::io::mapped::Mapped;
use crate::io::text::{
    ChunkRows, is_blank, line_chunks, lines, parse_chunks, parse_f64, parse_i64, tokens,
};
use crate::io::{FaceCounts, MeshRead, ReadError, fallback, push_fan};

/// A parsed value stored as the declared type would store it (trimesh reads the text as
/// `f64` and casts it to the property's type).
fn as_declared(value: f64, kind: Kind) -> f64 {
    if kind == Kind::F32 {
        f64::from(value as f32)
    } else {
        value
    }
}

/// Reads the ASCII data of a PLY file whose header is `elements`.
pub(super) fn read_ascii(
    mapped: &Mapped,
    elements: &[Element],
    start: usize,
    vi: usize,
    fi: usize,
) -> Result<MeshRead, ReadError> {
    let data = mapped.bytes();
    let coords = coordinates(&elements[vi])?;
    let index = index_list(&elements[fi])?;
    let chunks = line_chunks(data, start);
    let rows_before: Vec<usize> = chunks
        .par_iter()
        .map(|&(from, to)| lines(&data[from..to]).filter(|l| !is_blank(l)).count())
        .collect();
    let mut first_rows = Vec::with_capacity(chunks.len());
    let mut total = 0;
    for n in rows_before {
        first_rows.push(total);
        total += n;
    }
    // Where each element's rows start and end, counted in rows.
    let mut bounds = Vec::with_capacity(elements.len());
    let mut row = 0usize;
    for element in elements {
        bounds.push((row, row + element.count));
        row += element.count;
    }
    if total != row {
        return fallback("the data holds another number of rows than the header declares");
    }
    let vertex_count = elements[vi].count;
    let (vertex_rows, face_rows) = (bounds[vi], bounds[fi]);
    let face = &elements[fi];
    let (vertices, faces, counts): ChunkRows = parse_chunks(mapped, &chunks, |chunk, bytes| {
        let mut out: ChunkRows = (Vec::new(), Vec::new(), FaceCounts::default());
        let mut corners = Vec::new();
        let rows = lines(bytes).filter(|l| !is_blank(l));
        for (row, line) in (first_rows[chunk]..).zip(rows) {
            if (vertex_rows.0..vertex_rows.1).contains(&row) {
                out.0.push(vertex_row(line, &elements[vi], &coords)?);
            } else if (face_rows.0..face_rows.1).contains(&row) {
                face_row(line, face, index, &mut corners)?;
                if push_fan(&corners, vertex_count, &mut out.1, &mut out.2).is_none() {
                    return fallback("a face of fewer than 3 corners or an index out of range");
                }
            }
        }
        Ok(out)
    })?;
    if vertices.len() != vertex_count {
        return fallback("another number of vertex rows than declared");
    }
    Ok(counts.into_read(vertices, faces))
}

/// A vertex row's x, y and z; every property must be there, nothing more.
fn vertex_row(
    line: &[u8],
    vertex: &Element,
    coords: &super::Coordinates,
) -> Result<[f64; 3], ReadError> {
    let mut xyz = [0.0; 3];
    let mut n = 0;
    for (column, token) in tokens(line).enumerate() {
        if let Some(k) = coords.columns.iter().position(|&c| c == column) {
            let Some(value) = parse_f64(token) else {
                return fallback("a coordinate that is not a number");
            };
            xyz[k] = as_declared(value, coords.kinds[k]);
        }
        n += 1;
    }
    if n != vertex.properties.len() {
        return fallback("a vertex row of another length than its properties");
    }
    Ok(xyz)
}

/// A face row's vertex indices into `corners`; every property must be there, nothing
/// more.
fn face_row(
    line: &[u8],
    face: &Element,
    index: usize,
    corners: &mut Vec<u32>,
) -> Result<(), ReadError> {
    corners.clear();
    let mut words = tokens(line);
    for (number, p) in face.properties.iter().enumerate() {
        let Some(first) = words.next() else {
            return fallback("a face row shorter than its properties");
        };
        if p.list.is_none() {
            continue;
        }
        let Some(n) = parse_i64(first).and_then(|n| usize::try_from(n).ok()) else {
            return fallback("a list length that is not a whole number");
        };
        for _ in 0..n {
            let item = words.next();
            if number == index {
                let Some(i) = item.and_then(parse_i64).and_then(|i| u32::try_from(i).ok()) else {
                    return fallback("a vertex index that is not a whole number >= 0");
                };
                corners.push(i);
            } else if item.is_none() {
                return fallback("a list shorter than its length");
            }
        }
    }
    if words.next().is_some() {
        return fallback("a face row longer than its properties");
    }
    Ok(())
}
