//! Vertex welding: vertices with bit-identical coordinates merged into the smallest such
//! index (`-0.0` and `+0.0` weld), before the edge table ([`crate::adjacency`]) or the
//! simplifier see the mesh.

use rayon::prelude::*;

use crate::error::{MeshError, check_indices};

/// Vertices per partition of the parallel weld (the partition's table stays in cache).
const WELD_PARTITION_TARGET: usize = 1 << 15;

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

/// One chunk's vertices listed by weld partition: the partitions' starts, and each
/// vertex's `(hash, index)` in partition order.
type PartitionLists = (Vec<usize>, Vec<(u64, u32)>);

/// Welds vertices whose three coordinates are exactly equal (`-0.0 == 0.0`).
///
/// Triangle soups (STL files) repeat every shared vertex once per triangle; without
/// welding every edge would look like a boundary. The vertices are split by the top bits
/// of their hash into partitions of about `WELD_PARTITION_TARGET`, each listed in
/// ascending index order; each partition, in parallel, runs an open-addressing table
/// (linear probing, collisions resolved by full comparison) filled in index order, so the
/// first (smallest) index of each set of equal vertices becomes its representative:
/// expected O(n), the same for any thread count.
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
    let hashes: Vec<u64> = vertices
        .par_iter()
        .with_min_len(1 << 12)
        .map(|v| vertex_hash(key(v)))
        .collect();
    let part_bits = (n / WELD_PARTITION_TARGET)
        .max(1)
        .next_power_of_two()
        .trailing_zeros();
    let parts = 1usize << part_bits;
    let part_of = |h: u64| (h >> 32 >> (32 - part_bits)) as usize;
    // Each chunk lists its vertices by partition, in index order, each with its hash: the
    // partitions then read their lists in sequence and touch a vertex only when its hash
    // matches an earlier one's.
    let chunk = n.div_ceil(4 * rayon::current_num_threads()).max(1 << 14);
    let lists: Vec<PartitionLists> = hashes
        .par_chunks(chunk)
        .enumerate()
        .map(|(c, hs)| {
            let mut start = vec![0usize; parts + 1];
            for &h in hs {
                start[part_of(h) + 1] += 1;
            }
            for p in 0..parts {
                start[p + 1] += start[p];
            }
            let mut cursor = start.clone();
            let mut list = vec![(0u64, 0u32); hs.len()];
            for (j, &h) in hs.iter().enumerate() {
                let slot = &mut cursor[part_of(h)];
                list[*slot] = (h, (c * chunk + j) as u32);
                *slot += 1;
            }
            (start, list)
        })
        .collect();
    // Each partition, in index order: the pairs (vertex, earlier equal vertex).
    let merges: Vec<Vec<(u32, u32)>> = (0..parts)
        .into_par_iter()
        .map_init(Vec::new, |slots: &mut Vec<(u64, u32)>, p| {
            let len: usize = lists.iter().map(|(s, _)| s[p + 1] - s[p]).sum();
            let capacity = (2 * len).next_power_of_two().max(16);
            let mask = capacity - 1;
            slots.clear();
            slots.resize(capacity, (0, u32::MAX));
            let mut merges = Vec::new();
            for (start, list) in &lists {
                for &(h, i) in &list[start[p]..start[p + 1]] {
                    let mut slot = (h as usize) & mask;
                    loop {
                        let (occupant_hash, occupant) = slots[slot];
                        if occupant == u32::MAX {
                            slots[slot] = (h, i);
                            break;
                        }
                        if occupant_hash == h
                            && key(&vertices[occupant as usize]) == key(&vertices[i as usize])
                        {
                            merges.push((i, occupant));
                            break;
                        }
                        slot = (slot + 1) & mask;
                    }
                }
            }
            merges
        })
        .collect();
    let mut canonical: Vec<u32> = (0..n as u32)
        .into_par_iter()
        .with_min_len(1 << 12)
        .collect();
    let mut merged = 0;
    for (i, first) in merges.into_iter().flatten() {
        canonical[i as usize] = first;
        merged += 1;
    }
    Weld { canonical, merged }
}

impl Weld {
    /// A face with each corner replaced by its [`canonical`](Weld::canonical) vertex.
    #[inline]
    #[must_use]
    pub fn face(&self, t: &[u32; 3]) -> [u32; 3] {
        t.map(|i| self.canonical[i as usize])
    }
}

/// `faces` over `vertices` with every corner replaced by the smallest-index vertex of
/// identical coordinates ([`weld_identical`]), and how many vertices were merged. Refuses
/// an index out of range.
pub fn weld_faces(
    vertices: &[[f64; 3]],
    faces: &[[u32; 3]],
) -> Result<(Vec<[u32; 3]>, usize), MeshError> {
    check_indices(faces, vertices.len())?;
    let weld = weld_identical(vertices);
    let welded = faces.iter().map(|t| weld.face(t)).collect();
    Ok((welded, weld.merged))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weld_over_many_partitions_matches_a_brute_force_map() {
        // 100k vertices drawn from 3000 distinct points (and signed zeros): 4 partitions.
        let points: Vec<[f64; 3]> = (0..3000)
            .map(|i| [f64::from(i % 17), f64::from(i / 17) * 0.5, 0.0])
            .collect();
        let v: Vec<[f64; 3]> = (0..100_000u32)
            .map(|i| {
                let mut p = points[((i as u64 * 2_654_435_761) % 3000) as usize];
                if i % 3 == 0 {
                    p[2] = -0.0;
                }
                p
            })
            .collect();
        let weld = weld_identical(&v);
        let mut first = std::collections::HashMap::new();
        for (i, p) in v.iter().enumerate() {
            let key = p.map(coordinate_key);
            let f = *first.entry(key).or_insert(i as u32);
            assert_eq!(weld.canonical[i], f, "vertex {i}");
        }
        assert_eq!(weld.merged, v.len() - first.len());
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
