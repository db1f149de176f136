//! PLY: the header, then the binary (either byte order) or ASCII data.
//!
//! Binary: the elements are laid out as trimesh reads them (each list as long as in its
//! element's first row) when the sizes add up to the file's; the faces are then parsed in
//! parallel at a fixed stride, each row's list length checked. A file whose face lists
//! differ in length (mixed polygons) is walked once, row by row, to find where each block
//! of rows starts and how many triangles come before it; the blocks are then parsed in
//! parallel. Any vertex property order, `float` or `double` coordinates, list lengths of
//! any integer type and index lists of any integer type are read; other properties and
//! elements are skipped. ASCII: one row per non-blank line, chunks of lines parsed in
//! parallel once each chunk's first row number is known.

mod ascii;
mod binary;

use super::mapped::Mapped;
use super::{MeshRead, ReadError, check_finite, fallback};

/// Largest header read (the Python header check reads as much).
const HEADER_LIMIT: usize = 1 << 20;

/// A PLY scalar type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Kind {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    I64,
    U64,
    F32,
    F64,
}

impl Kind {
    fn parse(name: &str) -> Option<Kind> {
        Some(match name {
            "char" | "int8" => Kind::I8,
            "uchar" | "uint8" => Kind::U8,
            "short" | "int16" => Kind::I16,
            "ushort" | "uint16" => Kind::U16,
            "int" | "int32" => Kind::I32,
            "uint" | "uint32" => Kind::U32,
            "int64" => Kind::I64,
            "uint64" => Kind::U64,
            "float" | "float32" => Kind::F32,
            "double" | "float64" => Kind::F64,
            _ => return None,
        })
    }

    pub(super) fn size(self) -> usize {
        match self {
            Kind::I8 | Kind::U8 => 1,
            Kind::I16 | Kind::U16 => 2,
            Kind::I32 | Kind::U32 | Kind::F32 => 4,
            Kind::I64 | Kind::U64 | Kind::F64 => 8,
        }
    }

    pub(super) fn is_float(self) -> bool {
        matches!(self, Kind::F32 | Kind::F64)
    }
}

/// Reads `N` bytes at `at` in the file's byte order.
#[inline(always)]
fn bytes_at<const N: usize>(data: &[u8], at: usize, big: bool) -> [u8; N] {
    let mut b: [u8; N] = data[at..at + N].try_into().unwrap_or([0; N]);
    if big {
        b.reverse();
    }
    b
}

/// A value of `kind` at `at`, as `f64` (a coordinate).
#[inline(always)]
pub(super) fn float_at(data: &[u8], at: usize, kind: Kind, big: bool) -> f64 {
    match kind {
        Kind::F32 => f64::from(f32::from_le_bytes(bytes_at(data, at, big))),
        Kind::F64 => f64::from_le_bytes(bytes_at(data, at, big)),
        _ => int_at(data, at, kind, big) as f64,
    }
}

/// A value of integer `kind` at `at` (a list length or an index; `u64` above `i64::MAX`
/// becomes negative, which every caller refuses).
#[inline(always)]
pub(super) fn int_at(data: &[u8], at: usize, kind: Kind, big: bool) -> i64 {
    match kind {
        Kind::I8 => i64::from(data[at] as i8),
        Kind::U8 => i64::from(data[at]),
        Kind::I16 => i64::from(i16::from_le_bytes(bytes_at(data, at, big))),
        Kind::U16 => i64::from(u16::from_le_bytes(bytes_at(data, at, big))),
        Kind::I32 => i64::from(i32::from_le_bytes(bytes_at(data, at, big))),
        Kind::U32 => i64::from(u32::from_le_bytes(bytes_at(data, at, big))),
        Kind::I64 => i64::from_le_bytes(bytes_at(data, at, big)),
        Kind::U64 => u64::from_le_bytes(bytes_at(data, at, big)) as i64,
        Kind::F32 | Kind::F64 => -1,
    }
}

/// A property: its name, its type, and for a list the type of its length.
#[derive(Debug, Clone)]
pub(super) struct Property {
    pub(super) name: String,
    pub(super) kind: Kind,
    pub(super) list: Option<Kind>,
}

#[derive(Debug, Clone)]
pub(super) struct Element {
    pub(super) name: String,
    pub(super) count: usize,
    pub(super) properties: Vec<Property>,
}

