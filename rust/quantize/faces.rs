//! The face pass of vertex clustering: corners remapped to clusters, collapsed faces
//! dropped (and repeated ones, on request), the kept faces compacted in input order.

use std::mem::MaybeUninit;
use std::sync::atomic::{AtomicBool, Ordering};

use rayon::prelude::*;

use super::buffers::{MIN_LEN, assume_init, gather_chunks, uninit};
use super::grid::{Grid, distance};
use super::keys::{Clusters, group_points};
use crate::error::{MeshError, VertexIndex, check_indices};

/// Faces per parallel work unit in the face pass of [`cluster`].
const FACE_CHUNK: usize = 1 << 14;

/// Marks a dropped face in the first corner of its remapped triple (vertex counts are
/// below `u32::MAX`, so no vertex has this index).
const DROPPED: u32 = u32::MAX;

/// Which faces count as repeats of an earlier face in [`cluster`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Duplicates {
    /// Keep every non-degenerate face.
    Keep,
    /// Drop a face whose corners are an earlier kept face's corners in the same cyclic
    /// order (`(a, b, c)`, `(b, c, a)`, `(c, a, b)`); the opposite winding is kept.
    Oriented,
    /// Drop a face whose corner set equals an earlier kept face's, whatever the order.
    Any,
}

/// The corners of a face in the canonical order of `mode`: rotated so that the smallest
/// comes first (`Oriented`) or sorted (`Any`).
#[inline]
#[must_use]
fn face_key(f: [u32; 3], mode: Duplicates) -> [u32; 3] {
    match mode {
        Duplicates::Any => {
            let mut s = f;
            s.sort_unstable();
            s
        }
        _ => {
            let m = if f[0] <= f[1] && f[0] <= f[2] {
                0
            } else if f[1] <= f[2] {
                1
            } else {
                2
            };
            [f[m], f[(m + 1) % 3], f[(m + 2) % 3]]
        }
    }
}

/// True when a triple repeats a corner.
#[inline]
#[must_use]
fn repeats_corner(t: &[u32; 3]) -> bool {
    (t[0] == t[1]) | (t[1] == t[2]) | (t[2] == t[0])
}

/// A clustered mesh and what clustering removed.
#[derive(Debug, Clone)]
pub struct Clustering {
    /// Dequantised grid positions of the kept clusters (length).
    pub vertices: Vec<[f64; 3]>,
    /// Corner codes of `vertices`.
    pub codes: Vec<[u32; 3]>,
    /// Kept faces, in input order, indexing `vertices`.
    pub faces: Vec<[u32; 3]>,
    /// For each kept face, its index among the input faces (ascending).
    pub face_index: Vec<u32>,
    /// For each input vertex, its output vertex, or -1 when its cluster was dropped.
    pub vertex_map: Vec<i64>,
    /// Input vertices that share another vertex's code: `n - clusters`.
    pub merged_vertices: usize,
    /// Clusters that no kept face uses: `clusters - vertices.len()`.
    pub unreferenced_vertices: usize,
    /// Faces with two equal corners after merging (including faces that repeated an
    /// index in the input).
    pub degenerate_faces: usize,
    /// Faces dropped as repeats of an earlier kept face (0 under [`Duplicates::Keep`]).
    pub duplicate_faces: usize,
    /// Largest distance from a kept input vertex (`vertex_map >= 0`) to its output
    /// vertex (length).
    pub max_displacement: f64,
}

/// The faces not marked DROPPED and their indices, in order: per-chunk counts give each
/// chunk its slice of the output, filled in parallel.
fn compact(mapped: &[[u32; 3]], kept: usize) -> (Vec<[u32; 3]>, Vec<u32>) {
    let counts: Vec<usize> = mapped
        .par_chunks(FACE_CHUNK)
        .map(|c| c.iter().filter(|t| t[0] != DROPPED).count())
        .collect();
    debug_assert_eq!(counts.iter().sum::<usize>(), kept);
    let mut out = vec![[0u32; 3]; kept];
    let mut index = vec![0u32; kept];
    let mut parts = Vec::with_capacity(counts.len());
    let (mut out_rest, mut index_rest) = (&mut out[..], &mut index[..]);
    for &c in &counts {
        let (o, o_rest) = out_rest.split_at_mut(c);
        let (i, i_rest) = index_rest.split_at_mut(c);
        parts.push((o, i));
        (out_rest, index_rest) = (o_rest, i_rest);
    }
    parts
        .into_par_iter()
        .zip(mapped.par_chunks(FACE_CHUNK))
        .enumerate()
        .for_each(|(chunk_no, ((o, i), chunk))| {
            // Write every face at the cursor and advance it only past kept ones: no
            // unpredictable branch when about half the faces collapse.
            let base = chunk_no * FACE_CHUNK;
            let mut k = 0;
            for (j, t) in chunk.iter().enumerate() {
                if k < o.len() {
                    o[k] = *t;
                    i[k] = (base + j) as u32;
                }
                k += usize::from(t[0] != DROPPED);
            }
        });
    (out, index)
}

