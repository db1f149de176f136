//! Vertices grouped into clusters by equal packed code ([`super::packed`]): a hash
//! partition with small per-partition tables for `B <= 21`, a stable LSD radix sort above.

use std::mem::MaybeUninit;

use rayon::prelude::*;

use super::buffers::{CHUNK, DisjointWrites, MIN_LEN, assume_init, uninit};
use super::grid::{Grid, MAX_BITS};
use super::packed::{MAX_KEY_BITS, PackedCode};
use crate::error::MeshError;

/// Digit width of the LSD radix sort of codes, in bits.
const RADIX_BITS: u32 = 12;

/// Stable LSD radix sort of `keys` (`key_bits` significant bits); returns the sorted keys
/// and, for each, its index in the input. Equal keys keep ascending input indices.
/// O(n * key_bits / 12); passes in which every key has the same digit are skipped.
fn radix_sort<K: PackedCode>(keys: Vec<K>, key_bits: u32) -> (Vec<K>, Vec<u32>) {
    let n = keys.len();
    let passes = key_bits.div_ceil(RADIX_BITS).max(1);
    let width = key_bits.div_ceil(passes);
    let buckets = 1usize << width;
    let mask = (buckets - 1) as u32;
    let counts = keys
        .par_chunks(CHUNK)
        .map(|chunk| {
            let mut c = vec![0usize; passes as usize * buckets];
            for &k in chunk {
                for p in 0..passes {
                    c[p as usize * buckets + k.digit(p * width, mask)] += 1;
                }
            }
            c
        })
        .reduce(
            || vec![0usize; passes as usize * buckets],
            |mut a, b| {
                a.iter_mut().zip(&b).for_each(|(x, y)| *x += y);
                a
            },
        );
    let mut keys = keys;
    let mut index: Vec<u32> = (0..n as u32).collect();
    let mut keys_out = vec![K::default(); n];
    let mut index_out = vec![0u32; n];
    for p in 0..passes {
        let count = &counts[p as usize * buckets..(p as usize + 1) * buckets];
        if count.contains(&n) {
            continue;
        }
        let mut offset = Vec::with_capacity(buckets);
        let mut total = 0;
        for &c in count {
            offset.push(total);
            total += c;
        }
        for (&k, &i) in keys.iter().zip(&index) {
            let d = k.digit(p * width, mask);
            let o = offset[d];
            keys_out[o] = k;
            index_out[o] = i;
            offset[d] = o + 1;
        }
        std::mem::swap(&mut keys, &mut keys_out);
        std::mem::swap(&mut index, &mut index_out);
    }
    (keys, index)
}

/// Vertices grouped by equal code.
#[derive(Debug, Clone)]
pub struct Clusters {
    /// `id[i]`: vertex `i`'s cluster. Clusters are numbered in order of their smallest
    /// vertex index.
    pub id: Vec<u32>,
    /// `first[c]`: the smallest vertex index of cluster `c` (ascending in `c`).
    pub first: Vec<u32>,
    /// `code[c]`: the code shared by cluster `c`.
    pub code: Vec<[u32; 3]>,
}

impl Clusters {
    /// Number of clusters (distinct codes).
    #[inline]
    #[must_use]
    pub fn count(&self) -> usize {
        self.first.len()
    }
}

/// Groups packed codes: a radix sort puts equal keys in runs, in ascending vertex order;
/// a pass in vertex order then numbers each run when its first vertex is reached.
fn group_keys<K: PackedCode>(keys: Vec<K>, bits: u32) -> Clusters {
    let n = keys.len();
    let (sorted, index) = radix_sort(keys, 3 * bits);
    let mut run_of = vec![0u32; n];
    let mut run_first: Vec<u32> = Vec::new();
    let mut run_key: Vec<K> = Vec::new();
    for (j, (&k, &i)) in sorted.iter().zip(&index).enumerate() {
        if j == 0 || k != sorted[j - 1] {
            run_first.push(i);
            run_key.push(k);
        }
        run_of[i as usize] = (run_first.len() - 1) as u32;
    }
    drop((sorted, index));
    // A run's first vertex precedes its others, so its id exists when they are reached.
    let mut run_id = vec![0u32; run_first.len()];
    let mut first = Vec::with_capacity(run_first.len());
    let mut code = Vec::with_capacity(run_first.len());
    let id: Vec<u32> = run_of
        .iter()
        .enumerate()
        .map(|(i, &r)| {
            let r = r as usize;
            if run_first[r] as usize == i {
                run_id[r] = first.len() as u32;
                first.push(i as u32);
                code.push(run_key[r].unpack(bits));
            }
            run_id[r]
        })
        .collect();
    Clusters { id, first, code }
}

