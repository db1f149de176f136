//! A bounding volume hierarchy over a mesh's triangles, and the nearest-triangle search.
//!
//! **Frame.** Coordinates are recentred on the centre `c` of the bounding box of the
//! referenced vertices (subtracted in f64), so that the f32 boxes keep their precision
//! far from the origin (a mesh at `x = 1e6` has f32 ulps of `0.06`; recentred, the ulps
//! scale with the mesh's size). Queries subtract `c`, answers add it back.
//!
//! **Boxes.** obvhs 0.4 stores f32 boxes. Each triangle's box is computed in f64 from
//! its recentred corners, widened by `pad = h · 2⁻⁴⁰` (`h` the largest half side of the
//! bounding box, length), converted to f32 and rounded *outward* (`f32::next_down` /
//! `next_up` after the conversion), so every box contains its triangle with a margin of at
//! least `pad`, far above the f64 rounding of the distances. Inner boxes are unions of
//! f32 boxes, so they are exact. A box's distance to the query is computed in f64 from the
//! f32 bounds (converted exactly), so pruning never discards a triangle closer than the
//! best found: the search returns the exact f64 minimum over all triangles.
//!
//! **Tree.** obvhs's PLOC builder makes a binary tree whose sibling nodes sit next to each
//! other. [`TriangleTree`] copies it into pairs of sibling boxes (64 bytes, one cache
//! line): visiting an inner node reads both children's boxes at once. Triangles are stored
//! prepared ([`PreparedTriangle`]) in leaf order, so a leaf's triangles are contiguous.
//!
//! **Equal boxes.** Triangles whose f32 boxes are bitwise equal are grouped before the
//! build ([`SharedBoxes`]: a radix sort of 32-bit box hashes, about 3 ms per 200k faces on
//! one thread, and nothing more unless two hashes are equal), and PLOC gets each box
//! once: given `n` equal boxes (a mesh collapsed to one point) it merged one pair per
//! pass, a chain `n` deep built in quadratic time (69k faces: 15 s). Inside a box,
//! triangles with bitwise-equal recentred corners (collapsed to the same point, or
//! repeated faces) form one leaf flagged [`IDENTICAL`], its slots in face order: their
//! distances are bitwise equal, so only the first (the smallest face) is tested. Several
//! such sets in one box (distinct triangles closer together than the f32 boxes resolve)
//! form a balanced subtree of them, in the order of their smallest faces; a query nearest
//! to them tests each set, as the boxes cannot tell them apart.
//!
//! **Search.** Nearest-first branch and bound with an explicit stack: at each inner node
//! both child boxes are measured; the nearer child is visited first and the farther one
//! pushed, each only if it may hold a better answer (see *Ties*). A
//! `hint` triangle (for instance the previous query's answer, when queries are spatially
//! coherent) sets the starting best, and the search starts in the subtree
//! [`RESTART_LEVELS`] levels above the hint's leaf (every pair knows its parent, every
//! triangle slot its leaf's pair), then climbs to the root, searching each ancestor's other
//! child that may hold a better answer: the start subtree and those children cover
//! the tree once, and near the hint the climb mostly measures one box per level. Without a
//! hint the search starts at the root. An empty tree answers `None`; a tree whose root is a
//! leaf tests its triangles directly. On the benchmark pair (1.31M faces against their
//! 482k-face clustered copy, `benches/bench_refs.py`), starting at the hint's subtree cut
//! the exact queries' time by 10 to 20% against descending from the root.
//!
//! **Ties.** The answer is the smallest `(d², face index)` pair, compared in that order:
//! among triangles at exactly the same f64 distance, the smallest face index, so the answer
//! does not depend on the tree's shape, the hint, or the thread count. Every child box
//! knows the smallest face index below it (`min_face`, read only on ties): a box is
//! searched when its `(d², smallest face)` is below the best pair, that is when it is
//! nearer than the best distance, or exactly at it and holds a smaller face index; of two
//! boxes at the best distance, the one holding the smaller face is searched first. Boxes
//! at exactly the best distance used to be searched whatever they held: on a collapsed
//! mesh (every vertex at one point), every box, so every query tested every triangle.
//!
//! **Early exit.** With `stop_below_d2 > 0`, the search returns as soon as it has found
//! a triangle with squared distance `< stop_below_d2`; the answer is then an upper bound
//! on the true distance, not the minimum. The max-only Hausdorff uses it: there, half the
//! queries end at the hint.

use std::time::Duration;

use glam::{DVec3, Vec3A};
use obvhs::BvhBuildParams;
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use obvhs::bvh2::builder::build_bvh2;
use rayon::prelude::*;

use crate::closest::PreparedTriangle;
use crate::error::{MAX_EXTENT, MeshError, check_finite, check_indices};

/// Relative widening of every triangle box before the f32 conversion (`2⁻⁴⁰`).
const BOX_PAD: f64 = 1.0 / (1u64 << 40) as f64;

/// Levels above the hint's leaf where a hinted search starts before climbing to the root
/// (a subtree of up to `2^(RESTART_LEVELS + 1)` triangles; 2, 4, 6 and 9 measured alike).
const RESTART_LEVELS: usize = 6;

/// Flag of a leaf's triangle count: its triangles are bitwise identical (recentred corners
/// equal, slots sorted by face index), and only the first is tested. Counts stay below
/// 2³¹ (at most 2³¹ faces).
const IDENTICAL: u32 = 1 << 31;

/// Triangle slots of a leaf of `count` (flag included).
#[inline(always)]
fn slots_of(count: u32) -> u32 {
    count & !IDENTICAL
}

/// Queries per parallel work unit in [`TriangleTree::query`]; the hint carries over
/// inside a unit.
const QUERY_CHUNK: usize = 512;

/// obvhs build preset: PLOC with the shortest search radius, no reinsertion and no leaf
/// collapse (one triangle per leaf). On the benchmark meshes, longer searches,
/// reinsertion and SAH-collapsed leaves of up to 2, 4 or 8 triangles built 1.3 to 2 times
/// slower and answered closest-point queries no faster (`benches/bench_hausdorff.py`).
const BUILD_PARAMS: BvhBuildParams = BvhBuildParams {
    max_prims_per_leaf: 1,
    ..BvhBuildParams::fastest_build()
};

/// Two sibling boxes and what they hold: one cache line.
#[derive(Debug, Clone, Copy, Default)]
#[repr(C, align(64))]
struct Pair {
    min: [[f32; 3]; 2],
    max: [[f32; 3]; 2],
    /// Inner child: index of its own pair of children. Leaf: first triangle slot.
    link: [u32; 2],
    /// Triangles in a leaf child, with the [`IDENTICAL`] flag; 0 for an inner child.
    count: [u32; 2],
}

impl Pair {
    /// Squared distance (length²) from `p` to box `k`; 0 inside.
    #[inline(always)]
    fn distance_squared(&self, p: DVec3, k: usize) -> f64 {
        let lo = Vec3A::from_array(self.min[k]).as_dvec3();
        let hi = Vec3A::from_array(self.max[k]).as_dvec3();
        (lo - p).max(p - hi).max(DVec3::ZERO).length_squared()
    }

    /// Squared distances (length²) from `p` to both boxes; 0 inside.
    #[inline(always)]
    fn distances_squared(&self, p: DVec3) -> [f64; 2] {
        [self.distance_squared(p, 0), self.distance_squared(p, 1)]
    }
}

/// A node waiting on the search stack.
#[derive(Debug, Clone, Copy)]
struct Pending {
    link: u32,
    count: u32,
    d2: f64,
    /// `2 × pair + child`: where its smallest face index is kept (`min_face`).
    owner: u32,
}

/// Reusable scratch space of one search thread.
#[derive(Debug, Default)]
pub struct SearchStack(Vec<Pending>);

/// The nearest triangle to a query.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Nearest {
    /// Storage slot of the triangle (use as a hint for the next query).
    pub slot: u32,
    /// Face index in the caller's face array.
    pub face: u32,
    /// Squared distance (length²).
    pub d2: f64,
    /// Closest point, in the tree's recentred frame (length).
    pub point: DVec3,
}