/// Rossignac-Borrel vertex clustering on `grid`; see the module docs. Faces come as
/// `u32` or `i64` indices ([`VertexIndex`]).
///
/// Refuses an empty mesh, NaN/infinite coordinates, negative or out-of-range indices and
/// vertices outside the grid's box.
pub fn cluster<I: VertexIndex>(
    vertices: &[[f64; 3]],
    faces: &[[I; 3]],
    grid: &Grid,
    duplicates: Duplicates,
) -> Result<Clustering, MeshError> {
    let (n, m) = (vertices.len(), faces.len());
    if n == 0 || m == 0 {
        return Err(MeshError::Empty(format!(
            "mesh is empty ({n} vertices, {m} faces)"
        )));
    }
    if n >= DROPPED as usize || m > u32::MAX as usize {
        return Err(MeshError::Shape(format!(
            "{n} vertices and {m} faces exceed the supported maximum of 2^32 - 2"
        )));
    }
    let (clusters, max_displacement_all) = group_points(vertices, grid)?;
    let count = clusters.count();
    let used: Vec<AtomicBool> = (0..count).map(|_| AtomicBool::new(false)).collect();
    let (mut out_faces, mut face_index) = remap_faces(faces, &clusters.id, &used, n)?;
    let degenerate_faces = m - out_faces.len();
    let duplicate_faces = drop_duplicates(&mut out_faces, &mut face_index, duplicates);
    let unreferenced_vertices = used
        .par_iter()
        .with_min_len(MIN_LEN)
        .filter(|u| !u.load(Ordering::Relaxed))
        .count();
    let kept = if unreferenced_vertices == 0 {
        all_clusters(grid, clusters, max_displacement_all)
    } else {
        used_clusters(vertices, grid, clusters, &used, &mut out_faces)
    };
    Ok(Clustering {
        merged_vertices: n - count,
        unreferenced_vertices,
        degenerate_faces,
        duplicate_faces,
        max_displacement: kept.max_displacement,
        vertices: kept.vertices,
        codes: kept.codes,
        faces: out_faces,
        face_index,
        vertex_map: kept.vertex_map,
    })
}

