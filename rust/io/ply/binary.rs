//! Binary PLY data (either byte order) read in parallel into the output arrays.

use std::mem::MaybeUninit;

use rayon::prelude::*;

use super::{Element, Kind, coordinates, float_at, index_list, int_at};
use crate::io::mapped::{CHUNK_BYTES, Mapped};
use crate::io::{FaceCounts, MeshRead, ReadError, fallback};

/// Face rows per block of the row walk (mixed polygon sizes).
const BLOCK_ROWS: usize = 1 << 16;

/// Most corners a face may have (a longer list is damage, or a file for the general
/// reader).
const MAX_CORNERS: usize = 1 << 12;

/// Each element's start, and its row length when every row is as long as its first.
fn first_row_layout(
    data: &[u8],
    elements: &[Element],
    start: usize,
    big: bool,
) -> Option<Vec<(usize, usize)>> {
    let mut offset = start;
    let mut layout = Vec::with_capacity(elements.len());
    for element in elements {
        let mut row = 0usize;
        for p in &element.properties {
            match p.list {
                None => row += p.kind.size(),
                Some(length) => {
                    let at = offset + row;
                    if element.count == 0 {
                        row += length.size();
                        continue;
                    }
                    if at + length.size() > data.len() {
                        return None;
                    }
                    let n = usize::try_from(int_at(data, at, length, big)).ok()?;
                    row =
                        row.checked_add(length.size().checked_add(n.checked_mul(p.kind.size())?)?)?;
                }
            }
        }
        layout.push((offset, row));
        offset = offset.checked_add(element.count.checked_mul(row)?)?;
    }
    (offset == data.len()).then_some(layout)
}

/// Reads the data of a binary PLY whose header is `elements` (vertex element `vi`, face
/// element `fi`), starting at `start`.
pub(super) fn read_binary(
    mapped: &Mapped,
    elements: &[Element],
    start: usize,
    vi: usize,
    fi: usize,
    big: bool,
) -> Result<MeshRead, ReadError> {
    let data = mapped.bytes();
    // Each row takes at least its scalars and its list lengths: a header declaring more
    // rows than the file can hold is left aside before anything is sized from its counts.
    let mut least = start;
    for element in elements {
        let row: usize = element
            .properties
            .iter()
            .map(|p| p.list.unwrap_or(p.kind).size())
            .sum();
        least = element
            .count
            .checked_mul(row.max(1))
            .and_then(|n| least.checked_add(n))
            .unwrap_or(usize::MAX);
    }
    if least > data.len() {
        return fallback("the header declares more rows than the file holds");
    }
    let coords = coordinates(&elements[vi])?;
    let index = index_list(&elements[fi])?;
    let vertex_row = elements[vi].fixed_row().unwrap_or(0);
    let layout = first_row_layout(data, elements, start, big);
    let (vertex_start, face_fixed) = match &layout {
        Some(layout) => (layout[vi].0, Some(layout[fi])),
        None => (walk_start(data, elements, start, vi, big)?, None),
    };
    let vertex_count = elements[vi].count;
    if vertex_count
        .checked_mul(vertex_row)
        .is_none_or(|n| vertex_start + n > data.len())
    {
        return fallback("the vertex rows run past the end of the file");
    }
    let vertices = read_vertices(mapped, vertex_start, vertex_row, vertex_count, &coords, big);
    let face = &elements[fi];
    let lists = face.properties.iter().filter(|p| p.list.is_some()).count();
    if let (Some((face_start, stride)), 1) = (face_fixed, lists)
        && let Some((faces, counts)) =
            fixed_faces(mapped, face, index, face_start, stride, vertex_count, big)?
    {
        return Ok(counts.into_read(vertices, faces));
    }
    let face_start = walk_start(data, elements, start, fi, big)?;
    let (blocks, triangles) = walk_faces(mapped, face, index, face_start, big)?;
    let (faces, counts) = block_faces(mapped, face, index, &blocks, triangles, vertex_count, big)?;
    Ok(counts.into_read(vertices, faces))
}