/// Per query point: distance (length), closest point (caller's frame), face index.
pub type QueryResult = (Vec<f64>, Vec<[f64; 3]>, Vec<u32>);

/// Bounding volume hierarchy over one mesh's triangles. See the module docs.
#[derive(Debug, Clone)]
pub struct TriangleTree {
    centre: DVec3,
    /// Largest half side of the bounding box (length).
    half_extent: f64,
    pairs: Vec<Pair>,
    /// Root: a leaf (`root_count > 0`: triangles `root_link ..`) or the pair `root_link`.
    root_link: u32,
    root_count: u32,
    root_min: [f32; 3],
    root_max: [f32; 3],
    triangles: Vec<PreparedTriangle>,
    faces: Vec<u32>,
    /// Per pair, the pair holding it as a child (`u32::MAX` for the root pair).
    parent: Vec<u32>,
    /// Per triangle slot, the pair holding its leaf (`u32::MAX` when the root is a leaf).
    leaf_pair: Vec<u32>,
    /// Per child box (`2 × pair + child`), the smallest face index below it.
    min_face: Vec<u32>,
    depth: usize,
    vertex_count: usize,
    /// [`crate::reduce::box_overlap`] of the mesh, from the triangles' f32 boxes.
    box_overlap: f64,
}

/// Per-triangle f32 box of recentred f64 corners, widened by `pad` and rounded outward.
#[inline]
fn outward_box(corners: [DVec3; 3], pad: f64) -> Aabb {
    let lo = corners[0].min(corners[1]).min(corners[2]) - DVec3::splat(pad);
    let hi = corners[0].max(corners[1]).max(corners[2]) + DVec3::splat(pad);
    let down = |x: f64| (x as f32).next_down();
    let up = |x: f64| (x as f32).next_up();
    Aabb::new(
        Vec3A::new(down(lo.x), down(lo.y), down(lo.z)),
        Vec3A::new(up(hi.x), up(hi.y), up(hi.z)),
    )
}

/// [`crate::reduce::box_overlap`] from the triangles' boxes: the sum of their volumes, each
/// widened by [`crate::reduce::overlap_pad`] of `extent` (the referenced vertices' box),
/// over the volume of that box widened alike (dimensionless; summed in fixed chunks, so
/// the same for any thread count).
fn overlap_of_boxes(boxes: &[Aabb], extent: DVec3) -> f64 {
    let Some(pad) = crate::reduce::overlap_pad(extent) else {
        return 0.0;
    };
    if boxes.is_empty() {
        return 0.0;
    }
    let volume = |b: &Aabb| {
        let side = b.max.as_dvec3() - b.min.as_dvec3() + pad;
        side.x * side.y * side.z
    };
    let parts: Vec<f64> = boxes
        .par_chunks(crate::reduce::SUM_CHUNK)
        .map(|chunk| chunk.iter().map(volume).sum::<f64>())
        .collect();
    let whole = extent + pad;
    parts.iter().sum::<f64>() / (whole.x * whole.y * whole.z)
}

/// Interleaves the low 21 bits of `x`, `y`, `z` into a 63-bit Morton code.
#[inline]
#[must_use]
fn morton3(x: u64, y: u64, z: u64) -> u64 {
    fn spread(v: u64) -> u64 {
        let mut v = v & 0x1f_ffff;
        v = (v | v << 32) & 0x001f_0000_0000_ffff;
        v = (v | v << 16) & 0x001f_0000_ff00_00ff;
        v = (v | v << 8) & 0x100f_00f0_0f00_f00f;
        v = (v | v << 4) & 0x10c3_0c30_c30c_30c3;
        v = (v | v << 2) & 0x1249_2492_4924_9249;
        v
    }
    spread(x) | spread(y) << 1 | spread(z) << 2
}

/// A processing order for queries: the indices of `points` sorted along a Morton curve
/// (2²¹ cells per side of their bounding cube; ties by index).
///
/// Consecutive queries in this order are close, so each search can start from the
/// previous answer (a good `hint`) and finds the tree's nodes in cache. It changes speed
/// only: every answer is exact and independent of the order.
#[must_use]
pub fn coherent_order(points: &[DVec3]) -> Vec<u32> {
    let (lo, hi) = points
        .par_iter()
        .fold(
            || (DVec3::INFINITY, DVec3::NEG_INFINITY),
            |(lo, hi), &p| (lo.min(p), hi.max(p)),
        )
        .reduce(
            || (DVec3::INFINITY, DVec3::NEG_INFINITY),
            |(a, b), (c, d)| (a.min(c), b.max(d)),
        );
    let cells = ((1u64 << 21) - 1) as f64;
    let side = (hi - lo).max_element();
    let scale = if side > 0.0 { cells / side } else { 0.0 };
    let mut keyed: Vec<(u64, u32)> = points
        .par_iter()
        .enumerate()
        .map(|(i, &p)| {
            let g = ((p - lo) * scale).clamp(DVec3::ZERO, DVec3::splat(cells));
            (morton3(g.x as u64, g.y as u64, g.z as u64), i as u32)
        })
        .collect();
    keyed.par_sort_unstable();
    keyed.into_par_iter().map(|(_, i)| i).collect()
}

/// The bit patterns of a triangle's three recentred corners.
type CornerBits = [[u64; 3]; 3];

/// Triangles whose f32 boxes are bitwise equal, found before the PLOC build: PLOC gets
/// each box once. Given `n` equal boxes (a mesh collapsed to a point) it merged one pair
/// per pass, a chain `n` deep built in quadratic time (69k faces: 15 s).
#[derive(Debug)]
struct SharedBoxes {
    /// The distinct boxes, in the order of their smallest face: obvhs's primitives.
    boxes: Vec<Aabb>,
    /// Per distinct box, its face when it holds one, else [`SHARED`] `| g`, `g` its entry
    /// in `groups`.
    entry: Vec<u32>,
    /// Per box of several faces, its range of `item_start` (one entry more).
    groups: Vec<u32>,
    /// Per item (a set of bitwise-identical triangles), its range of `faces` (one more).
    item_start: Vec<u32>,
    /// Faces, in face order inside an item; a box's items in the order of their first face.
    faces: Vec<u32>,
}

/// Flag of a [`SharedBoxes`] entry: a box of several faces.
const SHARED: u32 = 1 << 31;