/// The face pass of [`cluster`]: corners to cluster ids `id` (checking the indices against
/// `n` vertices), degenerate faces (two equal corners) dropped, the kept faces in input
/// order with their input index; the clusters they use are marked in `used`.
///
/// One pass over the faces in parallel chunks: kept faces are packed at the front of their
/// chunk with their input index, then (while the chunk is in cache) their clusters marked
/// used. Every face is written at the chunk's cursor, which only a kept face advances: no
/// unpredictable branch when about half the faces collapse.
fn remap_faces<I: VertexIndex>(
    faces: &[[I; 3]],
    id: &[u32],
    used: &[AtomicBool],
    n: usize,
) -> Result<(Vec<[u32; 3]>, Vec<u32>), MeshError> {
    let m = faces.len();
    let mut packed = uninit::<[u32; 3]>(m);
    let mut packed_index = uninit::<u32>(m);
    let chunks: Vec<(usize, bool)> = packed
        .par_chunks_mut(FACE_CHUNK)
        .zip(packed_index.par_chunks_mut(FACE_CHUNK))
        .zip(faces.par_chunks(FACE_CHUNK))
        .enumerate()
        .map(|(chunk_no, ((out, out_index), chunk))| {
            let base = chunk_no * FACE_CHUNK;
            let (mut kept, mut bad) = (0, false);
            for (j, f) in chunk.iter().enumerate() {
                let (Some(&a), Some(&b), Some(&c)) = (
                    id.get(f[0].to_usize()),
                    id.get(f[1].to_usize()),
                    id.get(f[2].to_usize()),
                ) else {
                    bad = true;
                    continue;
                };
                out[kept] = MaybeUninit::new([a, b, c]);
                out_index[kept] = MaybeUninit::new((base + j) as u32);
                kept += usize::from(!repeats_corner(&[a, b, c]));
            }
            for t in &out[..kept] {
                // SAFETY: the first `kept` faces of the chunk were written above.
                for &k in unsafe { t.assume_init_ref() } {
                    used[k as usize].store(true, Ordering::Relaxed);
                }
            }
            (kept, bad)
        })
        .collect();
    if chunks.iter().any(|&(_, bad)| bad) {
        check_indices(faces, n)?;
    }
    let kept_per_chunk: Vec<usize> = chunks.iter().map(|&(kept, _)| kept).collect();
    // Each chunk wrote its first `kept` items (all of them when no face was dropped).
    Ok(if kept_per_chunk.iter().sum::<usize>() == m {
        // SAFETY: every chunk kept, so wrote, all its faces.
        unsafe { (assume_init(packed), assume_init(packed_index)) }
    } else {
        // SAFETY: chunk `c` wrote its first `kept_per_chunk[c]` items.
        unsafe {
            (
                gather_chunks(&packed, FACE_CHUNK, &kept_per_chunk),
                gather_chunks(&packed_index, FACE_CHUNK, &kept_per_chunk),
            )
        }
    })
}

/// Drops from `faces` (and their input indices `face_index`) every face repeating an
/// earlier one under `mode`; returns how many were dropped. A repeated face's clusters are
/// its kept original's, so the clusters marked used stay right.
fn drop_duplicates(
    faces: &mut Vec<[u32; 3]>,
    face_index: &mut Vec<u32>,
    mode: Duplicates,
) -> usize {
    if mode == Duplicates::Keep {
        return 0;
    }
    let mut keyed: Vec<([u32; 3], u32)> = faces
        .par_iter()
        .enumerate()
        .map(|(i, t)| (face_key(*t, mode), i as u32))
        .collect();
    // Positions are unique, so the order is total and the sort deterministic.
    keyed.par_sort_unstable();
    let mut duplicate_faces = 0;
    for w in keyed.windows(2) {
        if w[0].0 == w[1].0 {
            faces[w[1].1 as usize] = [DROPPED; 3];
            duplicate_faces += 1;
        }
    }
    if duplicate_faces > 0 {
        let (kept, position) = compact(faces, faces.len() - duplicate_faces);
        *face_index = position.iter().map(|&i| face_index[i as usize]).collect();
        *faces = kept;
    }
    duplicate_faces
}

/// The output vertices of [`cluster`]: per input vertex its output vertex (-1: dropped),
/// the kept clusters' codes and dequantised positions, and the largest displacement of a
/// kept input vertex (length).
struct KeptClusters {
    vertex_map: Vec<i64>,
    codes: Vec<[u32; 3]>,
    vertices: Vec<[f64; 3]>,
    max_displacement: f64,
}

/// The dequantised positions of `codes` on `grid`.
fn positions(grid: &Grid, codes: &[[u32; 3]]) -> Vec<[f64; 3]> {
    codes
        .par_iter()
        .with_min_len(MIN_LEN)
        .map(|q| grid.position(q))
        .collect()
}

/// Every cluster is kept, with its number: the code pass measured every vertex
/// (`max_displacement`).
fn all_clusters(grid: &Grid, clusters: Clusters, max_displacement: f64) -> KeptClusters {
    let vertex_map: Vec<i64> = clusters
        .id
        .par_iter()
        .with_min_len(MIN_LEN)
        .map(|&c| i64::from(c))
        .collect();
    let out_vertices = positions(grid, &clusters.code);
    KeptClusters {
        vertex_map,
        codes: clusters.code,
        vertices: out_vertices,
        max_displacement,
    }
}

