//! Vertex welding and the unique-edge table of a triangle mesh.
//!
//! The edge table groups the three edges of every triangle by their unordered vertex pair,
//! keeping the vertex opposite the edge in that triangle: a counting sort on the smaller
//! vertex index followed by a tiny sort inside each bucket, so building it is linear in the
//! face count and its content does not depend on the number of threads.

use rayon::prelude::*;

use crate::error::MeshError;

/// At most this many vertex ranges are built in parallel (each one scans all faces).
const RANGE_PARTS_MAX: usize = 8;

/// Result of welding vertices with bit-identical coordinates.
#[derive(Debug, Clone)]
pub struct Weld {
    /// `canonical[i]` is the smallest index whose coordinates equal vertex `i`'s.
    pub canonical: Vec<u32>,
    /// How many vertices were mapped onto another one (`n - distinct`).
    pub merged: usize,
}

/// Bit pattern of a coordinate with `-0.0` folded onto `+0.0`, so that equal values weld.
#[inline]
#[must_use]
fn coordinate_key(x: f64) -> u64 {
    if x == 0.0 { 0 } else { x.to_bits() }
}

/// Mixes the three coordinate keys of a vertex into a 64-bit hash (a multiply-xorshift
/// finaliser over a running combination; collisions are resolved by full comparison).
#[inline]
#[must_use]
fn vertex_hash(key: [u64; 3]) -> u64 {
    let mut h = 0x9E37_79B9_7F4A_7C15u64;
    for k in key {
        h = (h ^ k).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        h ^= h >> 31;
    }
    h.wrapping_mul(0x94D0_49BB_1331_11EB) ^ (h >> 29)
}

/// Welds vertices whose three coordinates are exactly equal (`-0.0 == 0.0`).
///
/// Triangle soups (STL files) repeat every shared vertex once per triangle; without
/// welding every edge would look like a boundary. Open-addressing hash table with linear
/// probing, filled in index order so that the first (smallest) index of each set of equal
/// vertices becomes its representative: expected O(n), deterministic.
#[must_use]
pub fn weld_identical(vertices: &[[f64; 3]]) -> Weld {
    let n = vertices.len();
    let key = |v: &[f64; 3]| {
        [
            coordinate_key(v[0]),
            coordinate_key(v[1]),
            coordinate_key(v[2]),
        ]
    };
    let hashes: Vec<u64> = vertices.par_iter().map(|v| vertex_hash(key(v))).collect();
    let capacity = (2 * n).next_power_of_two().max(16);
    let mask = capacity - 1;
    let mut slots = vec![u32::MAX; capacity];
    let mut canonical: Vec<u32> = Vec::with_capacity(n);
    let mut merged = 0;
    for (i, v) in vertices.iter().enumerate() {
        let k = key(v);
        let mut slot = (hashes[i] as usize) & mask;
        loop {
            let occupant = slots[slot];
            if occupant == u32::MAX {
                slots[slot] = i as u32;
                canonical.push(i as u32);
                break;
            }
            if hashes[occupant as usize] == hashes[i] && key(&vertices[occupant as usize]) == k {
                canonical.push(occupant);
                merged += 1;
                break;
            }
            slot = (slot + 1) & mask;
        }
    }
    Weld { canonical, merged }
}

/// True when a face repeats a vertex index: it has no area and no well-defined edges.
#[inline]
#[must_use]
pub fn is_index_degenerate(face: &[u32; 3]) -> bool {
    face[0] == face[1] || face[1] == face[2] || face[2] == face[0]
}

/// Unique undirected edges of a triangle mesh with the vertex opposite each edge in each
/// incident triangle.
#[derive(Debug, Clone)]
pub struct EdgeTable {
    /// Unique edges as `(lo, hi)` with `lo < hi`, sorted lexicographically.
    pub edges: Vec<[u32; 2]>,
    /// The triangles of edge `e` are `(lo, hi, opposite[i])` for
    /// `i in starts[e] .. starts[e + 1]`, by ascending opposite vertex.
    pub starts: Vec<usize>,
    /// Opposite vertices, grouped by edge.
    pub opposite: Vec<u32>,
    /// Faces that repeat a vertex index; they are left out of the table.
    pub index_degenerate_faces: usize,
}

