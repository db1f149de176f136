//! Building the tree: triangle boxes computed in f64 and rounded outward to f32, equal
//! boxes grouped ([`SharedBoxes`]), obvhs's PLOC tree copied into sibling pairs in
//! depth-first order (see the [module docs](super)).

use std::time::Duration;

use glam::{DVec3, Vec3A};
use obvhs::BvhBuildParams;
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use obvhs::bvh2::builder::build_bvh2;
use rayon::prelude::*;

use super::primitives::{Primitive, Primitives};
use super::runs::find_runs;
use super::shared_boxes::SharedBoxes;
use super::tree::{IDENTICAL, Pair, RUN, TriangleTree};
use crate::closest::PreparedTriangle;
use crate::error::{MAX_EXTENT, MeshError, check_finite, check_indices};

/// Relative widening of every triangle box before the f32 conversion (`2⁻⁴⁰`).
const BOX_PAD: f64 = 1.0 / (1u64 << 40) as f64;

/// obvhs build preset: PLOC with the shortest search radius, no reinsertion and no leaf
/// collapse (one triangle per leaf). On the benchmark meshes, longer searches,
/// reinsertion and SAH-collapsed leaves of up to 2, 4 or 8 triangles built 1.3 to 2 times
/// slower and answered closest-point queries no faster (`benches/bench_hausdorff.py`).
const BUILD_PARAMS: BvhBuildParams = BvhBuildParams {
    max_prims_per_leaf: 1,
    ..BvhBuildParams::fastest_build()
};

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

impl TriangleTree {
    /// Builds the tree over `faces` (indices into `vertices`, length unit of the caller).
    ///
    /// An empty face list gives an empty tree (every query answers `None`).
    pub fn build(vertices: &[[f64; 3]], faces: &[[u32; 3]]) -> Result<Self, MeshError> {
        Self::build_with(vertices, faces, true)
    }

    /// [`build`](Self::build); `merge_identical: false` keeps identical triangles in
    /// leaves of their own (tests of the tie rule alone).
    pub(super) fn build_with(
        vertices: &[[f64; 3]],
        faces: &[[u32; 3]],
        merge_identical: bool,
    ) -> Result<Self, MeshError> {
        check_finite(vertices)?;
        check_indices(faces, vertices.len())?;
        if faces.len() >= RUN as usize {
            return Err(MeshError::Parameter(format!(
                "{} faces exceed 2**30",
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
        let runs = if merge_identical {
            // Input coordinates carry rounding relative to their size, not the mesh's.
            let scale = half_extent.max(centre.abs().max_element());
            find_runs(faces, vertices.len(), local, &boxes, scale)
        } else {
            Vec::new()
        };
        let primitives = Primitives::new(faces, &boxes, runs, |face| {
            if merge_identical {
                // Bitwise-equal recentred corners: equal faces, or faces collapsed to one
                // point.
                let f = faces[face as usize];
                [0, 1, 2].map(|k| local(f[k]).to_array().map(f64::to_bits))
            } else {
                [[u64::from(face); 3]; 3]
            }
        });
        let bvh = build_bvh2(
            primitives.boxes(&boxes),
            BUILD_PARAMS,
            &mut Duration::default(),
        );

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
            runs: Vec::new(),
            depth: 0,
            vertex_count: vertices.len(),
            box_overlap: overlap_of_boxes(&boxes, hi - lo),
        };
        if !bvh.nodes.is_empty() {
            tree.copy_from(&bvh, &primitives);
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
    fn copy_from(&mut self, bvh: &Bvh2, primitives: &Primitives) {
        let root = &bvh.nodes[0];
        self.root_min = root.aabb.min.to_array();
        self.root_max = root.aabb.max.to_array();
        if root.is_leaf() {
            (self.root_link, self.root_count) = self.copy_leaf(bvh, primitives, 0, u32::MAX, 0);
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
                            self.copy_leaf(bvh, primitives, index, pair, depth);
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
                self.min_face[2 * index + k] = if count == 1 || count & (IDENTICAL | RUN) != 0 {
                    // One triangle, or identical ones or a run in face order.
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
    /// leaves under the same box, the items of smaller faces on the first side. A run
    /// becomes one leaf, its faces in order, flagged [`RUN`].
    fn copy_leaf(
        &mut self,
        bvh: &Bvh2,
        primitives: &Primitives,
        index: u32,
        pair: u32,
        depth: usize,
    ) -> (u32, u32) {
        let node = &bvh.nodes[index as usize];
        let first = node.first_index as usize;
        let prims = &bvh.primitive_indices[first..first + node.prim_count as usize];
        let slot = self.faces.len() as u32;
        match prims {
            &[b] => match primitives.kind(b) {
                Primitive::Face(face) => self.faces.push(face),
                Primitive::Shared(shared, g) => {
                    let items = shared.groups[g]..shared.groups[g + 1];
                    let aabb = (node.aabb.min.to_array(), node.aabb.max.to_array());
                    return self.copy_items(shared, aabb, items, pair, depth);
                }
                Primitive::Run(run) => {
                    self.faces.extend_from_slice(&run.faces);
                    self.leaf_pair.resize(self.faces.len(), pair);
                    self.runs.push(run.placed(slot));
                    return (slot, run.faces.len() as u32 | RUN);
                }
            },
            // Several boxes in one leaf (not with one triangle per leaf): a plain leaf.
            _ => {
                for &b in prims {
                    match primitives.kind(b) {
                        Primitive::Face(face) => self.faces.push(face),
                        Primitive::Shared(shared, g) => {
                            for item in shared.groups[g]..shared.groups[g + 1] {
                                self.faces.extend_from_slice(shared.item(item));
                            }
                        }
                        Primitive::Run(run) => self.faces.extend_from_slice(&run.faces),
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
}