/// Only the `used` clusters are kept, renumbered by prefix count (kept ones keep their
/// order); `faces` are renumbered alike.
fn used_clusters(
    vertices: &[[f64; 3]],
    grid: &Grid,
    clusters: Clusters,
    used: &[AtomicBool],
    faces: &mut [[u32; 3]],
) -> KeptClusters {
    let count = clusters.count();
    let mut new_id = vec![DROPPED; count];
    let mut kept: Vec<u32> = Vec::with_capacity(count);
    for (c, u) in used.iter().enumerate() {
        if u.load(Ordering::Relaxed) {
            new_id[c] = kept.len() as u32;
            kept.push(c as u32);
        }
    }
    faces.par_iter_mut().with_min_len(MIN_LEN).for_each(|t| {
        *t = [
            new_id[t[0] as usize],
            new_id[t[1] as usize],
            new_id[t[2] as usize],
        ];
    });
    let vertex_map: Vec<i64> = clusters
        .id
        .par_iter()
        .with_min_len(MIN_LEN)
        .map(|&c| match new_id[c as usize] {
            DROPPED => -1,
            k => i64::from(k),
        })
        .collect();
    let out_codes: Vec<[u32; 3]> = kept
        .par_iter()
        .with_min_len(MIN_LEN)
        .map(|&c| clusters.code[c as usize])
        .collect();
    let out_vertices = positions(grid, &out_codes);
    let max_displacement = vertices
        .par_iter()
        .with_min_len(MIN_LEN)
        .zip(&vertex_map)
        .map(|(p, &k)| {
            if k >= 0 {
                distance(p, &out_vertices[k as usize])
            } else {
                0.0
            }
        })
        .reduce(|| 0.0, f64::max);
    KeptClusters {
        vertex_map,
        codes: out_codes,
        vertices: out_vertices,
        max_displacement,
    }
}

#[cfg(test)]
mod tests {
    use super::super::Mix;
    use super::super::grid::GridKind;
    use super::*;

    #[test]
    fn non_finite_and_outside_points_are_named_not_swallowed() {
        let nan = [[0.0, 0.0, 0.0], [1.0, 2.0, 3.0], [f64::NAN, 0.0, 0.0]];
        let inf = [[0.0, 0.0, 0.0], [f64::NEG_INFINITY, 0.0, 0.0]];
        assert_eq!(
            Grid::bounding(&nan, 8, GridKind::Cube),
            Err(MeshError::NonFinite { vertex: 2 })
        );
        assert_eq!(
            Grid::bounding(&inf, 8, GridKind::Axes),
            Err(MeshError::NonFinite { vertex: 1 })
        );
        let g = Grid::new(8, GridKind::Cube, [0.0; 3], [1.0; 3]).unwrap();
        let faces = [[0u32, 1, 2]];
        assert_eq!(
            cluster(&nan, &faces, &g, Duplicates::Keep).unwrap_err(),
            MeshError::NonFinite { vertex: 2 }
        );
        let outside = [[0.0, 0.0, 0.0], [0.5, 0.5, 0.5], [0.5, 1.5, 0.5]];
        assert_eq!(
            cluster(&outside, &faces, &g, Duplicates::Keep).unwrap_err(),
            MeshError::OutsideBox { point: 2 }
        );
        assert!(matches!(
            cluster(&outside[..2], &faces, &g, Duplicates::Keep),
            Err(MeshError::IndexOutOfRange {
                face: 0,
                index: 2,
                vertex_count: 2
            })
        ));
        let signed = [[0i64, 1, 0], [1, -1, 0]];
        assert!(matches!(
            cluster(&outside[..2], &signed, &g, Duplicates::Keep),
            Err(MeshError::IndexOutOfRange {
                face: 1,
                index: -1,
                vertex_count: 2
            })
        ));
    }