/// Where element `target` starts, the elements before it walked row by row.
fn walk_start(
    data: &[u8],
    elements: &[Element],
    start: usize,
    target: usize,
    big: bool,
) -> Result<usize, ReadError> {
    let mut at = start;
    for element in &elements[..target] {
        if let Some(row) = element.fixed_row() {
            at = element
                .count
                .checked_mul(row)
                .and_then(|n| at.checked_add(n))
                .unwrap_or(usize::MAX);
        } else {
            for _ in 0..element.count {
                at = row_end(data, element, at, big).ok_or_else(past_end)?;
            }
        }
        if at > data.len() {
            return Err(past_end());
        }
    }
    Ok(at)
}

fn past_end() -> ReadError {
    ReadError::Fallback("the rows run past the end of the file".into())
}

/// Where the row of `element` starting at `at` ends; `None` past the data.
fn row_end(data: &[u8], element: &Element, mut at: usize, big: bool) -> Option<usize> {
    for p in &element.properties {
        match p.list {
            None => at += p.kind.size(),
            Some(length) => {
                if at + length.size() > data.len() {
                    return None;
                }
                let n = usize::try_from(int_at(data, at, length, big)).ok()?;
                at = at.checked_add(length.size() + n.checked_mul(p.kind.size())?)?;
            }
        }
    }
    (at <= data.len()).then_some(at)
}

/// The vertex rows parsed in parallel, chunk by chunk, each chunk's pages released.
fn read_vertices(
    mapped: &Mapped,
    start: usize,
    row: usize,
    count: usize,
    coords: &super::Coordinates,
    big: bool,
) -> Vec<[f64; 3]> {
    let data = mapped.bytes();
    let mut vertices: Vec<[f64; 3]> = Vec::with_capacity(count);
    let per_chunk = (CHUNK_BYTES / row.max(1)).max(1);
    vertices.spare_capacity_mut()[..count]
        .par_chunks_mut(per_chunk)
        .enumerate()
        .for_each(|(chunk, slots)| {
            let first = start + chunk * per_chunk * row;
            for (k, slot) in slots.iter_mut().enumerate() {
                let at = first + k * row;
                slot.write([
                    float_at(data, at + coords.offsets[0], coords.kinds[0], big),
                    float_at(data, at + coords.offsets[1], coords.kinds[1], big),
                    float_at(data, at + coords.offsets[2], coords.kinds[2], big),
                ]);
            }
            mapped.release(first, first + slots.len() * row);
        });
    // SAFETY: every slot of `0..count` was written above.
    unsafe { vertices.set_len(count) };
    vertices
}

/// The faces at a fixed stride (every list as long as the first row's): `None` when a row
/// disagrees (the caller then walks the rows).
#[allow(clippy::type_complexity)]
fn fixed_faces(
    mapped: &Mapped,
    face: &Element,
    index: usize,
    start: usize,
    stride: usize,
    vertex_count: usize,
    big: bool,
) -> Result<Option<(Vec<[u32; 3]>, FaceCounts)>, ReadError> {
    let data = mapped.bytes();
    let rows = face.count;
    let list_at: usize = face.properties[..index].iter().map(|p| p.kind.size()).sum();
    let (length, item) = (
        face.properties[index].list.unwrap_or(Kind::U8),
        face.properties[index].kind,
    );
    if rows == 0 {
        return fallback("no faces");
    }
    let corners = int_at(data, start + list_at, length, big);
    let Ok(corners) = usize::try_from(corners) else {
        return Ok(None);
    };
    if !(3..=MAX_CORNERS).contains(&corners) {
        return Ok(None);
    }
    let per_row = corners - 2;
    let Some(total) = rows.checked_mul(per_row) else {
        return Ok(None);
    };
    let mut faces: Vec<[u32; 3]> = Vec::with_capacity(total);
    let rows_per_chunk = (CHUNK_BYTES / stride.max(1)).max(1);
    let outcome: Result<(), Outcome> = faces.spare_capacity_mut()[..total]
        .par_chunks_mut(rows_per_chunk * per_row)
        .enumerate()
        .try_for_each(|(chunk, slots)| {
            let first_row = chunk * rows_per_chunk;
            let from = start + first_row * stride;
            if corners == 3
                && let Some(rows) = triangle_rows(length, item)
            {
                rows(data, from, stride, list_at, slots, vertex_count, big)?;
            } else {
                let mut corner = [0u32; MAX_CORNERS];
                for r in 0..slots.len() / per_row {
                    let row_at = from + r * stride;
                    if int_at(data, row_at + list_at, length, big) != corners as i64 {
                        return Err(Outcome::Mismatch);
                    }
                    let at = row_at + list_at + length.size();
                    for (j, c) in corner[..corners].iter_mut().enumerate() {
                        let i = int_at(data, at + j * item.size(), item, big);
                        if i < 0 || i as usize >= vertex_count {
                            return Err(Outcome::BadIndex);
                        }
                        *c = i as u32;
                    }
                    for k in 0..per_row {
                        slots[r * per_row + k].write([corner[0], corner[k + 1], corner[k + 2]]);
                    }
                }
            }
            mapped.release(from, from + (slots.len() / per_row) * stride);
            Ok(())
        });
    match outcome {
        Ok(()) => {
            // SAFETY: every slot of `0..total` was written above.
            unsafe { faces.set_len(total) };
            let polygons = if corners > 3 { rows } else { 0 };
            let counts = FaceCounts {
                polygons,
                polygon_triangles: polygons * per_row,
                ..FaceCounts::default()
            };
            Ok(Some((faces, counts)))
        }
        Err(Outcome::Mismatch) => Ok(None),
        Err(Outcome::BadIndex) => fallback("a face index out of range"),
    }
}

