//! The stored tree: sibling pairs of f32 boxes (one cache line each), the triangles
//! prepared in leaf order, and the links a hinted search climbs (see the
//! [module docs](super)). Built in `build.rs`, searched in `search.rs`.

use glam::{DVec3, Vec3A};

use crate::closest::PreparedTriangle;

use super::runs::Run;

/// Flag of a leaf's triangle count: its triangles are bitwise identical (recentred corners
/// equal, slots sorted by face index), and only the first is tested. Counts stay below
/// 2³⁰ (fewer than 2³⁰ faces).
pub(super) const IDENTICAL: u32 = 1 << 31;

/// Flag of a leaf's triangle count: its triangles are a collinear run (`runs.rs`, slots
/// sorted by face index), searched as one segment.
pub(super) const RUN: u32 = 1 << 30;

/// Triangle slots of a leaf of `count` (flags included).
#[inline(always)]
pub(super) fn slots_of(count: u32) -> u32 {
    count & !(IDENTICAL | RUN)
}

/// Two sibling boxes and what they hold: one cache line.
#[derive(Debug, Clone, Copy, Default)]
#[repr(C, align(64))]
pub(super) struct Pair {
    pub(super) min: [[f32; 3]; 2],
    pub(super) max: [[f32; 3]; 2],
    /// Inner child: index of its own pair of children. Leaf: first triangle slot.
    pub(super) link: [u32; 2],
    /// Triangles in a leaf child, with the [`IDENTICAL`] or [`RUN`] flag; 0 for an inner
    /// child.
    pub(super) count: [u32; 2],
}

impl Pair {
    /// Squared distance (length²) from `p` to box `k`; 0 inside.
    #[inline(always)]
    pub(super) fn distance_squared(&self, p: DVec3, k: usize) -> f64 {
        let lo = Vec3A::from_array(self.min[k]).as_dvec3();
        let hi = Vec3A::from_array(self.max[k]).as_dvec3();
        (lo - p).max(p - hi).max(DVec3::ZERO).length_squared()
    }

    /// Squared distances (length²) from `p` to both boxes; 0 inside.
    #[inline(always)]
    pub(super) fn distances_squared(&self, p: DVec3) -> [f64; 2] {
        [self.distance_squared(p, 0), self.distance_squared(p, 1)]
    }
}

/// Bounding volume hierarchy over one mesh's triangles. See the [module docs](super).
#[derive(Debug, Clone)]
pub struct TriangleTree {
    pub(super) centre: DVec3,
    /// Largest half side of the bounding box (length).
    pub(super) half_extent: f64,
    pub(super) pairs: Vec<Pair>,
    /// Root: a leaf (`root_count > 0`: triangles `root_link ..`) or the pair `root_link`.
    pub(super) root_link: u32,
    pub(super) root_count: u32,
    pub(super) root_min: [f32; 3],
    pub(super) root_max: [f32; 3],
    pub(super) triangles: Vec<PreparedTriangle>,
    pub(super) faces: Vec<u32>,
    /// Per pair, the pair holding it as a child (`u32::MAX` for the root pair).
    pub(super) parent: Vec<u32>,
    /// Per triangle slot, the pair holding its leaf (`u32::MAX` when the root is a leaf).
    pub(super) leaf_pair: Vec<u32>,
    /// Per child box (`2 × pair + child`), the smallest face index below it.
    pub(super) min_face: Vec<u32>,
    /// The collinear runs, in slot order (empty for most meshes).
    pub(super) runs: Vec<Run>,
    pub(super) depth: usize,
    pub(super) vertex_count: usize,
    /// [`crate::reduce::box_overlap`] of the mesh, from the triangles' f32 boxes.
    pub(super) box_overlap: f64,
}

impl TriangleTree {
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

    /// The run holding slot `slot`, if any.
    #[inline]
    pub(super) fn run_holding(&self, slot: u32) -> Option<&Run> {
        if self.runs.is_empty() {
            return None;
        }
        let k = self.runs.partition_point(|r| r.first <= slot);
        let run = &self.runs[k.checked_sub(1)?];
        (slot - run.first < run.len).then_some(run)
    }

    /// The triangle in storage slot `slot` (recentred frame).
    #[inline]
    #[must_use]
    pub fn triangle(&self, slot: u32) -> &PreparedTriangle {
        &self.triangles[slot as usize]
    }
}