impl SharedBoxes {
    /// Groups the faces by box; inside a box, by `key` (bitwise corners: identical
    /// triangles). None when every box is distinct (the usual case).
    fn find(boxes: &[Aabb], key: impl Fn(u32) -> CornerBits) -> Option<SharedBoxes> {
        let bits = |b: &Aabb| {
            let (lo, hi) = (b.min.to_array(), b.max.to_array());
            [lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]].map(f32::to_bits)
        };
        // 32-bit hashes of the boxes above the face indices, sorted by hash (stable: equal
        // hashes in face order). Equal boxes have equal hashes; equal hashes are checked.
        let mut keyed: Vec<u64> = boxes
            .par_iter()
            .enumerate()
            .map(|(i, b)| {
                let h = bits(b).iter().fold(0u64, |h, &x| {
                    (h ^ u64::from(x)).wrapping_mul(0x9E37_79B9_7F4A_7C15)
                });
                (h & !0xffff_ffff) | i as u64
            })
            .collect();
        radix_sort_high32(&mut keyed);
        let hash = |k: &u64| k >> 32;
        if !keyed.par_windows(2).any(|w| hash(&w[0]) == hash(&w[1])) {
            return None;
        }
        // The faces of each box held by several, in face order.
        let mut several: Vec<Vec<u32>> = Vec::new();
        let mut run = Vec::new();
        for same_hash in keyed
            .chunk_by(|a, b| hash(a) == hash(b))
            .filter(|r| r.len() > 1)
        {
            run.clear();
            run.extend(same_hash.iter().map(|&k| {
                let face = k as u32;
                (bits(&boxes[face as usize]), face)
            }));
            run.sort_unstable();
            for same_box in run.chunk_by(|a, b| a.0 == b.0).filter(|r| r.len() > 1) {
                several.push(same_box.iter().map(|&(_, face)| face).collect());
            }
        }
        if several.is_empty() {
            return None;
        }
        several.sort_unstable_by_key(|faces| faces[0]);
        // A face stands for its box when no smaller face shares it.
        let mut hidden = vec![false; boxes.len()];
        for faces in &several {
            for &face in &faces[1..] {
                hidden[face as usize] = true;
            }
        }
        let distinct: Vec<u32> = (0..boxes.len() as u32)
            .into_par_iter()
            .filter(|&face| !hidden[face as usize])
            .collect();
        // Where each box of several faces stands among the distinct ones.
        let at: Vec<usize> = several
            .iter()
            .map(|faces| distinct.binary_search(&faces[0]).expect("a distinct face"))
            .collect();
        let mut shared = SharedBoxes {
            boxes: distinct.par_iter().map(|&f| boxes[f as usize]).collect(),
            entry: distinct,
            groups: Vec::with_capacity(several.len() + 1),
            item_start: Vec::new(),
            faces: Vec::new(),
        };
        // Inside each box, identical triangles together (each item in face order), the
        // items in the order of their first face.
        let mut by_key = Vec::new();
        for (g, faces) in several.iter().enumerate() {
            shared.entry[at[g]] = SHARED | g as u32;
            shared.groups.push(shared.item_start.len() as u32);
            by_key.clear();
            by_key.extend(faces.iter().map(|&f| (key(f), f)));
            by_key.sort_unstable();
            let mut items: Vec<&[(CornerBits, u32)]> = by_key.chunk_by(|a, b| a.0 == b.0).collect();
            items.sort_unstable_by_key(|item| item[0].1);
            for item in items {
                shared.item_start.push(shared.faces.len() as u32);
                shared.faces.extend(item.iter().map(|&(_, f)| f));
            }
        }
        shared.groups.push(shared.item_start.len() as u32);
        shared.item_start.push(shared.faces.len() as u32);
        Some(shared)
    }

    /// The faces of item `item`.
    fn item(&self, item: u32) -> &[u32] {
        let (a, b) = (
            self.item_start[item as usize],
            self.item_start[item as usize + 1],
        );
        &self.faces[a as usize..b as usize]
    }
}

/// `keys` sorted by their upper 32 bits, stably (LSD radix sort, four 8-bit passes).
fn radix_sort_high32(keys: &mut Vec<u64>) {
    let mut other = vec![0u64; keys.len()];
    for pass in 0..4 {
        let shift = 32 + 8 * pass;
        let digit = |k: u64| ((k >> shift) & 0xff) as usize;
        let mut start = [0usize; 257];
        for &k in keys.iter() {
            start[digit(k) + 1] += 1;
        }
        for i in 0..256 {
            start[i + 1] += start[i];
        }
        for &k in keys.iter() {
            let at = &mut start[digit(k)];
            other[*at] = k;
            *at += 1;
        }
        std::mem::swap(keys, &mut other);
    }
}

impl TriangleTree {
    /// Builds the tree over `faces` (indices into `vertices`, length unit of the caller).
    ///
    /// An empty face list gives an empty tree (every query answers `None`).
    pub fn build(vertices: &[[f64; 3]], faces: &[[u32; 3]]) -> Result<Self, MeshError> {
        Self::build_with(vertices, faces, true)
    }

    /// [`build`](Self::build); `merge_identical: false` keeps identical triangles in
    /// leaves of their own (tests of the tie rule alone).
    fn build_with(
        vertices: &[[f64; 3]],
        faces: &[[u32; 3]],
        merge_identical: bool,
    ) -> Result<Self, MeshError> {
        check_finite(vertices)?;
        check_indices(faces, vertices.len())?;
        if faces.len() >= u32::MAX as usize / 2 {
            return Err(MeshError::Parameter(format!(
                "{} faces exceed 2**31",
                faces.len()
            )));
        }
        let (lo, hi) = crate::reduce::referenced_bbox(vertices, faces);
        let centre = crate::reduce::bbox_centre(lo, hi);
        let (lo, hi) = (DVec3::from_array(lo), DVec3::from_array(hi));
        let (centre, half_extent) = if faces.is_empty() {
            (DVec3::ZERO, 0.0)
        } else {
            (centre, ((hi - lo) * 0.5).max_element())
        };
        if half_extent.is_nan() || half_extent > MAX_EXTENT {
            return Err(MeshError::Parameter(format!(
                "the mesh spans {:.3e} (length): more than the supported {MAX_EXTENT:.0e}",
                2.0 * half_extent
            )));
        }
        let local = |i: u32| DVec3::from_array(vertices[i as usize]) - centre;
        let pad = half_extent.max(f64::MIN_POSITIVE) * BOX_PAD;
        let boxes: Vec<Aabb> = faces
            .par_iter()
            .map(|f| outward_box([local(f[0]), local(f[1]), local(f[2])], pad))
            .collect();
        // Bitwise-equal recentred corners: equal faces, or faces collapsed to one point.
        let corners = |face: u32| {
            let f = faces[face as usize];
            [0, 1, 2].map(|k| local(f[k]).to_array().map(f64::to_bits))
        };
        let shared = SharedBoxes::find(&boxes, |face| {
            if merge_identical {
                corners(face)
            } else {
                [[u64::from(face); 3]; 3]
            }
        });
        let bvh = match &shared {
            Some(shared) => build_bvh2(&shared.boxes, BUILD_PARAMS, &mut Duration::default()),
            None => build_bvh2(&boxes, BUILD_PARAMS, &mut Duration::default()),
        };

        let mut tree = TriangleTree {
            centre,
            half_extent,
            pairs: Vec::new(),
            root_link: 0,
            root_count: 0,
            root_min: [0.0; 3],
            root_max: [0.0; 3],
            triangles: Vec::new(),
            faces: Vec::with_capacity(faces.len()),
            parent: Vec::new(),
            leaf_pair: Vec::with_capacity(faces.len()),
            min_face: Vec::new(),
            depth: 0,
            vertex_count: vertices.len(),
            box_overlap: overlap_of_boxes(&boxes, hi - lo),
        };
        if !bvh.nodes.is_empty() {
            tree.copy_from(&bvh, shared.as_ref());
            tree.triangles = tree
                .faces
                .par_iter()
                .with_min_len(1 << 12)
                .map(|&face| {
                    let f = faces[face as usize];
                    PreparedTriangle::new(local(f[0]), local(f[1]), local(f[2]))
                })
                .collect();
        }

        Ok(tree)
    }

    /// Copies obvhs's nodes into sibling pairs in depth-first order, and the face indices
    /// into leaf order (the triangles are then prepared in parallel, in that order); then
    /// each child box's smallest face index.
    fn copy_from(&mut self, bvh: &Bvh2, shared: Option<&SharedBoxes>) {
        let root = &bvh.nodes[0];
        self.root_min = root.aabb.min.to_array();
        self.root_max = root.aabb.max.to_array();
        if root.is_leaf() {
            (self.root_link, self.root_count) = self.copy_leaf(bvh, shared, 0, u32::MAX, 0);
            self.depth = self.depth.max(1);
        } else {
            // (obvhs index of the first child, our pair index, depth)
            self.pairs.reserve(bvh.nodes.len() / 2);
            self.parent.reserve(bvh.nodes.len() / 2);
            self.pairs.push(Pair::default());
            self.parent.push(u32::MAX);
            let mut todo = vec![(root.first_index, 0u32, 1usize)];
            while let Some((first, pair, depth)) = todo.pop() {
                self.depth = self.depth.max(depth + 1);
                let mut built = Pair::default();
                for k in 0..2 {
                    let index = first + k as u32;
                    let node = &bvh.nodes[index as usize];
                    built.min[k] = node.aabb.min.to_array();
                    built.max[k] = node.aabb.max.to_array();
                    if node.is_leaf() {
                        (built.link[k], built.count[k]) =
                            self.copy_leaf(bvh, shared, index, pair, depth);
                    } else {
                        let child = self.pairs.len() as u32;
                        self.pairs.push(Pair::default());
                        self.parent.push(pair);
                        built.link[k] = child;
                        todo.push((node.first_index, child, depth + 1));
                    }
                }
                self.pairs[pair as usize] = built;
            }
        }
        // Children pairs come after their parent: fill from the last pair up.
        self.min_face = vec![u32::MAX; 2 * self.pairs.len()];
        for index in (0..self.pairs.len()).rev() {
            let pair = self.pairs[index];
            for k in 0..2 {
                let (link, count) = (pair.link[k] as usize, pair.count[k]);
                self.min_face[2 * index + k] = if count == 1 || count & IDENTICAL != 0 {
                    // One triangle, or identical ones in face order.
                    self.faces[link]
                } else if count > 0 {
                    let faces = &self.faces[link..link + count as usize];
                    faces.iter().copied().min().unwrap_or(u32::MAX)
                } else {
                    debug_assert!(link > index);
                    self.min_face[2 * link].min(self.min_face[2 * link + 1])
                };
            }
        }
    }