    #[test]
    fn collapsing_a_thin_strip_drops_degenerate_and_duplicate_faces() {
        // Two triangles of a quad, plus the quad's mirror copy; at 1 bit the far corners
        // merge with the near ones in pairs.
        let v = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 0.25, 0.0],
            [0.0, 0.25, 0.0],
            [0.2, 0.0, 0.0],
        ];
        let f = [[0, 1, 2], [0, 2, 3], [0, 4, 1], [2, 1, 0], [1, 0, 2]];
        let g = Grid::new(4, GridKind::Cube, [0.0; 3], [1.0, 0.25, 0.0]).unwrap();
        // Step 1/15: codes x {0, 15, 15, 0, 3}, y {0, 0, 4, 4, 0}: nothing merges.
        let keep = cluster(&v, &f, &g, Duplicates::Keep).unwrap();
        assert_eq!(
            (
                keep.merged_vertices,
                keep.degenerate_faces,
                keep.duplicate_faces
            ),
            (0, 0, 0)
        );
        assert_eq!(keep.faces, f.to_vec());
        let oriented = cluster(&v, &f, &g, Duplicates::Oriented).unwrap();
        assert_eq!(oriented.face_index, vec![0, 1, 2, 3]);
        let any = cluster(&v, &f, &g, Duplicates::Any).unwrap();
        assert_eq!(any.face_index, vec![0, 1, 2]);
        assert_eq!(any.duplicate_faces, 2);

        // At 1 bit (step 1) vertices 3 and 4 merge into 0 and vertex 2 into 1 (y rounds to 0).
        let g1 = Grid::new(1, GridKind::Cube, [0.0; 3], [1.0, 0.25, 0.0]).unwrap();
        let c = cluster(&v, &f, &g1, Duplicates::Keep).unwrap();
        assert_eq!(c.merged_vertices, 3);
        assert_eq!(c.degenerate_faces, 5);
        assert!(c.faces.is_empty());
        assert_eq!(c.unreferenced_vertices, 2);
        assert_eq!(c.vertex_map, vec![-1; 5]);
    }

    #[test]
    fn output_vertices_follow_the_smallest_input_index_of_their_cluster() {
        let v = [
            [9.0, 0.0, 0.0],
            [0.0, 0.0, 0.0],
            [0.0, 9.0, 0.0],
            [0.1, 0.0, 0.0],
            [5.0, 5.0, 0.0],
        ];
        let f = [[3i64, 0, 2], [4, 2, 0]];
        let g = Grid::bounding(&v, 3, GridKind::Cube).unwrap();
        let c = cluster(&v, &f, &g, Duplicates::Keep).unwrap();
        // Clusters {0}, {1, 3}, {2}, {4}; order of smallest index: 0, 1, 2, 4.
        assert_eq!(c.vertex_map, vec![0, 1, 2, 1, 3]);
        assert_eq!(c.faces, vec![[1, 0, 2], [3, 2, 0]]);
        assert_eq!(c.vertices[1], [0.0; 3]);
        assert_eq!(c.merged_vertices, 1);
        assert_eq!(c.unreferenced_vertices, 0);
        assert!(c.max_displacement <= g.bound());
    }

    #[test]
    fn clustering_keeps_every_vertex_on_the_grid_within_the_bound() {
        let mut rng = Mix(11);
        let v: Vec<[f64; 3]> = (0..400)
            .map(|_| [rng.unit(), rng.unit() * 0.5, rng.unit() * 0.25])
            .collect();
        let f: Vec<[u32; 3]> = (0..700)
            .map(|_| [0, 1, 2].map(|_| (rng.next() % 400) as u32))
            .collect();
        for bits in [1, 2, 4, 8, 16, 32] {
            for kind in [GridKind::Cube, GridKind::Axes] {
                let g = Grid::bounding(&v, bits, kind).unwrap();
                let c = cluster(&v, &f, &g, Duplicates::Any).unwrap();
                assert_eq!(
                    c.vertices.len() + c.merged_vertices + c.unreferenced_vertices,
                    v.len()
                );
                assert_eq!(
                    c.faces.len() + c.degenerate_faces + c.duplicate_faces,
                    f.len()
                );
                assert!(c.max_displacement <= g.bound() * (1.0 + 1e-12) + 1e-15);
                for (i, m) in c.vertex_map.iter().enumerate() {
                    if *m >= 0 {
                        assert_eq!(c.codes[*m as usize], g.code(&v[i]));
                    }
                }
                let mut used = vec![false; c.vertices.len()];
                for face in &c.faces {
                    assert!(face[0] != face[1] && face[1] != face[2] && face[0] != face[2]);
                    face.iter().for_each(|&i| used[i as usize] = true);
                }
                assert!(used.iter().all(|&u| u), "unreferenced output vertex");
            }
        }
    }
}