/// The edges whose smaller vertex lies in one range of vertex indices.
struct EdgeRange {
    edges: Vec<[u32; 2]>,
    starts: Vec<usize>,
    opposite: Vec<u32>,
}

/// Builds the edges whose smaller vertex is in `v0..v1`: counting sort of the half-edges
/// by smaller vertex, then a sort of each (tiny) bucket by `(hi, opposite)`.
fn edge_range(faces: &[[u32; 3]], v0: usize, v1: usize) -> EdgeRange {
    let in_range = |lo: u32| (v0..v1).contains(&(lo as usize));
    let mut bucket_starts = vec![0usize; v1 - v0 + 1];
    for f in faces {
        if is_index_degenerate(f) {
            continue;
        }
        for lo in [f[0].min(f[1]), f[1].min(f[2]), f[2].min(f[0])] {
            if in_range(lo) {
                bucket_starts[lo as usize - v0 + 1] += 1;
            }
        }
    }
    for i in 0..v1 - v0 {
        bucket_starts[i + 1] += bucket_starts[i];
    }
    // Entry `hi << 32 | opposite`: sorting a bucket's entries orders it by (hi, opposite).
    let mut cursor = bucket_starts.clone();
    let mut entries = vec![0u64; bucket_starts[v1 - v0]];
    for f in faces {
        if is_index_degenerate(f) {
            continue;
        }
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            let lo = a.min(b);
            if in_range(lo) {
                let slot = &mut cursor[lo as usize - v0];
                entries[*slot] = (u64::from(a.max(b)) << 32) | u64::from(f[(k + 2) % 3]);
                *slot += 1;
            }
        }
    }
    let mut edges = Vec::with_capacity(entries.len() / 2 + 1);
    let mut starts = Vec::with_capacity(entries.len() / 2 + 1);
    for v in v0..v1 {
        let (b0, b1) = (bucket_starts[v - v0], bucket_starts[v - v0 + 1]);
        let bucket = &mut entries[b0..b1];
        bucket.sort_unstable();
        let mut i = 0;
        while i < bucket.len() {
            let hi = bucket[i] >> 32;
            edges.push([v as u32, hi as u32]);
            starts.push(b0 + i);
            while i < bucket.len() && bucket[i] >> 32 == hi {
                i += 1;
            }
        }
    }
    let opposite = entries.iter().map(|&e| e as u32).collect();
    EdgeRange {
        edges,
        starts,
        opposite,
    }
}

impl EdgeTable {
    /// Builds the table. Faces must already be index-checked against the vertex count.
    ///
    /// The vertex indices are split into ranges handled in parallel; each range scans all
    /// faces, so the table is identical for any number of threads.
    pub fn build(faces: &[[u32; 3]], vertex_count: usize) -> Result<Self, MeshError> {
        if faces.len() > (u32::MAX / 3) as usize {
            return Err(MeshError::Parameter(format!(
                "{} faces exceed the supported maximum of {}",
                faces.len(),
                u32::MAX / 3
            )));
        }
        let parts = rayon::current_num_threads().clamp(1, RANGE_PARTS_MAX);
        let ranges: Vec<EdgeRange> = (0..parts)
            .into_par_iter()
            .map(|p| {
                edge_range(
                    faces,
                    p * vertex_count / parts,
                    (p + 1) * vertex_count / parts,
                )
            })
            .collect();
        let edge_count = ranges.iter().map(|r| r.edges.len()).sum();
        let mut table = EdgeTable {
            edges: Vec::with_capacity(edge_count),
            starts: Vec::with_capacity(edge_count + 1),
            opposite: Vec::with_capacity(ranges.iter().map(|r| r.opposite.len()).sum()),
            index_degenerate_faces: faces.iter().filter(|f| is_index_degenerate(f)).count(),
        };
        for range in ranges {
            let offset = table.opposite.len();
            table.edges.extend(range.edges);
            table.starts.extend(range.starts.iter().map(|s| s + offset));
            table.opposite.extend(range.opposite);
        }
        table.starts.push(table.opposite.len());
        Ok(table)
    }