/// An integer type of a list length or an index, read at compile-time width.
trait Scalar {
    const SIZE: usize;
    fn get(bytes: &[u8], big: bool) -> i64;
}

macro_rules! scalar {
    ($($t:ty),*) => {$(
        impl Scalar for $t {
            const SIZE: usize = size_of::<$t>();
            #[inline(always)]
            fn get(bytes: &[u8], big: bool) -> i64 {
                let mut b = [0u8; size_of::<$t>()];
                b.copy_from_slice(&bytes[..size_of::<$t>()]);
                i64::from(if big { <$t>::from_be_bytes(b) } else { <$t>::from_le_bytes(b) })
            }
        }
    )*};
}
scalar!(u8, u16, i32, u32);

/// Parses a chunk of triangle rows into `slots`: the arguments of [`rows_of`].
type TriangleRows = fn(
    &[u8],
    usize,
    usize,
    usize,
    &mut [MaybeUninit<[u32; 3]>],
    usize,
    bool,
) -> Result<(), Outcome>;

/// The triangle-row parser for list lengths of type `length` and indices of type `item`
/// (the common types, compiled for each), or `None` for the generic path.
fn triangle_rows(length: Kind, item: Kind) -> Option<TriangleRows> {
    Some(match (length, item) {
        (Kind::U8, Kind::I32) => rows_of::<u8, i32>,
        (Kind::U8, Kind::U32) => rows_of::<u8, u32>,
        (Kind::U16, Kind::I32) => rows_of::<u16, i32>,
        (Kind::U16, Kind::U32) => rows_of::<u16, u32>,
        (Kind::I32, Kind::I32) => rows_of::<i32, i32>,
        (Kind::I32, Kind::U32) => rows_of::<i32, u32>,
        (Kind::U32, Kind::I32) => rows_of::<u32, i32>,
        (Kind::U32, Kind::U32) => rows_of::<u32, u32>,
        _ => return None,
    })
}

/// Rows of 3 corners from `first`, `stride` bytes apart, the list length at `list_at` in
/// a row, into `slots`: each length checked to be 3 and each index to be in range.
fn rows_of<L: Scalar, I: Scalar>(
    data: &[u8],
    first: usize,
    stride: usize,
    list_at: usize,
    slots: &mut [MaybeUninit<[u32; 3]>],
    vertex_count: usize,
    big: bool,
) -> Result<(), Outcome> {
    let at = list_at + L::SIZE;
    let count = vertex_count as u64;
    let rows = data[first..first + slots.len() * stride].chunks_exact(stride);
    for (row, slot) in rows.zip(slots.iter_mut()) {
        if L::get(&row[list_at..], big) != 3 {
            return Err(Outcome::Mismatch);
        }
        let a = I::get(&row[at..], big);
        let b = I::get(&row[at + I::SIZE..], big);
        let c = I::get(&row[at + 2 * I::SIZE..], big);
        // A negative index becomes a u64 above any vertex count.
        if (a as u64) >= count || (b as u64) >= count || (c as u64) >= count {
            return Err(Outcome::BadIndex);
        }
        slot.write([a as u32, b as u32, c as u32]);
    }
    Ok(())
}

