//! The sampled one-sided Hausdorff distance, with a certified upper bound.
//!
//! The one-sided distance from a source surface `A` to a target surface `B` is
//! `h(A, B) = max over p in A of d(p, B)`, `d(p, B) = min over q in B of |p - q|`
//! (length); the Hausdorff distance of King & Rossignac (1999, Sec. 3.2) is
//! `H(A, B) = max(h(A, B), h(B, A))`. Here `A` is replaced by its sample set
//! ([`crate::sampling`]): every referenced vertex plus `N` seeded area samples. Each
//! sample's `d(p, B)` is the exact f64 minimum over `B`'s triangles ([`crate::bvh`]; on
//! faces collapsed onto a line, within `2⁻⁴⁵` of the mesh's scale above it, never below:
//! the bounds below only need distances to points of `B`).
//!
//! **Exact and max-only searches.** With `statistics`, every area sample's distance is
//! computed in full, which gives the mean, RMS and percentiles of `d(·, B)` over `A` (area
//! samples are uniform by area, so these estimate the surface's own statistics; the vertex
//! samples, dense where the mesh is fine, would bias them and are left out). Samples whose
//! exact distance nobody needs only have to show they cannot raise the maximum: they
//! are searched against a shared running maximum `m` (an exact distance of some sample),
//! and a sample whose search has found a triangle closer than `m` cannot raise the maximum,
//! so its search stops there (usually after testing one hint triangle). A sample whose
//! true distance equals the final maximum is never stopped early, so the maximum and its
//! sample (the smallest sample index among ties) do not depend on the thread count.
//!
//! **Certified upper bound.** Two bounds hold on any source triangle `T` (and on any
//! piece of it), and the smaller one is kept:
//!
//! * *Lipschitz*: `d(·, B)` is 1-Lipschitz. If the corners have distances at most
//!   `d₀, d₁, d₂` and `R_T` is the covering radius of `T` by its corners
//!   ([`covering_radius`](crate::closest::covering_radius)), every point of `T` is within
//!   `R_T` of a corner, so `max over T of d(·, B) ≤ max(d₀, d₁, d₂) + R_T`.
//! * *Convex*: for any one target triangle `t`, `d(·, B) ≤ d(·, t)`, and `d(·, t)` is the
//!   distance to a convex set, a convex function, whose maximum over `T` is reached at a
//!   corner. So `max over T of d(·, B) ≤ max_i d(v_i, t)`, tried for the target triangles
//!   found for the three corners. It is exact when the corners share their nearest
//!   triangle, which the Lipschitz bound never is on flat, parallel pieces.
//!
//! * *Split*: when the corners' target triangles `t_i`, `t_j` share an edge, the plane
//!   through that edge (perpendicular to their mean plane) cuts `T` into two convex
//!   pieces, each bounded by the convex bound of its own triangle, evaluated at the
//!   piece's vertices (corners and the crossings of `T`'s edges with the plane). A piece
//!   straddling the edge of two nearly coplanar triangles, as on the flat faces of a CAD
//!   part, gets about its height above them.
//!
//! The largest bound over the source triangles bounds `h(A, B)` from above; the sampled
//! maximum (the largest exact distance of any point evaluated) bounds it from below. With
//! a tolerance `τ`, each triangle whose bound exceeds `lower + τ` is split at its edge
//! midpoints into four similar triangles of half the covering radius, the three midpoints
//! are evaluated, and so on, level by level, until every bound is `≤ lower + τ` (then
//! `upper - lower ≤ τ`) or a query budget is spent. The Lipschitz bound guarantees the end:
//! once `R ≤ τ` a piece settles. A piece that is one point (`R = 0`, a triangle collapsed
//! to a point) is never split: its pieces would be copies of it, with the same bound, so
//! its bound is final. It can stay above `lower + τ` only for a tolerance under the
//! rounding margin (below); the refinement then ends unconverged when the other pieces
//! are done, instead of splitting copies of it until the budget is spent (69k faces
//! collapsed to a point, `τ = 1e-15`: 17.7M points, 25 s).
//! A midpoint only has to show
//! `d ≤ t = min(lower, lower + τ - R_child)`: its search stops as soon as it finds a
//! triangle closer than `t` and records `t` (a valid upper bound), otherwise it is exact.
//! With a threshold `θ` (is `h(A, B) <= θ`?), pieces settle at `θ` instead of
//! `lower + τ`, and the refinement stops as soon as `lower > θ`: the answer is then known.
//! When `h` is close below `θ` this refines deep; the query budget bounds it.
//! A level is evaluated against the `lower` of its start, so the result does not depend
//! on the thread count. Distances carry f64 rounding (relative ~1e-15): every upper bound
//! is raised by `2⁻⁴⁰ (h_B + bound)` (`h_B` the target's half extent) to cover it, so
//! tolerances below about `1e-12 h_B` cannot be reached.
//!
//! **Files**, imports running one way (`directed` -> `bound` -> `cell`; `directed` ->
//! `exact`, `statistics`, `options`): `options.rs` (what to compute), `exact.rs` (the
//! exact and max-only searches over the samples), `statistics.rs` (mean, RMS,
//! percentiles), `cell.rs` (the bound of one source triangle or piece, and its split),
//! `bound.rs` (the certified upper bound and its refinement) and `directed.rs` (the
//! one-sided distance, putting them together).

mod bound;
mod cell;
mod directed;
mod exact;
mod options;
mod statistics;

#[cfg(test)]
mod tests;

pub use bound::Bounds;
pub use directed::{Directed, SampleData, directed, directed_from_samples};
pub use options::{Options, RELATIVE_FLOOR};
pub use statistics::Statistics;