    /// Number of unique edges.
    #[inline]
    #[must_use]
    pub fn len(&self) -> usize {
        self.edges.len()
    }

    /// True when the table holds no edge.
    #[inline]
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.edges.is_empty()
    }

    /// Opposite vertices of the triangles incident to edge `e` (one per triangle).
    #[inline]
    #[must_use]
    pub fn incident(&self, e: usize) -> &[u32] {
        &self.opposite[self.starts[e]..self.starts[e + 1]]
    }

    /// Checks the table's invariants against the faces it was built from: edges strictly
    /// sorted, every non-degenerate face's three edges present with its opposite vertex,
    /// and nothing else.
    pub fn validate(&self, faces: &[[u32; 3]]) -> Result<(), String> {
        if self.starts.len() != self.edges.len() + 1 {
            return Err("starts must have one entry more than edges".into());
        }
        let mut expected: Vec<(u32, u32, u32)> = faces
            .iter()
            .filter(|f| !is_index_degenerate(f))
            .flat_map(|f| {
                (0..3).map(move |k| {
                    let (a, b) = (f[k], f[(k + 1) % 3]);
                    (a.min(b), a.max(b), f[(k + 2) % 3])
                })
            })
            .collect();
        expected.sort_unstable();
        let mut found = Vec::with_capacity(self.opposite.len());
        for (e, edge) in self.edges.iter().enumerate() {
            if edge[0] >= edge[1] {
                return Err(format!("edge {e} is not ordered lo < hi"));
            }
            if e > 0 && self.edges[e - 1] >= *edge {
                return Err(format!("edges {} and {e} are not strictly sorted", e - 1));
            }
            if self.incident(e).is_empty() {
                return Err(format!("edge {e} has no triangle"));
            }
            found.extend(self.incident(e).iter().map(|&o| (edge[0], edge[1], o)));
        }
        if found != expected {
            return Err("the table's (edge, opposite) triples differ from the faces'".into());
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tetrahedron_has_six_edges_each_with_two_faces() {
        let faces = [[0, 1, 2], [0, 3, 1], [1, 3, 2], [2, 3, 0]];
        let table = EdgeTable::build(&faces, 4).unwrap();
        table.validate(&faces).unwrap();
        assert_eq!(table.len(), 6);
        assert!((0..6).all(|e| table.incident(e).len() == 2));
    }

    #[test]
    fn repeated_indices_are_left_out_and_counted() {
        let faces = [[0, 1, 2], [0, 0, 1]];
        let table = EdgeTable::build(&faces, 3).unwrap();
        table.validate(&faces).unwrap();
        assert_eq!(table.index_degenerate_faces, 1);
        assert_eq!(table.len(), 3);
    }

    #[test]
    fn fan_of_three_faces_on_one_edge() {
        let faces = [[0, 1, 2], [1, 0, 3], [0, 1, 4]];
        let table = EdgeTable::build(&faces, 5).unwrap();
        table.validate(&faces).unwrap();
        let e = table.edges.iter().position(|e| *e == [0, 1]).unwrap();
        assert_eq!(table.incident(e).len(), 3);
    }

    #[test]
    fn validator_accepts_every_strip_size() {
        for n in 1..=100u32 {
            let faces: Vec<[u32; 3]> = (0..n).map(|i| [i, i + 1, i + 2]).collect();
            let table = EdgeTable::build(&faces, n as usize + 2).unwrap();
            table.validate(&faces).unwrap();
            assert_eq!(table.len(), 2 * n as usize + 1);
        }
    }

    #[test]
    fn weld_maps_to_smallest_index_and_folds_signed_zero() {
        let v = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [-0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
        ];
        let weld = weld_identical(&v);
        assert_eq!(weld.canonical, vec![0, 1, 0, 1]);
        assert_eq!(weld.merged, 2);
    }
}