/// Fibonacci hashing: the top bits of `key * 2^64 / golden ratio` spread nearby grid codes
/// over the whole range.
#[inline]
fn spread(key: u64) -> u64 {
    key.wrapping_mul(0x9E37_79B9_7F4A_7C15)
}

/// Keys per partition that [`group_keys_partitioned`] aims at: its hash table (two to four
/// times as many slots of 8 or 16 bytes, 0.5 to 2 MiB) then stays in a core's L2 cache,
/// and the scatter writes few enough partitions at once (32 for a million vertices): with
/// 8192 keys per partition (128 partitions) the scatter took 2.5x longer at 655k
/// vertices, likely from TLB misses.
const PARTITION_TARGET: usize = 32768;

/// A vertex and its packed key, as [`group_keys_partitioned`] moves and stores them: one
/// `u64` `key << shift | vertex` when the key and the vertex index fit in 63 bits (the
/// usual case: `3 B + log2 n <= 63`), else a pair.
trait KeyedVertex: Copy + PartialEq + Send + Sync {
    /// Marks an empty hash-table slot; equal to no entry.
    const EMPTY: Self;
    fn new(key: u64, vertex: u32, shift: u32) -> Self;
    fn key(self, shift: u32) -> u64;
    fn vertex(self, shift: u32) -> u32;
}

impl KeyedVertex for u64 {
    const EMPTY: Self = u64::MAX;
    #[inline]
    fn new(key: u64, vertex: u32, shift: u32) -> Self {
        (key << shift) | u64::from(vertex)
    }
    #[inline]
    fn key(self, shift: u32) -> u64 {
        self >> shift
    }
    #[inline]
    fn vertex(self, shift: u32) -> u32 {
        (self & ((1u64 << shift) - 1)) as u32
    }
}

impl KeyedVertex for (u64, u32) {
    const EMPTY: Self = (u64::MAX, u32::MAX);
    #[inline]
    fn new(key: u64, vertex: u32, _: u32) -> Self {
        (key, vertex)
    }
    #[inline]
    fn key(self, _: u32) -> u64 {
        self.0
    }
    #[inline]
    fn vertex(self, _: u32) -> u32 {
        self.1
    }
}

/// Groups packed keys (`3 B <= 63` bits) in cache-friendly parallel passes:
///
/// 1. a stable counting sort on the top bits of [`spread`] splits the vertices into
///    partitions of about [`PARTITION_TARGET`] keys, equal keys in the same partition in
///    ascending vertex order (chunks of the input scatter in parallel, each at offsets
///    fixed by the counts of the chunks before it);
/// 2. each partition, in parallel, finds with a small open-addressing table the first
///    vertex `rep[i] <= i` that has vertex `i`'s key;
/// 3. the vertices with `rep[i] == i` (the first of their cluster) are numbered in vertex
///    order by per-chunk counts, and every other vertex takes its first's number.
///
/// Clusters come numbered by their smallest vertex index; nothing depends on the thread
/// count. Vertices and keys travel as one `u64` when they fit (see [`KeyedVertex`]).
fn group_keys_partitioned(keys: &[u64], bits: u32) -> Clusters {
    let n = keys.len();
    debug_assert!(3 * bits <= 63 && n < u32::MAX as usize);
    let shift = usize::BITS - n.saturating_sub(1).leading_zeros();
    let rep = if 3 * bits + shift <= 63 {
        representatives::<u64>(keys, shift)
    } else {
        representatives::<(u64, u32)>(keys, shift)
    };
    number_clusters(rep, keys, bits)
}