impl Element {
    /// Bytes of a row without lists; `None` when it has one.
    pub(super) fn fixed_row(&self) -> Option<usize> {
        self.properties
            .iter()
            .map(|p| p.list.is_none().then_some(p.kind.size()))
            .sum()
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Encoding {
    Ascii,
    Little,
    Big,
}

/// The encoding, the elements and the offset of the data.
fn header(data: &[u8]) -> Result<(Encoding, Vec<Element>, usize), ReadError> {
    let head = &data[..data.len().min(HEADER_LIMIT)];
    let Some(end) = find_end_header(head) else {
        return fallback("no end_header line");
    };
    let Ok(text) = std::str::from_utf8(&head[..end.0]) else {
        return fallback("the header is not text");
    };
    let mut lines = text.lines();
    if lines.next().map(str::trim) != Some("ply") {
        return fallback("not a PLY file");
    }
    let (mut encoding, mut elements) = (None, Vec::<Element>::new());
    for line in lines {
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            [] | ["comment", ..] | ["obj_info", ..] => {}
            ["format", "ascii", _] => encoding = Some(Encoding::Ascii),
            ["format", "binary_little_endian", _] => encoding = Some(Encoding::Little),
            ["format", "binary_big_endian", _] => encoding = Some(Encoding::Big),
            ["element", name, count] if count.bytes().all(|b| b.is_ascii_digit()) => {
                let Ok(count) = count.parse::<usize>() else {
                    return fallback("an element count beyond the address space");
                };
                elements.push(Element {
                    name: (*name).to_string(),
                    count,
                    properties: Vec::new(),
                });
            }
            ["property", "list", length, item, name] => {
                let (Some(length), Some(kind)) = (Kind::parse(length), Kind::parse(item)) else {
                    return fallback("a list property of an unknown type");
                };
                if length.is_float() {
                    return fallback("a list length of a float type");
                }
                let Some(element) = elements.last_mut() else {
                    return fallback("a property before any element");
                };
                element.properties.push(Property {
                    name: (*name).to_string(),
                    kind,
                    list: Some(length),
                });
            }
            ["property", kind, name] => {
                let (Some(kind), Some(element)) = (Kind::parse(kind), elements.last_mut()) else {
                    return fallback("a property of an unknown type, or before any element");
                };
                element.properties.push(Property {
                    name: (*name).to_string(),
                    kind,
                    list: None,
                });
            }
            _ => return fallback(format!("a header line not read here: {line:?}")),
        }
    }
    match encoding {
        Some(encoding) => Ok((encoding, elements, end.1)),
        None => fallback("no format line"),
    }
}

/// Where the `end_header` line starts and where the data after it starts.
fn find_end_header(head: &[u8]) -> Option<(usize, usize)> {
    let key = b"end_header";
    let mut at = 0;
    while let Some(found) = head[at..].windows(key.len()).position(|w| w == key) {
        let start = at + found;
        let line_start = start == 0 || matches!(head[start - 1], b'\n' | b'\r');
        let mut end = start + key.len();
        while end < head.len() && matches!(head[end], b' ' | b'\t') {
            end += 1;
        }
        let rest = &head[end..];
        let after = if rest.starts_with(b"\r\n") {
            Some(end + 2)
        } else if rest.starts_with(b"\n") || rest.starts_with(b"\r") {
            Some(end + 1)
        } else {
            None
        };
        if let (true, Some(after)) = (line_start, after) {
            return Some((start, after));
        }
        at = start + 1;
    }
    None
}

/// Where the vertex element's x, y and z are: their types and byte offsets in a row (or,
/// for ASCII, their property numbers).
pub(super) struct Coordinates {
    pub(super) kinds: [Kind; 3],
    pub(super) offsets: [usize; 3],
    pub(super) columns: [usize; 3],
}

pub(super) fn coordinates(vertex: &Element) -> Result<Coordinates, ReadError> {
    if vertex.fixed_row().is_none() {
        return fallback("a list property in the vertex element");
    }
    let mut found = Coordinates {
        kinds: [Kind::F32; 3],
        offsets: [0; 3],
        columns: [0; 3],
    };
    for (k, axis) in ["x", "y", "z"].iter().enumerate() {
        let mut offset = 0;
        let mut hit = false;
        for (column, p) in vertex.properties.iter().enumerate() {
            if p.name == *axis && !hit {
                if !p.kind.is_float() {
                    return fallback("an integer coordinate");
                }
                (found.kinds[k], found.offsets[k], found.columns[k]) = (p.kind, offset, column);
                hit = true;
            }
            offset += p.kind.size();
        }
        if !hit {
            return fallback(format!("no property {axis:?}"));
        }
    }
    Ok(found)
}

/// The face element's list of vertex indices: its property number.
pub(super) fn index_list(face: &Element) -> Result<usize, ReadError> {
    let lists: Vec<usize> = (0..face.properties.len())
        .filter(|&i| face.properties[i].list.is_some())
        .collect();
    let named = lists.iter().copied().find(|&i| {
        matches!(
            face.properties[i].name.as_str(),
            "vertex_indices" | "vertex_index"
        )
    });
    match (named, lists.as_slice()) {
        (Some(i), _) | (None, &[i]) if !face.properties[i].kind.is_float() => Ok(i),
        _ => fallback("no integer list of vertex indices in the face element"),
    }
}

/// Reads a PLY file.
pub(crate) fn read(mapped: &Mapped) -> Result<MeshRead, ReadError> {
    let data = mapped.bytes();
    let (encoding, elements, start) = header(data)?;
    let (Some(vi), Some(fi)) = (
        elements.iter().position(|e| e.name == "vertex"),
        elements.iter().position(|e| e.name == "face"),
    ) else {
        return fallback("no vertex or no face element");
    };
    if elements[vi].count > u32::MAX as usize {
        return fallback("more vertices than u32 indices reach");
    }
    let read = match encoding {
        Encoding::Ascii => ascii::read_ascii(mapped, &elements, start, vi, fi)?,
        Encoding::Little | Encoding::Big => {
            binary::read_binary(mapped, &elements, start, vi, fi, encoding == Encoding::Big)?
        }
    };
    check_finite(&read.vertices)?;
    Ok(read)
}