    /// Copies obvhs leaf `index`, a child of our pair `pair` at `depth` (`u32::MAX`, 0:
    /// the root): returns its `(link, count)` as a child of `pair`.
    ///
    /// With `shared` boxes, obvhs's primitives are the distinct boxes, each holding items
    /// of identical triangles. One item becomes one leaf, its faces in order, flagged
    /// [`IDENTICAL`] when it holds more than one; several items (distinct triangles
    /// closer together than the f32 boxes resolve) become a balanced subtree of such
    /// leaves under the same box, the items of smaller faces on the first side.
    fn copy_leaf(
        &mut self,
        bvh: &Bvh2,
        shared: Option<&SharedBoxes>,
        index: u32,
        pair: u32,
        depth: usize,
    ) -> (u32, u32) {
        let node = &bvh.nodes[index as usize];
        let first = node.first_index as usize;
        let prims = &bvh.primitive_indices[first..first + node.prim_count as usize];
        let slot = self.faces.len() as u32;
        match (shared, prims) {
            (None, _) => self.faces.extend_from_slice(prims),
            (Some(shared), &[b]) => {
                let entry = shared.entry[b as usize];
                if entry & SHARED == 0 {
                    self.faces.push(entry);
                } else {
                    let g = (entry & !SHARED) as usize;
                    let items = shared.groups[g]..shared.groups[g + 1];
                    let aabb = (node.aabb.min.to_array(), node.aabb.max.to_array());
                    return self.copy_items(shared, aabb, items, pair, depth);
                }
            }
            // Several boxes in one leaf (not with one triangle per leaf): a plain leaf.
            (Some(shared), _) => {
                for &b in prims {
                    let entry = shared.entry[b as usize];
                    if entry & SHARED == 0 {
                        self.faces.push(entry);
                    } else {
                        let g = (entry & !SHARED) as usize;
                        for item in shared.groups[g]..shared.groups[g + 1] {
                            self.faces.extend_from_slice(shared.item(item));
                        }
                    }
                }
            }
        }
        self.leaf_pair.resize(self.faces.len(), pair);
        (slot, self.faces.len() as u32 - slot)
    }

    /// The `items` of [`SharedBoxes`] (all in the box `aabb`, min and max) as a child of
    /// our pair `pair` at `depth`: a leaf for one item, else a balanced subtree of them.
    fn copy_items(
        &mut self,
        shared: &SharedBoxes,
        aabb: ([f32; 3], [f32; 3]),
        items: std::ops::Range<u32>,
        pair: u32,
        depth: usize,
    ) -> (u32, u32) {
        if items.len() == 1 {
            let slot = self.faces.len() as u32;
            let faces = shared.item(items.start);
            self.faces.extend_from_slice(faces);
            self.leaf_pair.resize(self.faces.len(), pair);
            let flag = if faces.len() > 1 { IDENTICAL } else { 0 };
            return (slot, faces.len() as u32 | flag);
        }
        let child = self.pairs.len() as u32;
        self.pairs.push(Pair::default());
        self.parent.push(pair);
        self.depth = self.depth.max(depth + 2);
        let middle = items.start + items.len() as u32 / 2;
        let mut built = Pair {
            min: [aabb.0; 2],
            max: [aabb.1; 2],
            ..Pair::default()
        };
        for (k, half) in [items.start..middle, middle..items.end]
            .into_iter()
            .enumerate()
        {
            (built.link[k], built.count[k]) = self.copy_items(shared, aabb, half, child, depth + 1);
        }
        self.pairs[child as usize] = built;
        (child, 0)
    }

    /// Number of triangles.
    #[inline]
    #[must_use]
    pub fn len(&self) -> usize {
        self.triangles.len()
    }

    /// Whether the tree holds no triangle.
    #[inline]
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// How many triangle boxes a point of the mesh's box lies in, on average
    /// ([`crate::reduce::box_overlap`], from the f32 boxes of the tree; dimensionless).
    #[inline]
    #[must_use]
    pub fn box_overlap(&self) -> f64 {
        self.box_overlap
    }

    /// Number of vertices of the mesh it was built from.
    #[inline]
    #[must_use]
    pub fn vertex_count(&self) -> usize {
        self.vertex_count
    }

    /// The point subtracted from every coordinate (length).
    #[inline]
    #[must_use]
    pub fn centre(&self) -> DVec3 {
        self.centre
    }

    /// Largest half side of the mesh's bounding box (length).
    #[inline]
    #[must_use]
    pub fn half_extent(&self) -> f64 {
        self.half_extent
    }

    /// Depth of the tree (a leaf root has depth 1).
    #[inline]
    #[must_use]
    pub fn depth(&self) -> usize {
        self.depth
    }

    /// The triangle in storage slot `slot` (recentred frame).
    #[inline]
    #[must_use]
    pub fn triangle(&self, slot: u32) -> &PreparedTriangle {
        &self.triangles[slot as usize]
    }

    /// A stack sized for this tree.
    #[must_use]
    pub fn stack(&self) -> SearchStack {
        SearchStack(Vec::with_capacity(self.depth + 1))
    }

    /// Tests the triangles of the leaf `first`, `count` (flag included: only the first of
    /// identical ones) against `p`, keeping the best.
    #[inline(always)]
    fn test_leaf(&self, p: DVec3, first: u32, count: u32, best: &mut Nearest) {
        let tested = if count & IDENTICAL != 0 { 1 } else { count };
        #[cfg(test)]
        tests::count_tested(tested);
        for slot in first..first + tested {
            let (q, d2) = self.triangles[slot as usize].closest(p);
            if d2 < best.d2 || (d2 == best.d2 && self.faces[slot as usize] < best.face) {
                *best = Nearest {
                    slot,
                    face: self.faces[slot as usize],
                    d2,
                    point: q,
                };
            }
        }
    }

    /// Whether a child box at squared distance `d2` (length²) may hold a triangle whose
    /// `(d², face)` is below `best`'s: `owner` is `2 × pair + child` (see the module docs).
    #[inline(always)]
    fn worth(&self, d2: f64, owner: usize, best: &Nearest) -> bool {
        d2 < best.d2 || (d2 == best.d2 && self.min_face[owner] < best.face)
    }