/// Steps 1 and 2 of [`group_keys_partitioned`]: `rep[i]`, the smallest vertex with vertex
/// `i`'s key.
fn representatives<E: KeyedVertex>(keys: &[u64], shift: u32) -> Vec<u32> {
    let n = keys.len();
    let part_bits = (n / PARTITION_TARGET)
        .max(1)
        .next_power_of_two()
        .trailing_zeros();
    let parts = 1usize << part_bits;
    let part_of = |k: u64| {
        if part_bits == 0 {
            0
        } else {
            (spread(k) >> (64 - part_bits)) as usize
        }
    };
    let chunk_counts: Vec<Vec<u32>> = keys
        .par_chunks(CHUNK)
        .map(|chunk| {
            let mut count = vec![0u32; parts];
            for &k in chunk {
                count[part_of(k)] += 1;
            }
            count
        })
        .collect();
    let mut start = vec![0usize; parts + 1];
    for count in &chunk_counts {
        for (p, &c) in count.iter().enumerate() {
            start[p + 1] += c as usize;
        }
    }
    for p in 0..parts {
        start[p + 1] += start[p];
    }
    let mut chunk_offsets = Vec::with_capacity(chunk_counts.len());
    let mut cursor = start[..parts].to_vec();
    for count in &chunk_counts {
        chunk_offsets.push(cursor.clone());
        for (c, &k) in cursor.iter_mut().zip(count) {
            *c += k as usize;
        }
    }
    let mut sorted = uninit::<E>(n);
    let out = DisjointWrites::new(&mut sorted);
    keys.par_chunks(CHUNK)
        .zip(chunk_offsets)
        .enumerate()
        .for_each(|(chunk_no, (chunk, mut offset))| {
            for (j, &k) in chunk.iter().enumerate() {
                let p = part_of(k);
                let vertex = (chunk_no * CHUNK + j) as u32;
                // SAFETY: chunk `c` writes partition `p` at
                // `[offset[c][p], offset[c][p] + count[c][p])`; these ranges are disjoint.
                unsafe { out.write(offset[p], MaybeUninit::new(E::new(k, vertex, shift))) };
                offset[p] += 1;
            }
        });
    // SAFETY: the chunks' ranges cover `0..n` (the counts sum to `n`).
    let sorted = unsafe { assume_init(sorted) };
    let mut rep = uninit::<u32>(n);
    let rep_out = DisjointWrites::new(&mut rep);
    // One table per worker, cleared for each partition: no allocation per partition.
    (0..parts)
        .into_par_iter()
        .for_each_init(Vec::new, |table, p| {
            let part = &sorted[start[p]..start[p + 1]];
            let slots = (2 * part.len()).next_power_of_two().max(8);
            let mask = slots - 1;
            let hash_shift = 64 - slots.trailing_zeros();
            // The first entry of each key; entries arrive in ascending vertex order.
            table.clear();
            table.resize(slots, E::EMPTY);
            for &e in part {
                let k = e.key(shift);
                let mut s = ((spread(k) << part_bits) >> hash_shift) as usize;
                let first = loop {
                    let slot = table[s];
                    if slot == E::EMPTY {
                        table[s] = e;
                        break e.vertex(shift);
                    }
                    if slot.key(shift) == k {
                        break slot.vertex(shift);
                    }
                    s = (s + 1) & mask;
                };
                // SAFETY: every vertex index appears in exactly one entry of `sorted`.
                unsafe { rep_out.write(e.vertex(shift) as usize, MaybeUninit::new(first)) };
            }
        });
    // SAFETY: as above, every index of `rep` was written once.
    unsafe { assume_init(rep) }
}

