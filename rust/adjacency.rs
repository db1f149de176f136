//! The unique-edge table of a triangle mesh (welding identical vertices first is
//! [`crate::weld`]).
//!
//! The edge table groups the three edges of every triangle by their unordered vertex pair
//! `(lo, hi)`, keeping the vertex opposite the edge in that triangle. Each half-edge is one
//! packed integer `(lo mod 2^b) << 2v | hi << v | opposite` (`v` bits per vertex index), so
//! that integer order is `(lo, hi, opposite)` order within a block of `2^b` vertices:
//!
//! 1. the faces are cut into chunks; each chunk, in parallel, counting-sorts its half-edges
//!    by the block of `lo` into a buffer of its own (one pass to count, one to place);
//! 2. each block, in parallel, gathers its half-edges from every chunk, counting-sorts them
//!    by `lo` inside the block (in cache: about 24k half-edges for 4096 vertices) and sorts
//!    each vertex's few entries; runs of equal `(lo, hi)` are the edges.
//!
//! Every face is read twice whatever the thread count, the work is spread over many
//! blocks, and the table, fully sorted, does not depend on the number of threads or on the
//! chunking. Block consumers (shape complexity) work on a block's edges while they are in
//! cache and never build the whole table.

use rayon::prelude::*;

use crate::error::{MeshError, VertexIndex};

/// Vertices per block of the edge sort, as a power of two: with about six half-edges per
/// vertex a block's entries (192 KiB) and its counts stay in a core's L2 cache.
const BLOCK_BITS: u32 = 12;

/// Narrowest block, in bits, of `u64` half-edge keys; meshes whose vertex indices leave
/// less room (more than 2^28 vertices) use `u128` keys.
const MIN_BLOCK_BITS: u32 = 8;

/// Fewest faces per chunk of the counting pass.
const MIN_FACE_CHUNK: usize = 1 << 15;

/// True when a face repeats a vertex index: it has no area and no well-defined edges.
#[inline]
#[must_use]
pub fn is_index_degenerate(face: &[u32; 3]) -> bool {
    face[0] == face[1] || face[1] == face[2] || face[2] == face[0]
}

/// A face's corners as `u32` (indices already checked against the vertex count).
#[inline]
fn corners<I: VertexIndex>(f: &[I; 3]) -> [u32; 3] {
    [
        f[0].to_usize() as u32,
        f[1].to_usize() as u32,
        f[2].to_usize() as u32,
    ]
}

/// One half-edge packed so that integer order is `(lo, hi, opposite)` order inside a block
/// of vertices: `local << 2v | hi << v | opposite`, `local = lo mod 2^b`, `v` the bits of a
/// vertex index field.
trait HalfEdgeKey: Copy + Ord + Default + Send + Sync {
    fn pack(local: u32, hi: u32, opposite: u32, v: u32) -> Self;
    fn local(self, v: u32) -> usize;
    fn hi(self, v: u32) -> u32;
    fn opposite(self, v: u32) -> u32;
}

macro_rules! half_edge_key {
    ($t:ty) => {
        impl HalfEdgeKey for $t {
            #[inline]
            fn pack(local: u32, hi: u32, opposite: u32, v: u32) -> Self {
                (<$t>::from(local) << (2 * v)) | (<$t>::from(hi) << v) | <$t>::from(opposite)
            }
            #[inline]
            fn local(self, v: u32) -> usize {
                (self >> (2 * v)) as usize
            }
            #[inline]
            fn hi(self, v: u32) -> u32 {
                ((self >> v) & ((1 << v) - 1)) as u32
            }
            #[inline]
            fn opposite(self, v: u32) -> u32 {
                (self & ((1 << v) - 1)) as u32
            }
        }
    };
}
half_edge_key!(u64);
half_edge_key!(u128);

/// The edges of one block of vertices, sorted by `(lo, hi)`, as [`map_edge_blocks`] hands
/// them to its consumer: the same layout as an [`EdgeTable`], `starts` local to the block.
#[derive(Debug, Clone, Copy)]
pub struct BlockEdges<'a> {
    pub edges: &'a [[u32; 2]],
    pub starts: &'a [u32],
    pub opposite: &'a [u32],
}

impl BlockEdges<'_> {
    /// Number of edges in the block.
    #[inline]
    #[must_use]
    pub fn len(&self) -> usize {
        self.edges.len()
    }

    /// True when the block holds no edge.
    #[inline]
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.edges.is_empty()
    }

    /// Opposite vertices of the triangles incident to edge `e`, ascending.
    #[inline]
    #[must_use]
    pub fn incident(&self, e: usize) -> &[u32] {
        &self.opposite[self.starts[e] as usize..self.starts[e + 1] as usize]
    }
}

/// A worker's buffers for one block: sorted keys, per-vertex counts, and the block's table.
#[derive(Default)]
struct BlockScratch<K> {
    sorted: Vec<K>,
    count: Vec<u32>,
    edges: Vec<[u32; 2]>,
    starts: Vec<u32>,
    opposite: Vec<u32>,
}

