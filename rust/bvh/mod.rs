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
//! best found: the search returns the exact f64 minimum over all triangles (within a
//! collinear run, see below, the distance of the run's face for the query).
//!
//! **Tree.** obvhs's PLOC builder makes a binary tree whose sibling nodes sit next to each
//! other. [`TriangleTree`] copies it into pairs of sibling boxes (64 bytes, one cache
//! line): visiting an inner node reads both children's boxes at once. Triangles are stored
//! prepared ([`PreparedTriangle`](crate::closest::PreparedTriangle)) in leaf order, so a
//! leaf's triangles are contiguous.
//!
//! **Equal boxes.** Triangles whose f32 boxes are bitwise equal are grouped before the
//! build (`SharedBoxes` in `shared_boxes.rs`: a radix sort of 32-bit box hashes, about 3 ms
//! per 200k faces on one thread, and nothing more unless two hashes are equal), and PLOC
//! gets each box once: given `n` equal boxes (a mesh collapsed to one point) it merged one
//! pair per pass, a chain `n` deep built in quadratic time (69k faces: 15 s). Inside a box,
//! triangles with bitwise-equal recentred corners (collapsed to the same point, or repeated
//! faces) form one leaf flagged `IDENTICAL`, its slots in face order: their distances are
//! bitwise equal, so only the first (the smallest face) is tested. Several such sets in one
//! box (distinct triangles closer together than the f32 boxes resolve) form a balanced
//! subtree of them, in the order of their smallest faces; a query nearest to them tests
//! each set, as the boxes cannot tell them apart.
//!
//! **Collinear runs.** Zero-area triangles lying on one line and connected through shared
//! vertices (a mesh collapsed onto a line, or onto lines) are grouped before the build
//! (`runs.rs`): PLOC gets one box per run, and the run is one leaf flagged `RUN`, its
//! slots in face order, searched as one segment: the query's closest point on the run's
//! segment picks the smallest face holding it (a binary search of the faces' intervals
//! along the line), and that face's own exact distance is the answer. Segments overlap
//! hundreds deep on such a mesh, each inside a box far looser than itself: on the bunny
//! collapsed onto a diagonal, a query tested 5,600 of its 69,451 triangles; it tests one.
//! A run's answer may exceed the smallest distance over its faces by about twice the
//! run's width (`2⁻⁴⁶` of the mesh's scale, plus rounding), never undercut it: it is the
//! distance to a point of the mesh. A hint inside a run tests the run, so the answer does
//! not depend on the hint.
//!
//! **Search.** Nearest-first branch and bound with an explicit stack: at each inner node
//! both child boxes are measured; the nearer child is visited first and the farther one
//! pushed, each only if it may hold a better answer (see *Ties*). A
//! `hint` triangle (for instance the previous query's answer, when queries are spatially
//! coherent) sets the starting best, and the search starts in the subtree
//! `RESTART_LEVELS` levels above the hint's leaf (every pair knows its parent, every
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
//!
//! **Files**, imports running one way (`queries` -> `search` -> `tree` -> `runs`; `build`
//! -> `primitives` -> `shared_boxes`, `runs`; `build` -> `tree`): `tree.rs` (the stored tree: sibling pairs, prepared
//! triangles, links), `build.rs` (from obvhs's PLOC tree to ours), `shared_boxes.rs`
//! (equal boxes grouped before the build), `runs.rs` (collinear runs), `primitives.rs` (what PLOC builds on:
//! faces, shared boxes, runs), `search.rs` (the nearest-triangle search),
//! `queries.rs` (batches of queries in [`coherent_order`]), `order.rs` (the Morton
//! order) and `validate.rs` (the tree's invariants, which the tests check).

mod build;
mod order;
mod primitives;
mod queries;
mod runs;
mod search;
mod shared_boxes;
mod tree;
mod validate;

#[cfg(test)]
mod tests;

pub use order::coherent_order;
pub use queries::QueryResult;
pub use search::{Nearest, SearchStack};
pub use tree::TriangleTree;