/// Why a chunk of faces stopped.
enum Outcome {
    /// A row's list length differs from the first row's.
    Mismatch,
    /// An index is negative or beyond the vertices.
    BadIndex,
}

/// A block of face rows: where it starts and how many triangles come before it.
type Block = (usize, usize);

/// The face rows walked one by one: the blocks of [`BLOCK_ROWS`] rows, and the number of
/// triangles they make.
fn walk_faces(
    mapped: &Mapped,
    face: &Element,
    index: usize,
    start: usize,
    big: bool,
) -> Result<(Vec<Block>, usize), ReadError> {
    let data = mapped.bytes();
    let mut blocks = Vec::with_capacity(face.count / BLOCK_ROWS + 2);
    let (mut at, mut triangles, mut released) = (start, 0usize, start);
    for row in 0..face.count {
        if row % BLOCK_ROWS == 0 {
            blocks.push((at, triangles));
            mapped.release(released, at);
            released = at;
        }
        for (number, p) in face.properties.iter().enumerate() {
            let Some(length) = p.list else {
                at += p.kind.size();
                continue;
            };
            if at + length.size() > data.len() {
                return Err(past_end());
            }
            let n = usize::try_from(int_at(data, at, length, big)).map_err(|_| past_end())?;
            if number == index {
                if !(3..=MAX_CORNERS).contains(&n) {
                    return fallback("a face of fewer than 3 or very many corners");
                }
                triangles += n - 2;
            }
            at = n
                .checked_mul(p.kind.size())
                .and_then(|b| (at + length.size()).checked_add(b))
                .ok_or_else(past_end)?;
        }
        if at > data.len() {
            return Err(past_end());
        }
    }
    mapped.release(released, at);
    blocks.push((at, triangles));
    Ok((blocks, triangles))
}

/// The faces of walked blocks parsed in parallel, each block into its own part of the
/// output.
fn block_faces(
    mapped: &Mapped,
    face: &Element,
    index: usize,
    blocks: &[Block],
    total: usize,
    vertex_count: usize,
    big: bool,
) -> Result<(Vec<[u32; 3]>, FaceCounts), ReadError> {
    let data = mapped.bytes();
    let mut faces: Vec<[u32; 3]> = Vec::with_capacity(total);
    let mut parts: Vec<(usize, &mut [MaybeUninit<[u32; 3]>])> = Vec::with_capacity(blocks.len());
    let mut rest = &mut faces.spare_capacity_mut()[..total];
    for pair in blocks.windows(2) {
        let (head, tail) = rest.split_at_mut(pair[1].1 - pair[0].1);
        parts.push((pair[0].0, head));
        rest = tail;
    }
    let rows = face.count;
    let counts = parts
        .into_par_iter()
        .enumerate()
        .map(|(block, (mut at, slots))| {
            let mut counts = FaceCounts::default();
            let mut written = 0;
            let first = at;
            let block_rows = BLOCK_ROWS.min(rows - block * BLOCK_ROWS);
            for _ in 0..block_rows {
                for (number, p) in face.properties.iter().enumerate() {
                    let Some(length) = p.list else {
                        at += p.kind.size();
                        continue;
                    };
                    let n = int_at(data, at, length, big) as usize;
                    at += length.size();
                    if number == index {
                        for k in 1..n - 1 {
                            let mut t = [0u32; 3];
                            for (slot, j) in t.iter_mut().zip([0, k, k + 1]) {
                                let i = int_at(data, at + j * p.kind.size(), p.kind, big);
                                if i < 0 || i as usize >= vertex_count {
                                    return Err(ReadError::Fallback(
                                        "a face index out of range".into(),
                                    ));
                                }
                                *slot = i as u32;
                            }
                            slots[written].write(t);
                            written += 1;
                        }
                        if n > 3 {
                            counts.polygons += 1;
                            counts.polygon_triangles += n - 2;
                        }
                    }
                    at += n * p.kind.size();
                }
            }
            mapped.release(first, at);
            Ok(counts)
        })
        .try_reduce(FaceCounts::default, |a, b| Ok(a.add(b)))?;
    // SAFETY: the walk counted `total` triangles over the blocks, and each block wrote
    // its own (its slice's length is its count).
    unsafe { faces.set_len(total) };
    Ok((faces, counts))
}