    /// The nearest triangle to `p` (recentred frame: subtract [`centre`](Self::centre)).
    ///
    /// `hint`: a triangle slot to test first (`u32::MAX` for none). `stop_below_d2`: return
    /// as soon as a triangle closer than this squared distance is found (0 for the exact
    /// nearest). `None` only for an empty tree.
    #[inline]
    pub fn nearest_local(
        &self,
        p: DVec3,
        hint: u32,
        stop_below_d2: f64,
        stack: &mut SearchStack,
    ) -> Option<Nearest> {
        if self.triangles.is_empty() {
            return None;
        }
        let mut best = Nearest {
            slot: u32::MAX,
            face: u32::MAX,
            d2: f64::INFINITY,
            point: p,
        };
        if (hint as usize) < self.triangles.len() {
            self.test_leaf(p, hint, 1, &mut best);
            if best.d2 < stop_below_d2 {
                return Some(best);
            }
        }
        if self.root_count > 0 {
            self.test_leaf(p, self.root_link, self.root_count, &mut best);
            return Some(best);
        }
        let stack = &mut stack.0;
        if (hint as usize) >= self.triangles.len() {
            self.descend(p, self.root_link, stop_below_d2, &mut best, stack);
            return Some(best);
        }
        // The hint is the previous query's answer and this query is near it: the subtree a
        // few levels above the hint's leaf likely holds the nearest triangle. Search it
        // first, then each ancestor's other child on the way up to the root, each only if
        // its box is within the best distance: together they cover the tree once.
        let mut start = self.leaf_pair[hint as usize];
        for _ in 0..RESTART_LEVELS {
            match self.parent[start as usize] {
                u32::MAX => break,
                up => start = up,
            }
        }
        if self.descend(p, start, stop_below_d2, &mut best, stack) {
            return Some(best);
        }
        let mut child = start;
        loop {
            let up = self.parent[child as usize];
            if up == u32::MAX {
                break;
            }
            let pair = &self.pairs[up as usize];
            let other = usize::from(pair.count[0] == 0 && pair.link[0] == child);
            if self.worth(
                pair.distance_squared(p, other),
                2 * up as usize + other,
                &best,
            ) {
                if pair.count[other] > 0 {
                    self.test_leaf(p, pair.link[other], pair.count[other], &mut best);
                    if best.d2 < stop_below_d2 {
                        return Some(best);
                    }
                } else if self.descend(p, pair.link[other], stop_below_d2, &mut best, stack) {
                    return Some(best);
                }
            }
            child = up;
        }
        Some(best)
    }