/// Step 3 of [`group_keys_partitioned`]: clusters numbered in order of their first vertex,
/// in three parallel passes over chunks (count the firsts; number them at their chunk's
/// offset; give every vertex its first's number, in place of `rep`).
fn number_clusters(mut rep: Vec<u32>, keys: &[u64], bits: u32) -> Clusters {
    let n = rep.len();
    let firsts: Vec<usize> = rep
        .par_chunks(CHUNK)
        .enumerate()
        .map(|(chunk_no, chunk)| {
            let base = chunk_no * CHUNK;
            chunk
                .iter()
                .enumerate()
                .filter(|&(j, &r)| r as usize == base + j)
                .count()
        })
        .collect();
    let count = firsts.iter().sum();
    // `id` is written at the first vertex of each cluster only, and read only there.
    let mut id = uninit::<u32>(n);
    let mut first = uninit::<u32>(count);
    let mut code = uninit::<[u32; 3]>(count);
    let mut parts = Vec::with_capacity(firsts.len());
    let (mut first_rest, mut code_rest) = (&mut first[..], &mut code[..]);
    let mut offset = 0;
    for &f in &firsts {
        let (fp, fr) = first_rest.split_at_mut(f);
        let (cp, cr) = code_rest.split_at_mut(f);
        parts.push((offset, fp, cp));
        (first_rest, code_rest) = (fr, cr);
        offset += f;
    }
    id.par_chunks_mut(CHUNK)
        .zip(rep.par_chunks(CHUNK))
        .zip(parts)
        .enumerate()
        .for_each(|(chunk_no, ((id, rep), (offset, first, code)))| {
            let base = chunk_no * CHUNK;
            let mut k = 0;
            for (j, &r) in rep.iter().enumerate() {
                let i = base + j;
                if r as usize == i {
                    id[j] = MaybeUninit::new((offset + k) as u32);
                    first[k] = MaybeUninit::new(i as u32);
                    code[k] = MaybeUninit::new(keys[i].unpack(bits));
                    k += 1;
                }
            }
        });
    // SAFETY: `rep[i]` is the first vertex of `i`'s cluster, whose `id` was written.
    rep.par_iter_mut()
        .with_min_len(MIN_LEN)
        .for_each(|r| *r = unsafe { id[*r as usize].assume_init() });
    Clusters {
        id: rep,
        // SAFETY: chunk `c` wrote its `firsts[c]` clusters; these parts cover `0..count`.
        first: unsafe { assume_init(first) },
        // SAFETY: as for `first`.
        code: unsafe { assume_init(code) },
    }
}

/// Quantizes `points` on `grid` and groups them by code; returns the clusters and the
/// largest distance from a point to its grid position (length). Refuses like
/// [`Grid::codes`].
///
/// For `B <= 21` the packed codes are grouped by `group_keys_partitioned` (expected
/// O(n)); above, by a stable LSD radix sort of 128-bit keys (O(n B)) and a pass in vertex
/// order. Clusters are numbered by their smallest vertex index, for any thread count.
pub fn group_points(points: &[[f64; 3]], grid: &Grid) -> Result<(Clusters, f64), MeshError> {
    if grid.bits <= MAX_KEY_BITS {
        let (keys, max_displacement) = grid.keys(points)?;
        Ok((group_keys_partitioned(&keys, grid.bits), max_displacement))
    } else {
        let (codes, max_displacement) = grid.codes(points)?;
        Ok((group_codes_sorted(&codes, grid.bits), max_displacement))
    }
}

/// Groups vertices by code (see [`group_points`]).
#[must_use]
pub fn group_codes(codes: &[[u32; 3]], bits: u32) -> Clusters {
    debug_assert!((1..=MAX_BITS).contains(&bits));
    if bits <= MAX_KEY_BITS {
        let keys: Vec<u64> = codes
            .par_iter()
            .with_min_len(MIN_LEN)
            .map(|&q| u64::pack(q, bits))
            .collect();
        group_keys_partitioned(&keys, bits)
    } else {
        group_codes_sorted(codes, bits)
    }
}

