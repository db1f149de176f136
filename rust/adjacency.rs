//! Vertex welding and the unique-edge table of a triangle mesh.
//!
//! A half-edge is identified by `face * 3 + k`: it runs from corner `k` to corner
//! `(k + 1) % 3` of `face`, and the corner opposite it is `(k + 2) % 3`. The edge table
//! groups half-edges by their unordered vertex pair with a counting sort on the smaller
//! vertex index followed by a tiny sort inside each bucket, so building it is linear in the
//! face count and its order does not depend on the number of threads.

use rayon::prelude::*;

use crate::error::MeshError;

/// Half-edges per parallel work unit when sorting buckets.
const BUCKET_BLOCK: usize = 1 << 14;

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

/// Welds vertices whose three coordinates are exactly equal (`-0.0 == 0.0`).
///
/// Triangle soups (STL files) repeat every shared vertex once per triangle; without
/// welding every edge would look like a boundary. O(n log n), parallel, deterministic.
#[must_use]
pub fn weld_identical(vertices: &[[f64; 3]]) -> Weld {
    let n = vertices.len();
    let mut order: Vec<u32> = (0..n as u32).collect();
    let key = |i: u32| {
        let v = vertices[i as usize];
        (coordinate_key(v[0]), coordinate_key(v[1]), coordinate_key(v[2]), i)
    };
    order.par_sort_unstable_by_key(|&i| key(i));
    let mut canonical: Vec<u32> = (0..n as u32).collect();
    let mut merged = 0;
    let mut run_start = 0;
    for pos in 1..=n {
        let same = pos < n && {
            let (ax, ay, az, _) = key(order[run_start]);
            let (bx, by, bz, _) = key(order[pos]);
            (ax, ay, az) == (bx, by, bz)
        };
        if !same {
            // `order` is sorted by index inside a run, so its first element is the smallest.
            let representative = order[run_start];
            for &i in &order[run_start + 1..pos] {
                canonical[i as usize] = representative;
                merged += 1;
            }
            run_start = pos;
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

/// Unique undirected edges of a triangle mesh with their incident half-edges.
#[derive(Debug, Clone)]
pub struct EdgeTable {
    /// Unique edges as `(lo, hi)` with `lo < hi`, sorted lexicographically.
    pub edges: Vec<[u32; 2]>,
    /// Half-edges of edge `e` are `halfedges[starts[e] .. starts[e + 1]]`, by ascending id.
    pub starts: Vec<usize>,
    /// Half-edge ids `face * 3 + k`, grouped by edge.
    pub halfedges: Vec<u32>,
    /// Faces that repeat a vertex index; they are left out of the table.
    pub index_degenerate_faces: usize,
}

impl EdgeTable {
    /// Builds the table. Faces must already be index-checked against the vertex count.
    pub fn build(faces: &[[u32; 3]], vertex_count: usize) -> Result<Self, MeshError> {
        if faces.len() > (u32::MAX / 3) as usize {
            return Err(MeshError::Parameter(format!(
                "{} faces exceed the supported maximum of {}",
                faces.len(),
                u32::MAX / 3
            )));
        }
        let lo_hi = |h: u32| -> (u32, u32) {
            let face = &faces[(h / 3) as usize];
            let k = (h % 3) as usize;
            let (a, b) = (face[k], face[(k + 1) % 3]);
            if a < b { (a, b) } else { (b, a) }
        };

        let mut counts = vec![0usize; vertex_count + 1];
        let mut index_degenerate_faces = 0;
        for face in faces {
            if is_index_degenerate(face) {
                index_degenerate_faces += 1;
                continue;
            }
            for k in 0..3 {
                counts[face[k].min(face[(k + 1) % 3]) as usize + 1] += 1;
            }
        }
        for v in 0..vertex_count {
            counts[v + 1] += counts[v];
        }
        let bucket_starts = counts;
        let mut cursor = bucket_starts.clone();
        let mut halfedges = vec![0u32; bucket_starts[vertex_count]];
        for (f, face) in faces.iter().enumerate() {
            if is_index_degenerate(face) {
                continue;
            }
            for k in 0..3 {
                let lo = face[k].min(face[(k + 1) % 3]) as usize;
                halfedges[cursor[lo]] = (f * 3 + k) as u32;
                cursor[lo] += 1;
            }
        }
        drop(cursor);

        // Split the half-edge array into blocks of whole buckets, sort each bucket by
        // (hi, id) and collect the edges of each block; blocks are concatenated in order.
        let mut block_bounds = vec![0usize];
        let mut next_cut = BUCKET_BLOCK;
        for v in 0..vertex_count {
            if bucket_starts[v + 1] >= next_cut {
                block_bounds.push(v + 1);
                next_cut = bucket_starts[v + 1] + BUCKET_BLOCK;
            }
        }
        if *block_bounds.last().unwrap_or(&0) != vertex_count {
            block_bounds.push(vertex_count);
        }
        let mut slices: Vec<(usize, usize, &mut [u32])> = Vec::with_capacity(block_bounds.len());
        let mut rest: &mut [u32] = &mut halfedges;
        for w in block_bounds.windows(2) {
            let len = bucket_starts[w[1]] - bucket_starts[w[0]];
            let (head, tail) = rest.split_at_mut(len);
            slices.push((w[0], w[1], head));
            rest = tail;
        }
        let blocks: Vec<(Vec<[u32; 2]>, Vec<usize>)> = slices
            .into_par_iter()
            .map(|(v0, v1, block)| {
                let base = bucket_starts[v0];
                let mut edges = Vec::new();
                let mut starts = Vec::new();
                for v in v0..v1 {
                    let bucket = &mut block[bucket_starts[v] - base..bucket_starts[v + 1] - base];
                    bucket.sort_unstable_by_key(|&h| (lo_hi(h).1, h));
                    let mut i = 0;
                    while i < bucket.len() {
                        let hi = lo_hi(bucket[i]).1;
                        edges.push([v as u32, hi]);
                        starts.push(bucket_starts[v] + i);
                        while i < bucket.len() && lo_hi(bucket[i]).1 == hi {
                            i += 1;
                        }
                    }
                }
                (edges, starts)
            })
            .collect();
        let edge_count: usize = blocks.iter().map(|b| b.0.len()).sum();
        let mut edges = Vec::with_capacity(edge_count);
        let mut starts = Vec::with_capacity(edge_count + 1);
        for (block_edges, block_starts) in blocks {
            edges.extend(block_edges);
            starts.extend(block_starts);
        }
        starts.push(halfedges.len());
        Ok(EdgeTable { edges, starts, halfedges, index_degenerate_faces })
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

    /// Half-edge ids incident to edge `e`.
    #[inline]
    #[must_use]
    pub fn incident(&self, e: usize) -> &[u32] {
        &self.halfedges[self.starts[e]..self.starts[e + 1]]
    }

    /// Checks the table's invariants against the faces it was built from.
    pub fn validate(&self, faces: &[[u32; 3]]) -> Result<(), String> {
        if self.starts.len() != self.edges.len() + 1 {
            return Err("starts must have one entry more than edges".into());
        }
        let expected: usize = faces.iter().filter(|f| !is_index_degenerate(f)).count() * 3;
        if self.halfedges.len() != expected {
            return Err(format!("{} half-edges, expected {expected}", self.halfedges.len()));
        }
        for (e, edge) in self.edges.iter().enumerate() {
            if edge[0] >= edge[1] {
                return Err(format!("edge {e} is not ordered lo < hi"));
            }
            if e > 0 && self.edges[e - 1] >= *edge {
                return Err(format!("edges {} and {e} are not strictly sorted", e - 1));
            }
            let incident = self.incident(e);
            if incident.is_empty() {
                return Err(format!("edge {e} has no half-edge"));
            }
            for &h in incident {
                let face = faces[(h / 3) as usize];
                let k = (h % 3) as usize;
                let (a, b) = (face[k], face[(k + 1) % 3]);
                if [a.min(b), a.max(b)] != *edge {
                    return Err(format!("half-edge {h} is filed under the wrong edge {e}"));
                }
            }
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
        let v = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [-0.0, 0.0, 0.0], [1.0, 0.0, 0.0]];
        let weld = weld_identical(&v);
        assert_eq!(weld.canonical, vec![0, 1, 0, 1]);
        assert_eq!(weld.merged, 2);
    }
}