    /// Nearest-first search of the subtree under pair `start`, improving `best`; true when
    /// it stopped early at a triangle closer than `stop_below_d2` (squared length).
    #[inline(always)]
    fn descend(
        &self,
        p: DVec3,
        start: u32,
        stop_below_d2: f64,
        best: &mut Nearest,
        stack: &mut Vec<Pending>,
    ) -> bool {
        stack.clear();
        let mut current = start;
        'descend: loop {
            #[cfg(test)]
            tests::count_pair();
            let pair = &self.pairs[current as usize];
            let owner = 2 * current as usize;
            let [d0, d1] = pair.distances_squared(p);
            // The nearer box first; at equal distances, the one holding the smaller face
            // when that distance is the best one (only ties can be found there).
            let second_first = d1 < d0
                || (d1 == d0 && d0 == best.d2 && self.min_face[owner + 1] < self.min_face[owner]);
            let (near, far, dn, df) = if second_first {
                (1, 0, d1, d0)
            } else {
                (0, 1, d0, d1)
            };
            if self.worth(df, owner + far, best) {
                stack.push(Pending {
                    link: pair.link[far],
                    count: pair.count[far],
                    d2: df,
                    owner: (owner + far) as u32,
                });
            }
            if self.worth(dn, owner + near, best) {
                if pair.count[near] == 0 {
                    current = pair.link[near];
                    continue 'descend;
                }
                self.test_leaf(p, pair.link[near], pair.count[near], best);
                if best.d2 < stop_below_d2 {
                    return true;
                }
            }
            while let Some(next) = stack.pop() {
                if !self.worth(next.d2, next.owner as usize, best) {
                    continue;
                }
                if next.count == 0 {
                    current = next.link;
                    continue 'descend;
                }
                self.test_leaf(p, next.link, next.count, best);
                if best.d2 < stop_below_d2 {
                    return true;
                }
            }
            return false;
        }
    }

    /// The first of `local` (points in the tree's frame) farther than [`MAX_EXTENT`] from
    /// its centre on some axis, with that distance: such points' squared distances approach
    /// the float64 range, and the f32 boxes cannot hold them.
    #[must_use]
    pub fn beyond_reach(&self, local: &[DVec3]) -> Option<(usize, f64)> {
        local
            .par_iter()
            .position_first(|p| p.abs().max_element() > MAX_EXTENT)
            .map(|i| (i, local[i].abs().max_element()))
    }

    /// Exact nearest triangle to each point (caller's frame), in parallel.
    ///
    /// Returns, per point, the distance (length), the closest point (caller's frame,
    /// length) and the face index. The points are searched in [`coherent_order`], each
    /// search starting from the previous answer. Results do not depend on the order or the
    /// thread count.
    pub fn query(&self, points: &[[f64; 3]]) -> Result<QueryResult, MeshError> {
        let local = self.local_points(points)?;
        let (order, hits) = self.search_coherent(&local, QUERY_CHUNK, 0.0, |hit| hit);
        let n = points.len();
        let (mut dist, mut closest, mut face) = (vec![0.0; n], vec![[0.0; 3]; n], vec![0u32; n]);
        for (&i, hit) in order.iter().zip(&hits) {
            let i = i as usize;
            dist[i] = hit.d2.sqrt();
            closest[i] = (hit.point + self.centre).to_array();
            face[i] = hit.face;
        }
        Ok((dist, closest, face))
    }

    /// Searches `local` points (recentred frame) in [`coherent_order`], in parallel units
    /// of `chunk` points, each search hinted by the previous answer of its unit and
    /// stopping below `stop_below_d2` (0: exact). Returns the order and, in that order,
    /// what `keep` takes of each answer.
    pub fn search_coherent<T: Send>(
        &self,
        local: &[DVec3],
        chunk: usize,
        stop_below_d2: f64,
        keep: impl Fn(Nearest) -> T + Sync,
    ) -> (Vec<u32>, Vec<T>) {
        let order = coherent_order(local);
        let kept = order
            .par_chunks(chunk)
            .flat_map_iter(|unit| {
                let mut stack = self.stack();
                let mut hint = u32::MAX;
                unit.iter()
                    .map(|&i| {
                        let hit = self
                            .nearest_local(local[i as usize], hint, stop_below_d2, &mut stack)
                            .expect("the tree is not empty");
                        hint = hit.slot;
                        keep(hit)
                    })
                    .collect::<Vec<_>>()
            })
            .collect();
        (order, kept)
    }

    /// Which of `points` (caller's frame) lie farther than `distance` (length) from every
    /// triangle, decided exactly (`d(p) > distance`). A search stops at the first triangle
    /// within `distance` (usually the previous point's, or one in its subtree), so this
    /// costs far less than [`query`](Self::query) when most points are near the mesh.
    pub fn farther_than(&self, points: &[[f64; 3]], distance: f64) -> Result<Vec<bool>, MeshError> {
        if !(distance >= 0.0 && distance.is_finite()) {
            return Err(MeshError::Parameter(format!(
                "distance must be finite and >= 0, got {distance}"
            )));
        }
        let local = self.local_points(points)?;
        let stop = distance * distance;
        // Below `stop` a search ended early: within the distance. Else it ran to
        // completion, and `d2` is the exact minimum.
        let (order, verdicts) =
            self.search_coherent(&local, QUERY_CHUNK, stop, |hit| hit.d2 > stop);
        let mut far = vec![false; points.len()];
        for (&i, verdict) in order.iter().zip(verdicts) {
            far[i as usize] = verdict;
        }
        Ok(far)
    }

    /// `points` (caller's frame) in the tree's recentred frame, checked: finite and
    /// within [`MAX_EXTENT`] of the centre. Fails on an empty tree.
    fn local_points(&self, points: &[[f64; 3]]) -> Result<Vec<DVec3>, MeshError> {
        if self.is_empty() {
            return Err(MeshError::Empty("the tree holds no triangles".into()));
        }
        check_finite(points).map_err(|e| match e {
            MeshError::NonFinite { vertex } => {
                MeshError::Parameter(format!("point {vertex} has a NaN or infinite coordinate"))
            }
            other => other,
        })?;
        let local: Vec<DVec3> = points
            .par_iter()
            .map(|p| DVec3::from_array(*p) - self.centre)
            .collect();
        if let Some((i, far)) = self.beyond_reach(&local) {
            return Err(MeshError::Parameter(format!(
                "point {i} lies {far:.3e} (length) from the mesh's centre: more than the \
                 supported {MAX_EXTENT:.0e}"
            )));
        }
        Ok(local)
    }

    /// Checks the tree's invariants: every triangle slot sits in exactly one leaf, every
    /// triangle lies inside its leaf's box (in f64, margin `pad` included), every child
    /// box lies inside its parent's box, and the face map is a permutation.
    pub fn validate(&self) -> Result<(), String> {
        let n = self.triangles.len();
        if self.faces.len() != n || self.leaf_pair.len() != n {
            return Err(format!(
                "{} faces and {} leaf links for {n} triangles",
                self.faces.len(),
                self.leaf_pair.len()
            ));
        }
        if self.parent.len() != self.pairs.len() {
            return Err(format!(
                "{} parent links for {} pairs",
                self.parent.len(),
                self.pairs.len()
            ));
        }
        let mut seen_face = vec![false; n];
        for &f in &self.faces {
            let slot = seen_face
                .get_mut(f as usize)
                .ok_or(format!("face {f} out of range"))?;
            if std::mem::replace(slot, true) {
                return Err(format!("face {f} stored twice"));
            }
        }
        if n == 0 {
            return if self.pairs.is_empty() {
                Ok(())
            } else {
                Err("empty tree with nodes".into())
            };
        }
        let mut seen_slot = vec![false; n];
        let inside = |min: &[f32; 3], max: &[f32; 3], p: DVec3| {
            (0..3).all(|k| min[k] as f64 <= p[k] && p[k] <= max[k] as f64)
        };
        let mut check_leaf = |first: u32, count: u32, min: &[f32; 3], max: &[f32; 3]| {
            let (flagged, count) = (count & IDENTICAL != 0, slots_of(count));
            if count == 0 || (first + count) as usize > n {
                return Err(format!("leaf {first}+{count} out of range"));
            }
            if flagged {
                let slots = first as usize..(first + count) as usize;
                let same = &self.triangles[first as usize];
                if count < 2
                    || self.triangles[slots.clone()].iter().any(|t| t != same)
                    || self.faces[slots].windows(2).any(|w| w[0] >= w[1])
                {
                    return Err(format!(
                        "leaf {first}+{count} flagged identical: not 2 or more identical \
                         triangles in increasing face order"
                    ));
                }
            }
            for slot in first..first + count {
                if std::mem::replace(&mut seen_slot[slot as usize], true) {
                    return Err(format!("slot {slot} in two leaves"));
                }
                for corner in self.triangles[slot as usize].corners() {
                    if !inside(min, max, corner) {
                        return Err(format!("slot {slot}: corner {corner} outside its box"));
                    }
                }
            }
            Ok(())
        };
        if self.root_count > 0 {
            check_leaf(
                self.root_link,
                self.root_count,
                &self.root_min,
                &self.root_max,
            )?;
            if self.leaf_pair.iter().any(|&p| p != u32::MAX) {
                return Err("a slot of the root leaf linked to a pair".into());
            }
        } else {
            if self.parent.get(self.root_link as usize) != Some(&u32::MAX) {
                return Err("the root pair has a parent".into());
            }
            if self.min_face.len() != 2 * self.pairs.len() {
                return Err(format!(
                    "{} smallest faces for {} pairs",
                    self.min_face.len(),
                    self.pairs.len()
                ));
            }
            let mut seen_pair = vec![false; self.pairs.len()];
            let mut todo = vec![(self.root_link, self.root_min, self.root_max)];
            while let Some((index, pmin, pmax)) = todo.pop() {
                let pair = self
                    .pairs
                    .get(index as usize)
                    .ok_or(format!("pair {index} missing"))?;
                if std::mem::replace(&mut seen_pair[index as usize], true) {
                    return Err(format!("pair {index} reached twice"));
                }
                for k in 0..2 {
                    let (min, max) = (pair.min[k], pair.max[k]);
                    let corners = [
                        DVec3::from_array(min.map(f64::from)),
                        DVec3::from_array(max.map(f64::from)),
                    ];
                    if !corners.iter().all(|&c| inside(&pmin, &pmax, c)) {
                        return Err(format!("pair {index} child {k} outside its parent"));
                    }
                    let (link, count) = (pair.link[k], pair.count[k]);
                    let smallest = if count > 0 {
                        check_leaf(link, count, &min, &max)?;
                        let slots = link as usize..(link + slots_of(count)) as usize;
                        if self.leaf_pair[slots.clone()].iter().any(|&p| p != index) {
                            return Err(format!(
                                "a slot of leaf {link} not linked to pair {index}"
                            ));
                        }
                        self.faces[slots].iter().copied().min()
                    } else {
                        if self.parent.get(link as usize) != Some(&index) {
                            return Err(format!("pair {link} not linked to its parent {index}"));
                        }
                        todo.push((link, min, max));
                        let below = 2 * link as usize;
                        self.min_face.get(below..below + 2).map(|m| m[0].min(m[1]))
                    };
                    if smallest != Some(self.min_face[2 * index as usize + k]) {
                        return Err(format!("pair {index} child {k}: wrong smallest face"));
                    }
                }
            }
            if let Some(p) = seen_pair.iter().position(|s| !s) {
                return Err(format!("pair {p} unreachable"));
            }
        }
        match seen_slot.iter().position(|s| !s) {
            Some(slot) => Err(format!("triangle slot {slot} unreachable")),
            None => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::closest::closest_point_on_triangle;
    use std::cell::Cell;

    thread_local! {
        /// Triangles tested and pairs visited by this thread's searches.
        static TESTED: Cell<u64> = const { Cell::new(0) };
        static PAIRS: Cell<u64> = const { Cell::new(0) };
    }

    pub(super) fn count_tested(n: u32) {
        TESTED.with(|c| c.set(c.get() + u64::from(n)));
    }

    pub(super) fn count_pair() {
        PAIRS.with(|c| c.set(c.get() + 1));
    }

    /// Triangles tested and pairs visited by `f` on this thread.
    fn counted<T>(f: impl FnOnce() -> T) -> (T, u64, u64) {
        let (t0, p0) = (TESTED.with(Cell::get), PAIRS.with(Cell::get));
        let out = f();
        let (t1, p1) = (TESTED.with(Cell::get), PAIRS.with(Cell::get));
        (out, t1 - t0, p1 - p0)
    }

    fn lcg(state: &mut u64) -> f64 {
        *state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((*state >> 11) as f64) / ((1u64 << 53) as f64)
    }

    /// A random soup of `n` small triangles in the unit cube, some degenerate.
    fn soup(n: usize, seed: u64) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
        let mut s = seed;
        let mut v = Vec::new();
        let mut f = Vec::new();
        for i in 0..n {
            let c = [lcg(&mut s), lcg(&mut s), lcg(&mut s)];
            let base = v.len() as u32;
            for _ in 0..3 {
                v.push([
                    c[0] + 0.1 * lcg(&mut s),
                    c[1] + 0.1 * lcg(&mut s),
                    c[2] + 0.1 * lcg(&mut s),
                ]);
            }
            match i % 7 {
                0 => f.push([base, base, base + 1]),
                1 => {
                    let (a, b) = (v[base as usize], v[base as usize + 1]);
                    v[base as usize + 2] = [
                        (a[0] + b[0]) / 2.0,
                        (a[1] + b[1]) / 2.0,
                        (a[2] + b[2]) / 2.0,
                    ];
                    f.push([base, base + 1, base + 2]);
                }
                _ => f.push([base, base + 1, base + 2]),
            }
        }
        (v, f)
    }

    fn brute(v: &[[f64; 3]], f: &[[u32; 3]], p: DVec3) -> (f64, u32) {
        let at = |i: u32| DVec3::from_array(v[i as usize]);
        f.iter()
            .enumerate()
            .map(|(i, t)| {
                (
                    closest_point_on_triangle(p, at(t[0]), at(t[1]), at(t[2])).1,
                    i as u32,
                )
            })
            .fold(
                (f64::INFINITY, u32::MAX),
                |a, b| if b.0 < a.0 { b } else { a },
            )
    }

    #[test]
    fn every_size_from_1_to_100_validates_and_matches_brute_force() {
        for n in 1..=100 {
            let (v, f) = soup(n, n as u64);
            let tree = TriangleTree::build(&v, &f).unwrap();
            tree.validate().unwrap_or_else(|e| panic!("n = {n}: {e}"));
            assert_eq!(tree.len(), n);
            assert_matches_brute_force(&tree, &v, &f, 99 + n as u64, 20);
        }
    }

    /// Nearest distances of `queries` seeded points around the unit cube equal brute
    /// force's (the same triangles, recentred: equal up to rounding).
    fn assert_matches_brute_force(
        tree: &TriangleTree,
        v: &[[f64; 3]],
        f: &[[u32; 3]],
        seed: u64,
        queries: usize,
    ) {
        let mut s = seed;
        let mut stack = tree.stack();
        for _ in 0..queries {
            let p = DVec3::new(lcg(&mut s), lcg(&mut s), lcg(&mut s)) * 1.4 - 0.2;
            let hit = tree
                .nearest_local(p - tree.centre(), u32::MAX, 0.0, &mut stack)
                .unwrap();
            let (d2, _) = brute(v, f, p);
            assert!(
                (hit.d2.sqrt() - d2.sqrt()).abs() < 1e-14,
                "{} faces: {} vs {d2}",
                f.len(),
                hit.d2
            );
        }
    }

    #[test]
    fn a_deep_tree_validates_matches_brute_force_and_does_not_depend_on_threads() {
        let (v, f) = soup(20_000, 7);
        let tree = TriangleTree::build(&v, &f).unwrap();
        tree.validate().unwrap();
        let single = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| TriangleTree::build(&v, &f).unwrap());
        assert_eq!(single.faces, tree.faces);
        assert_eq!(single.depth, tree.depth);
        assert_matches_brute_force(&tree, &v, &f, 5, 50);
    }

    #[test]
    fn hints_and_early_exit() {
        let (v, f) = soup(500, 3);
        let tree = TriangleTree::build(&v, &f).unwrap();
        let mut stack = tree.stack();
        let p = DVec3::new(0.5, 0.5, 0.5) - tree.centre();
        let exact = tree.nearest_local(p, u32::MAX, 0.0, &mut stack).unwrap();
        for hint in [0, 17, 499] {
            assert_eq!(tree.nearest_local(p, hint, 0.0, &mut stack).unwrap(), exact);
        }
        // Stopping below a huge threshold returns the hint itself.
        let early = tree
            .nearest_local(p, 17, f64::INFINITY, &mut stack)
            .unwrap();
        assert_eq!(early.slot, 17);
        assert!(early.d2 >= exact.d2);
    }

    /// An exact search started from any hint (near the query or across the tree) climbs
    /// from the hint's subtree to the root and returns the brute-force nearest triangle.
    #[test]
    fn exact_search_from_any_hint_matches_brute_force() {
        let (v, f) = soup(20_000, 5);
        let tree = TriangleTree::build(&v, &f).unwrap();
        let mut stack = tree.stack();
        let mut state = 99u64;
        for _ in 0..300 {
            let p = DVec3::new(lcg(&mut state), lcg(&mut state), lcg(&mut state)) * 1.4
                - DVec3::splat(0.2);
            let (d2, face) = brute(&v, &f, p);
            let unhinted = tree
                .nearest_local(p - tree.centre(), u32::MAX, 0.0, &mut stack)
                .unwrap();
            for hint in [
                unhinted.slot,
                (lcg(&mut state) * 20_000.0) as u32,
                0,
                19_999,
            ] {
                let hit = tree
                    .nearest_local(p - tree.centre(), hint, 0.0, &mut stack)
                    .unwrap();
                assert_eq!(hit, unhinted, "hint {hint}");
                assert_eq!(hit.face, face);
                assert!((hit.d2.sqrt() - d2.sqrt()).abs() < 1e-14);
            }
        }
    }

    /// An early-exit search along a path of nearby queries, each hinted by the previous
    /// answer (so that it starts in the hint's subtree): below the stop distance it returns
    /// a triangle within it, at its true distance; otherwise the exact nearest.
    #[test]
    fn early_exit_from_the_hints_subtree_matches_brute_force() {
        let (v, f) = soup(20_000, 11);
        let tree = TriangleTree::build(&v, &f).unwrap();
        let mut stack = tree.stack();
        let mut hint = u32::MAX;
        let (mut early, mut exact_answers) = (0, 0);
        for step in 0..2_000 {
            let t = step as f64 / 2_000.0;
            let p = DVec3::new(t, 0.5 + 0.3 * (7.0 * t).sin(), 0.5 + 0.3 * (5.0 * t).cos());
            let (exact, _) = brute(&v, &f, p);
            let stop = 0.01 * 0.01;
            let hit = tree
                .nearest_local(p - tree.centre(), hint, stop, &mut stack)
                .unwrap();
            let face = f[hit.face as usize];
            let at = |i: u32| DVec3::from_array(v[i as usize]);
            let (_, true_d2) = closest_point_on_triangle(p, at(face[0]), at(face[1]), at(face[2]));
            assert!((hit.d2 - true_d2).abs() <= 1e-12 * (1.0 + true_d2));
            if exact < stop {
                assert!(hit.d2 < stop, "step {step}: {} not below the stop", hit.d2);
                early += 1;
            } else {
                assert!((hit.d2.sqrt() - exact.sqrt()).abs() < 1e-14, "step {step}");
                exact_answers += 1;
            }
            hint = hit.slot;
        }
        assert!(
            early > 100 && exact_answers > 100,
            "{early} early, {exact_answers} exact"
        );
    }

    /// The overlap measured on the tree's f32 boxes is the f64 one of `reduce`, up to the
    /// boxes' outward rounding.
    #[test]
    fn box_overlap_matches_the_f64_pass() {
        for (n, seed) in [(1, 1), (37, 2), (5_000, 3)] {
            let (v, f) = soup(n, seed);
            let tree = TriangleTree::build(&v, &f).unwrap();
            let exact = crate::reduce::box_overlap(&v, &f);
            assert!(exact > 0.0);
            let rel = (tree.box_overlap() - exact).abs() / exact;
            assert!(rel < 1e-5, "{n} faces: {} vs {exact}", tree.box_overlap());
        }
        assert_eq!(
            TriangleTree::build(&[[0.0; 3]], &[]).unwrap().box_overlap(),
            0.0
        );
    }

    /// `farther_than` agrees with the exact distances of `query`, at several distances.
    #[test]
    fn farther_than_matches_the_exact_distances() {
        let (v, f) = soup(3_000, 21);
        let tree = TriangleTree::build(&v, &f).unwrap();
        let mut s = 5;
        let points: Vec<[f64; 3]> = (0..4_000)
            .map(|_| [lcg(&mut s), lcg(&mut s), lcg(&mut s)].map(|x| x * 1.4 - 0.2))
            .collect();
        let (exact, _, _) = tree.query(&points).unwrap();
        for distance in [0.0, 0.01, 0.05, 0.2, 10.0] {
            let far = tree.farther_than(&points, distance).unwrap();
            for (i, (&d, &verdict)) in exact.iter().zip(&far).enumerate() {
                assert_eq!(verdict, d > distance, "point {i}: {d} against {distance}");
            }
        }
        assert!(tree.farther_than(&points, -1.0).is_err());
        assert!(tree.farther_than(&[[f64::NAN, 0.0, 0.0]], 0.1).is_err());
    }

    #[test]
    fn empty_tree_and_leaf_root() {
        let tree = TriangleTree::build(&[[0.0; 3]], &[]).unwrap();
        tree.validate().unwrap();
        assert!(
            tree.nearest_local(DVec3::ZERO, u32::MAX, 0.0, &mut tree.stack())
                .is_none()
        );
        assert!(tree.query(&[[0.0; 3]]).is_err());
        let v = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let tree = TriangleTree::build(&v, &[[0, 1, 2]]).unwrap();
        tree.validate().unwrap();
        let (d, q, face) = tree.query(&[[0.25, 0.25, 2.0]]).unwrap();
        assert_eq!((d[0], face[0]), (2.0, 0));
        assert_eq!(q[0], [0.25, 0.25, 0.0]);
    }

    #[test]
    fn ties_go_to_the_smallest_face_index() {
        // The same triangle four times, in a larger mesh.
        let (mut v, mut f) = soup(50, 5);
        let base = v.len() as u32;
        v.extend([[2.0, 2.0, 2.0], [3.0, 2.0, 2.0], [2.0, 3.0, 2.0]]);
        for _ in 0..4 {
            f.push([base, base + 1, base + 2]);
        }
        let tree = TriangleTree::build(&v, &f).unwrap();
        let (_, _, face) = tree.query(&[[2.2, 2.2, 2.5]]).unwrap();
        assert_eq!(face[0], 50);
    }

    /// `n` faces of the soup with every vertex at one point (a mesh collapsed by a coarse
    /// quantization), some faces repeated with permuted corners.
    fn collapsed(n: usize, at: [f64; 3]) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
        let (v, mut f) = soup(n, 4);
        for (i, face) in f.iter_mut().enumerate() {
            face.rotate_left(i % 3);
        }
        (vec![at; v.len()], f)
    }

    /// Queries around the unit cube against `tree`: each answer is brute force's (the
    /// smallest face at the smallest distance, whatever the hint), and the triangles
    /// tested and pairs visited per query average at most `tested` and `pairs`.
    fn assert_bounded_and_exact(
        tree: &TriangleTree,
        v: &[[f64; 3]],
        f: &[[u32; 3]],
        tested: f64,
        pairs: f64,
    ) {
        tree.validate().unwrap();
        let mut stack = tree.stack();
        let mut s = 17;
        let mut hint = u32::MAX;
        let (mut all_tested, mut all_pairs, queries) = (0, 0, 400);
        for i in 0..queries {
            let p = DVec3::new(lcg(&mut s), lcg(&mut s), lcg(&mut s)) * 1.4 - 0.2;
            let (hit, t, q) =
                counted(|| tree.nearest_local(p - tree.centre(), hint, 0.0, &mut stack));
            let hit = hit.unwrap();
            (all_tested, all_pairs) = (all_tested + t, all_pairs + q);
            let (d2, _) = brute(v, f, p);
            assert!(
                (hit.d2.sqrt() - d2.sqrt()).abs() < 1e-14,
                "{} vs {d2}",
                hit.d2
            );
            // Exactly the smallest (d², face) over every stored triangle (the tree's frame).
            let exact = (0..tree.len() as u32)
                .map(|slot| {
                    let d2 = tree.triangle(slot).closest(p - tree.centre()).1;
                    (d2, tree.faces[slot as usize])
                })
                .fold((f64::INFINITY, u32::MAX), |a, b| if b < a { b } else { a });
            assert_eq!((hit.d2, hit.face), exact, "query {i}");
            let unhinted = tree.nearest_local(p - tree.centre(), u32::MAX, 0.0, &mut stack);
            assert_eq!(unhinted, Some(hit));
            // Every hint, including a slot that is not the first of identical triangles.
            hint = (lcg(&mut s) * f.len() as f64) as u32;
        }
        let (t, q) = (
            all_tested as f64 / f64::from(queries),
            all_pairs as f64 / f64::from(queries),
        );
        assert!(
            t <= tested && q <= pairs,
            "{t} triangles, {q} pairs per query"
        );
    }

    /// A mesh collapsed to one point is one leaf of identical triangles: a query tests the
    /// hint and the smallest face, and answers that face; the distances are brute force's.
    #[test]
    fn a_collapsed_mesh_is_one_leaf_tested_once() {
        for at in [[0.0; 3], [0.3, -0.7, 1e3]] {
            let (v, f) = collapsed(20_000, at);
            let tree = TriangleTree::build(&v, &f).unwrap();
            assert_eq!(tree.root_count, 20_000 | IDENTICAL);
            assert_eq!(tree.depth(), 1);
            assert_bounded_and_exact(&tree, &v, &f, 2.0, 0.0);
            let (d, q, face) = tree.query(&[[0.0, 0.0, 5.0], at]).unwrap();
            assert_eq!(face, [0, 0]);
            assert_eq!(q, [at, at]);
            assert_eq!(d[1], 0.0);
        }
    }

    /// Without merging identical triangles, the tie rule alone (a box at exactly the best
    /// distance is skipped unless it holds a smaller face) bounds the search on a mesh
    /// collapsed to the centre, where every box is at the best distance: a few paths
    /// down the tree, not the 20,000 triangles.
    #[test]
    fn ties_skip_boxes_without_a_smaller_face() {
        let (v, f) = collapsed(20_000, [0.0; 3]);
        let tree = TriangleTree::build_with(&v, &f, false).unwrap();
        assert_eq!(tree.root_count, 0);
        // One box holding 20,000 faces in a balanced tree (PLOC made a chain 20,000 deep).
        assert_eq!(tree.depth(), 16);
        // 5.8 triangles and 44 pairs per query (visiting every box at the best distance
        // tested the 20,000 triangles).
        assert_bounded_and_exact(&tree, &v, &f, 12.0, 80.0);
    }

    /// Half the faces collapsed to one point off the centre (padded boxes: the tie rule
    /// does not prune them, merging does), the others a soup: exact, and bounded.
    #[test]
    fn a_partly_collapsed_mesh_is_exact_and_bounded() {
        let (mut v, f) = soup(20_000, 9);
        let at = [0.61, 0.27, 0.43];
        for face in f.iter().step_by(2) {
            for &i in face {
                v[i as usize] = at;
            }
        }
        let tree = TriangleTree::build(&v, &f).unwrap();
        // 13 triangles and 82 pairs per query.
        assert_bounded_and_exact(&tree, &v, &f, 30.0, 160.0);
        // Repeated faces (the same indices) merge too: 7.8 triangles, 45 pairs per query.
        let (v, f) = soup(2_000, 3);
        let f: Vec<[u32; 3]> = f.iter().flat_map(|&t| [t; 7]).collect();
        let tree = TriangleTree::build(&v, &f).unwrap();
        assert_bounded_and_exact(&tree, &v, &f, 16.0, 90.0);
        // 200 distinct triangles closer together than the f32 boxes resolve, each
        // repeated: boxes holding several sets of identical triangles. The boxes cannot
        // tell the 200 apart: a query nearest to them tests each (the copies once).
        let (mut v, f) = soup(4_000, 5);
        let mut s = 3;
        for p in &mut v[..600] {
            *p = [0.61, 0.27, 0.43].map(|x| x + 1e-11 * lcg(&mut s));
        }
        let f: Vec<[u32; 3]> = f.iter().flat_map(|&t| [t; 3]).collect();
        let tree = TriangleTree::build(&v, &f).unwrap();
        let shared = (0..tree.pairs.len()).any(|i| {
            let pair = &tree.pairs[i];
            pair.min[0] == pair.min[1] && pair.max[0] == pair.max[1]
        });
        assert!(shared, "no box holds several sets");
        // 25 triangles, 74 pairs per query.
        assert_bounded_and_exact(&tree, &v, &f, 60.0, 160.0);
    }

    #[test]
    fn far_from_the_origin() {
        let (v, f) = soup(200, 8);
        let shifted: Vec<[f64; 3]> = v.iter().map(|p| p.map(|x| x + 1e6)).collect();
        let (t0, t1) = (
            TriangleTree::build(&v, &f).unwrap(),
            TriangleTree::build(&shifted, &f).unwrap(),
        );
        t1.validate().unwrap();
        let pts: Vec<[f64; 3]> = (0..50).map(|i| [0.01 * i as f64, 0.5, 0.3]).collect();
        let pts_shifted: Vec<[f64; 3]> = pts.iter().map(|p| p.map(|x| x + 1e6)).collect();
        let (d0, _, f0) = t0.query(&pts).unwrap();
        let (d1, _, f1) = t1.query(&pts_shifted).unwrap();
        assert_eq!(f0, f1);
        for (a, b) in d0.iter().zip(&d1) {
            assert!((a - b).abs() < 1e-9, "{a} vs {b}");
        }
    }

    #[test]
    fn non_finite_points_are_refused() {
        let v = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let tree = TriangleTree::build(&v, &[[0, 1, 2]]).unwrap();
        assert!(tree.query(&[[f64::NAN, 0.0, 0.0]]).is_err());
        assert!(TriangleTree::build(&[[f64::INFINITY, 0.0, 0.0]], &[[0, 0, 0]]).is_err());
        assert!(TriangleTree::build(&v, &[[0, 1, 3]]).is_err());
    }
}