/// Bits needed for the largest vertex index of `vertex_count` vertices (at least 1).
fn index_bits(vertex_count: usize) -> u32 {
    (usize::BITS - vertex_count.saturating_sub(1).leading_zeros()).max(1)
}

/// Builds the edge table block by block (see the module docs) and returns
/// `consume(block)` for every block of vertices, in vertex order, with the number of faces
/// that repeat a vertex index (left out of the table).
///
/// Faces must already be index-checked against `vertex_count`.
pub fn map_edge_blocks<I, R, F>(
    faces: &[[I; 3]],
    vertex_count: usize,
    consume: F,
) -> Result<(Vec<R>, usize), MeshError>
where
    I: VertexIndex,
    R: Send,
    F: Fn(BlockEdges<'_>) -> R + Sync,
{
    if faces.len() > (u32::MAX / 3) as usize || vertex_count > u32::MAX as usize {
        return Err(MeshError::Parameter(format!(
            "{} faces or {vertex_count} vertices exceed the supported maximum of {} faces \
             and 2^32 - 1 vertices",
            faces.len(),
            u32::MAX / 3
        )));
    }
    let v = index_bits(vertex_count);
    if 64 - 2 * v >= MIN_BLOCK_BITS {
        Ok(map_blocks_with::<u64, I, R, F>(
            faces,
            vertex_count,
            v,
            BLOCK_BITS.min(64 - 2 * v),
            consume,
        ))
    } else {
        Ok(map_blocks_with::<u128, I, R, F>(
            faces,
            vertex_count,
            32,
            BLOCK_BITS,
            consume,
        ))
    }
}

/// [`map_edge_blocks`] with keys of type `K`, `v` bits per vertex field and blocks of
/// `2^block_bits` vertices.
fn map_blocks_with<K, I, R, F>(
    faces: &[[I; 3]],
    vertex_count: usize,
    v: u32,
    block_bits: u32,
    consume: F,
) -> (Vec<R>, usize)
where
    K: HalfEdgeKey,
    I: VertexIndex,
    R: Send,
    F: Fn(BlockEdges<'_>) -> R + Sync,
{
    let blocks = vertex_count.div_ceil(1 << block_bits).max(1);
    let parts = (4 * rayon::current_num_threads())
        .min(faces.len() / MIN_FACE_CHUNK)
        .max(1);
    let chunk = faces.len().div_ceil(parts).max(1);
    // Step 1: per chunk, its half-edges by block (`start[b]..start[b + 1]`).
    let chunks: Vec<ChunkHalfEdges<K>> = faces
        .par_chunks(chunk)
        .map(|chunk| chunk_half_edges(chunk, blocks, block_bits, v))
        .collect();
    let degenerate = chunks.iter().map(|c| c.2).sum();
    // Step 2: per block, gather, sort by (lo, hi, opposite), split into edges.
    let results = (0..blocks)
        .into_par_iter()
        .map_init(BlockScratch::<K>::default, |s, b| {
            let base = (b as u32) << block_bits;
            let size = (vertex_count - base as usize).min(1 << block_bits);
            block_edges(s, &chunks, b, base, size, v);
            consume(BlockEdges {
                edges: &s.edges,
                starts: &s.starts,
                opposite: &s.opposite,
            })
        })
        .collect();
    (results, degenerate)
}

/// One chunk of faces' half-edges, counting-sorted by block: the blocks' starts
/// (`start[b]..start[b + 1]`), the packed keys, and the faces that repeat a vertex index
/// (left out).
type ChunkHalfEdges<K> = (Vec<usize>, Vec<K>, usize);

/// Step 1 of [`map_blocks_with`] on one chunk of faces: one pass to count the half-edges
/// of each block of `2^block_bits` vertices (by their `lo` vertex), one to place them.
#[inline]
fn chunk_half_edges<K: HalfEdgeKey, I: VertexIndex>(
    chunk: &[[I; 3]],
    blocks: usize,
    block_bits: u32,
    v: u32,
) -> ChunkHalfEdges<K> {
    let block_mask = (1u32 << block_bits) - 1;
    let mut start = vec![0usize; blocks + 1];
    let mut degenerate = 0;
    for f in chunk {
        let [a, b, c] = corners(f);
        if is_index_degenerate(&[a, b, c]) {
            degenerate += 1;
            continue;
        }
        for lo in [a.min(b), b.min(c), c.min(a)] {
            start[(lo >> block_bits) as usize + 1] += 1;
        }
    }
    for b in 0..blocks {
        start[b + 1] += start[b];
    }
    let mut cursor = start.clone();
    let mut keys = vec![K::default(); start[blocks]];
    for f in chunk {
        let t = corners(f);
        if is_index_degenerate(&t) {
            continue;
        }
        for k in 0..3 {
            let (a, b, o) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
            let (lo, hi) = (a.min(b), a.max(b));
            let slot = &mut cursor[(lo >> block_bits) as usize];
            keys[*slot] = K::pack(lo & block_mask, hi, o, v);
            *slot += 1;
        }
    }
    (start, keys, degenerate)
}

/// Step 2 of [`map_blocks_with`] for block `b` (vertices `base .. base + size`): its
/// half-edges gathered from every chunk, counting-sorted by `lo`, each vertex's few
/// entries sorted, and runs of equal `(lo, hi)` written to `s` as the block's edges.
#[inline]
fn block_edges<K: HalfEdgeKey>(
    s: &mut BlockScratch<K>,
    chunks: &[ChunkHalfEdges<K>],
    b: usize,
    base: u32,
    size: usize,
    v: u32,
) {
    s.count.clear();
    s.count.resize(size + 1, 0);
    for (start, keys, _) in chunks {
        for &key in &keys[start[b]..start[b + 1]] {
            s.count[key.local(v) + 1] += 1;
        }
    }
    for i in 0..size {
        s.count[i + 1] += s.count[i];
    }
    let total = s.count[size] as usize;
    s.sorted.clear();
    s.sorted.resize(total, K::default());
    for (start, keys, _) in chunks {
        for &key in &keys[start[b]..start[b + 1]] {
            let slot = &mut s.count[key.local(v)];
            s.sorted[*slot as usize] = key;
            *slot += 1;
        }
    }
    // `count[i]` now ends vertex `i`'s run (and starts vertex `i + 1`'s).
    s.edges.clear();
    s.starts.clear();
    s.opposite.clear();
    let mut begin = 0;
    for i in 0..size {
        let end = s.count[i] as usize;
        let run = &mut s.sorted[begin..end];
        run.sort_unstable();
        let lo = base + i as u32;
        let mut previous = None;
        for &key in run.iter() {
            let hi = key.hi(v);
            if previous != Some(hi) {
                s.edges.push([lo, hi]);
                s.starts.push(s.opposite.len() as u32);
                previous = Some(hi);
            }
            s.opposite.push(key.opposite(v));
        }
        begin = end;
    }
    s.starts.push(s.opposite.len() as u32);
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

impl EdgeTable {
    /// Builds the table (see the module docs). Faces must already be index-checked
    /// against the vertex count. The table is identical for any number of threads.
    pub fn build<I: VertexIndex>(faces: &[[I; 3]], vertex_count: usize) -> Result<Self, MeshError> {
        let (blocks, index_degenerate_faces) = map_edge_blocks(faces, vertex_count, |b| {
            (b.edges.to_vec(), b.starts.to_vec(), b.opposite.to_vec())
        })?;
        let edge_count = blocks.iter().map(|b| b.0.len()).sum();
        let mut table = EdgeTable {
            edges: Vec::with_capacity(edge_count),
            starts: Vec::with_capacity(edge_count + 1),
            opposite: Vec::with_capacity(blocks.iter().map(|b| b.2.len()).sum()),
            index_degenerate_faces,
        };
        for (edges, starts, opposite) in blocks {
            let offset = table.opposite.len();
            table.edges.extend(edges);
            table.starts.extend(
                starts[..starts.len() - 1]
                    .iter()
                    .map(|&s| s as usize + offset),
            );
            table.opposite.extend(opposite);
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
    fn wide_keys_build_the_same_table() {
        // A band of faces on vertices spread over many blocks, with repeats and a fan.
        let n = 20_000u32;
        let mut faces: Vec<[u32; 3]> = (0..3 * n)
            .map(|i| {
                let a = (i * 7919) % n;
                [a, (a + 1 + i % 5) % n, (a * 31 + 17) % n]
            })
            .collect();
        faces.extend_from_within(..100);
        let narrow = EdgeTable::build(&faces, n as usize).unwrap();
        narrow.validate(&faces).unwrap();
        let (wide, degenerate) =
            map_blocks_with::<u128, u32, _, _>(&faces, n as usize, 32, 5, |b| {
                b.edges
                    .iter()
                    .enumerate()
                    .map(|(e, &edge)| (edge, b.incident(e).to_vec()))
                    .collect::<Vec<_>>()
            });
        assert_eq!(degenerate, narrow.index_degenerate_faces);
        let wide: Vec<_> = wide.into_iter().flatten().collect();
        assert_eq!(wide.len(), narrow.len());
        for (e, (edge, incident)) in wide.iter().enumerate() {
            assert_eq!(*edge, narrow.edges[e]);
            assert_eq!(incident.as_slice(), narrow.incident(e));
        }
    }

    #[test]
    fn signed_indices_build_the_same_table() {
        let faces = [[0u32, 1, 2], [0, 3, 1], [1, 3, 2], [2, 3, 0]];
        let signed: Vec<[i64; 3]> = faces.iter().map(|f| f.map(i64::from)).collect();
        let a = EdgeTable::build(&faces, 4).unwrap();
        let b = EdgeTable::build(&signed, 4).unwrap();
        assert_eq!(
            (a.edges, a.starts, a.opposite),
            (b.edges, b.starts, b.opposite)
        );
    }
}