/// Groups vertices by code with the radix sort of [`group_keys`] (any `bits`; the path
/// for `B > 21`, whose keys need 128 bits).
fn group_codes_sorted(codes: &[[u32; 3]], bits: u32) -> Clusters {
    fn packed<K: PackedCode>(codes: &[[u32; 3]], bits: u32) -> Clusters {
        group_keys(
            codes
                .par_iter()
                .with_min_len(MIN_LEN)
                .map(|&q| K::pack(q, bits))
                .collect(),
            bits,
        )
    }
    match 3 * bits {
        0..=32 => packed::<u32>(codes, bits),
        33..=64 => packed::<u64>(codes, bits),
        _ => packed::<u128>(codes, bits),
    }
}

#[cfg(test)]
mod tests {
    use super::super::Mix;
    use super::super::grid::{GridKind, max_code};
    use super::*;

    #[test]
    fn grouping_matches_a_brute_force_partition() {
        let mut rng = Mix(7);
        // Key widths u32 (3B <= 31), u64 (<= 63) and u128; shifted codes share their low
        // bits, so their keys differ only in high bits.
        let cases = [
            (0usize, 5u32, 0u32),
            (1, 1, 0),
            (1000, 3, 0),
            (3000, 10, 4),
            (5000, 11, 0),
        ];
        let more = [
            (4000, 12, 6),
            (3000, 21, 15),
            (3000, 22, 16),
            (2000, 32, 26),
            (2000, 32, 0),
        ];
        for &(n, bits, shift) in cases.iter().chain(&more) {
            let codes: Vec<[u32; 3]> = (0..n)
                .map(|_| {
                    [0, 1, 2].map(|_| (((rng.next() as u32) & 0x3f) << shift) & max_code(bits))
                })
                .collect();
            // Step 1: the points are their own codes.
            let top = f64::from(max_code(bits));
            let grid = Grid::new(bits, GridKind::Cube, [0.0; 3], [top; 3]).unwrap();
            let points: Vec<[f64; 3]> = codes.iter().map(|q| q.map(f64::from)).collect();
            let (clusters, max_displacement) = group_points(&points, &grid).unwrap();
            assert_eq!(max_displacement, 0.0, "points on the grid do not move");
            let mut firsts: Vec<u32> = Vec::new();
            for i in 0..n {
                let first = (0..=i).find(|&k| codes[k] == codes[i]).unwrap() as u32;
                if first as usize == i {
                    firsts.push(first);
                }
                let c = clusters.id[i] as usize;
                assert_eq!(clusters.first[c], first, "n={n} bits={bits} i={i}");
                assert_eq!(clusters.code[c], codes[i]);
            }
            assert_eq!(
                clusters.first, firsts,
                "clusters must be numbered by first vertex"
            );
            let sorted = group_codes_sorted(&codes, bits);
            assert_eq!(
                (&sorted.id, &sorted.first, &sorted.code),
                (&clusters.id, &clusters.first, &clusters.code),
                "partitioned and radix grouping must agree (bits={bits})"
            );
        }
    }

    #[test]
    fn partitioned_grouping_matches_the_radix_sort_on_many_chunks_and_partitions() {
        let mut rng = Mix(11);
        // 300k vertices: 5 input chunks, 16 partitions; few and many repeats; entries
        // packed in a u64 (B = 8, 14: 3 B + 19 <= 63) and as pairs (B = 16, 21).
        for (bits, range) in [(8u32, 0x3fu64), (14, 0x3fff), (16, 0xffff), (21, 0x1f_ffff)] {
            let codes: Vec<[u32; 3]> = (0..300_000)
                .map(|_| [0, 1, 2].map(|_| ((rng.next() & range) as u32) & max_code(bits)))
                .collect();
            let fast = group_codes(&codes, bits);
            let sorted = group_codes_sorted(&codes, bits);
            assert!(fast.count() > 1 && fast.count() <= codes.len());
            assert_eq!(fast.id, sorted.id, "bits={bits}");
            assert_eq!(fast.first, sorted.first, "bits={bits}");
            assert_eq!(fast.code, sorted.code, "bits={bits}");
        }
    }
}
