//! The sampled one-sided Hausdorff distance, with a certified upper bound.
//!
//! The one-sided distance from a source surface `A` to a target surface `B` is
//! `h(A, B) = max over p in A of d(p, B)`, `d(p, B) = min over q in B of |p - q|`
//! (length); the Hausdorff distance of King & Rossignac (1999, Sec. 3.2) is
//! `H(A, B) = max(h(A, B), h(B, A))`. Here `A` is replaced by its sample set
//! ([`crate::sampling`]): every referenced vertex plus `N` seeded area samples. Each
//! sample's `d(p, B)` is the exact f64 minimum over `B`'s triangles ([`crate::bvh`]).
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
//!   ([`covering_radius`]), every point of `T` is within `R_T` of a corner, so
//!   `max over T of d(·, B) ≤ max(d₀, d₁, d₂) + R_T`.
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

use std::sync::atomic::{AtomicU64, Ordering};

use glam::DVec3;
use rayon::prelude::*;

use crate::bvh::{SearchStack, TriangleTree, coherent_order};
use crate::closest::{PreparedTriangle, covering_radius};
use crate::error::{MAX_EXTENT, MeshError, check_finite, check_indices};
use crate::reduce::deterministic_sum;
use crate::sampling::{SurfaceSamples, local_corners, surface_samples};

/// Samples per parallel work unit; a unit runs sequentially, in Morton order, each search
/// starting from the previous sample's nearest triangle.
const SAMPLE_CHUNK: usize = 1024;

/// Relative margin added to every upper bound for the f64 rounding of the distances
/// (`2⁻⁴⁰`, times the target's half extent plus the bound; dimensionless).
const ROUNDING_MARGIN: f64 = 1.0 / (1u64 << 40) as f64;

/// The least tolerance a relative one becomes, relative to the target's half extent
/// (dimensionless): well above the rounding margin, so that it can be reached.
pub const RELATIVE_FLOOR: f64 = 1e-9;

/// Cells per parallel work unit during refinement.
const CELL_CHUNK: usize = 256;

/// What to compute; see the module docs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Options {
    /// Area samples `N` (the referenced vertices are always sampled too).
    pub area_samples: usize,
    pub seed: u64,
    /// Every sample's exact distance (mean, RMS, percentiles) rather than the maximum only.
    pub statistics: bool,
    /// Compute the certified upper bound.
    pub bounds: bool,
    /// Refine until `upper - lower <= tolerance` (length); implies `bounds`.
    pub tolerance: Option<f64>,
    /// Without `tolerance`: refine until `upper - lower <= relative_tolerance * lower`
    /// (dimensionless, `lower` the sampled maximum when the refinement starts; at least
    /// [`RELATIVE_FLOOR`] times the target's half extent, reachable even when `lower` is
    /// 0); implies `bounds`.
    pub relative_tolerance: Option<f64>,
    /// With a tolerance, the question is only whether `h(A, B) <= threshold` (length): a
    /// piece settles once its bound is `<= threshold` (instead of `lower + tolerance`),
    /// and the refinement stops once the lower bound exceeds it.
    pub threshold: Option<f64>,
    /// Largest number of extra point queries the refinement may spend.
    pub refine_budget: usize,
    /// Return every sample with its distance, and the per-vertex distances.
    pub return_samples: bool,
}

/// Statistics of the sample distances (length).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Statistics {
    pub mean: f64,
    pub rms: f64,
    /// 50th, 95th and 99th percentiles, linear interpolation between order statistics (as
    /// numpy's default).
    pub p50: f64,
    pub p95: f64,
    pub p99: f64,
}

/// The certified interval.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bounds {
    /// Upper bound on `h(A, B)` (length).
    pub upper: f64,
    /// Refinement points evaluated (in addition to the samples).
    pub refined_points: usize,
    /// Triangles split during refinement.
    pub refined_cells: usize,
    /// `Some(true)` when `upper - lower <= tolerance` was reached or, with a threshold,
    /// the bounds decided it (`upper <= threshold`, or `lower > threshold`); `Some(false)`
    /// when the budget ran out first; `None` without a tolerance.
    pub converged: Option<bool>,
}

/// Per-sample output.
#[derive(Debug, Clone, PartialEq)]
pub struct SampleData {
    /// Sample points, caller's frame (length).
    pub points: Vec<[f64; 3]>,
    /// Face of the source each sample lies on (`u32::MAX` for vertex samples).
    pub faces: Vec<u32>,
    /// Exact distance of each sample (length).
    pub distances: Vec<f64>,
    /// Distance of each source vertex (length); NaN for unreferenced vertices.
    pub vertex_distances: Vec<f64>,
}

/// The one-sided distance from a source mesh to a target tree.
#[derive(Debug, Clone, PartialEq)]
pub struct Directed {
    pub n_samples: usize,
    pub n_vertex_samples: usize,
    /// Largest exact distance found at any evaluated point (samples, and refinement points
    /// with a tolerance): a lower bound on `h(A, B)` (length).
    pub max: f64,
    /// The point achieving `max` (caller's frame), its closest point on the target, and
    /// the target face holding it.
    pub argmax: [f64; 3],
    pub argmax_closest: [f64; 3],
    pub argmax_face: u32,
    pub statistics: Option<Statistics>,
    pub bounds: Option<Bounds>,
    pub samples: Option<SampleData>,
}

/// The best exact distance so far: `(d², sample index)`, ties to the smaller index.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Best {
    d2: f64,
    index: usize,
}

impl Best {
    const NONE: Best = Best {
        d2: f64::NEG_INFINITY,
        index: usize::MAX,
    };

    #[inline]
    fn offer(&mut self, d2: f64, index: usize) {
        if d2 > self.d2 || (d2 == self.d2 && index < self.index) {
            *self = Best { d2, index };
        }
    }

    #[inline]
    fn merge(self, other: Best) -> Best {
        let mut out = self;
        out.offer(other.d2, other.index);
        out
    }
}

/// Exact squared distance of every point, in parallel, searched in [`coherent_order`];
/// also returns each point's nearest triangle slot (the hint for later searches).
fn exact_distances(tree: &TriangleTree, points: &[DVec3]) -> (Vec<f64>, Vec<u32>) {
    let (order, hits) = tree.search_coherent(points, SAMPLE_CHUNK, 0.0, |hit| (hit.d2, hit.slot));
    let mut d2 = vec![0.0; points.len()];
    let mut slots = vec![0u32; points.len()];
    for (&i, &(d, slot)) in order.iter().zip(&hits) {
        (d2[i as usize], slots[i as usize]) = (d, slot);
    }
    (d2, slots)
}

/// One pass over `points` in [`coherent_order`]: the points from `first_exact` on are
/// searched exactly (their squared distances are returned, in order), the others max-only
/// against the running maximum of every exact distance found so far. Returns the best
/// exact distance of all.
fn exact_beyond(tree: &TriangleTree, points: &[DVec3], first_exact: usize) -> (Vec<f64>, Best) {
    let running = AtomicU64::new(0.0_f64.to_bits());
    let parts: Vec<(Vec<(u32, f64)>, Best)> = coherent_order(points)
        .par_chunks(SAMPLE_CHUNK)
        .map(|chunk| {
            let mut stack = tree.stack();
            let mut hint = u32::MAX;
            let mut best = Best::NONE;
            let mut exact = Vec::with_capacity(chunk.len());
            for &i in chunk {
                let full = i as usize >= first_exact;
                let threshold = if full {
                    0.0
                } else {
                    f64::from_bits(running.load(Ordering::Relaxed))
                };
                let Some(hit) = tree.nearest_local(points[i as usize], hint, threshold, &mut stack)
                else {
                    continue;
                };
                hint = hit.slot;
                if full {
                    exact.push((i, hit.d2));
                }
                if hit.d2 >= threshold {
                    best.offer(hit.d2, i as usize);
                    running.fetch_max(hit.d2.to_bits(), Ordering::Relaxed);
                }
            }
            (exact, best)
        })
        .collect();
    let mut d2 = vec![0.0; points.len() - first_exact];
    let mut best = Best::NONE;
    for (exact, part) in parts {
        for (i, d) in exact {
            d2[i as usize - first_exact] = d;
        }
        best = best.merge(part);
    }
    (d2, best)
}

/// The largest of `d2` as a [`Best`], sample indices offset by `first`.
fn best_of(d2: &[f64], first: usize) -> Best {
    d2.par_iter()
        .enumerate()
        .map(|(i, &d2)| Best {
            d2,
            index: first + i,
        })
        .reduce(|| Best::NONE, Best::merge)
}

/// Max-only pass over `points` (sample indices offset by `first`), searched in
/// [`coherent_order`]: returns the best exact distance among them, given a running
/// maximum `start_d2` already known.
fn max_only(tree: &TriangleTree, points: &[DVec3], first: usize, start_d2: f64) -> Best {
    let running = AtomicU64::new(start_d2.max(0.0).to_bits());
    coherent_order(points)
        .par_chunks(SAMPLE_CHUNK)
        .map(|chunk| {
            let mut stack = tree.stack();
            let mut hint = u32::MAX;
            let mut best = Best::NONE;
            for &i in chunk {
                // Non-negative f64 order like their bit patterns.
                let threshold = f64::from_bits(running.load(Ordering::Relaxed));
                let Some(hit) = tree.nearest_local(points[i as usize], hint, threshold, &mut stack)
                else {
                    continue;
                };
                hint = hit.slot;
                if hit.d2 >= threshold {
                    // The search ran to completion: exact.
                    best.offer(hit.d2, first + i as usize);
                    if hit.d2 > threshold {
                        running.fetch_max(hit.d2.to_bits(), Ordering::Relaxed);
                    }
                }
            }
            best
        })
        .reduce(|| Best::NONE, Best::merge)
}

/// Linear-interpolation percentile of sorted values, `q` in `[0, 100]`.
#[must_use]
fn percentile(sorted: &[f64], q: f64) -> f64 {
    let h = (sorted.len() - 1) as f64 * q / 100.0;
    let lo = h.floor() as usize;
    let hi = (lo + 1).min(sorted.len() - 1);
    sorted[lo] + (h - lo as f64) * (sorted[hi] - sorted[lo])
}

fn statistics(distances: &[f64]) -> Statistics {
    let n = distances.len() as f64;
    let squares: Vec<f64> = distances.par_iter().map(|d| d * d).collect();
    let mut sorted = distances.to_vec();
    sorted.par_sort_unstable_by(f64::total_cmp);
    Statistics {
        mean: deterministic_sum(distances) / n,
        rms: (deterministic_sum(&squares) / n).sqrt(),
        p50: percentile(&sorted, 50.0),
        p95: percentile(&sorted, 95.0),
        p99: percentile(&sorted, 99.0),
    }
}

/// A source triangle (or a piece of one) in the refinement (target's frame): its corners,
/// upper bounds `d` on their distances (length), the target triangle slots found for them,
/// its covering radius `r` (length) and its certified bound `upper` (length).
#[derive(Debug, Clone, Copy)]
struct Cell {
    v: [DVec3; 3],
    d: [f64; 3],
    slot: [u32; 3],
    r: f64,
    upper: f64,
}

impl Cell {
    /// Whether the cell is one point (covering radius 0: a source triangle collapsed to a
    /// point). Its pieces would be copies of it, with the same bound: it is never split,
    /// its bound is final.
    fn is_point(&self) -> bool {
        self.r == 0.0
    }

    /// `min(Lipschitz bound, convex bound)`; see the module docs. The convex bound is
    /// skipped when the Lipschitz one is already within `settle` (length): the cell
    /// settles either way.
    fn new(
        tree: &TriangleTree,
        v: [DVec3; 3],
        d: [f64; 3],
        slot: [u32; 3],
        r: f64,
        settle: f64,
    ) -> Cell {
        let lipschitz = d[0].max(d[1]).max(d[2]) + r;
        let margin = |upper: f64| upper + ROUNDING_MARGIN * (tree.half_extent() + upper);
        if margin(lipschitz) <= settle {
            return Cell {
                v,
                d,
                slot,
                r,
                upper: margin(lipschitz),
            };
        }
        let mut convex2 = f64::INFINITY;
        for (k, &s) in slot.iter().enumerate() {
            if slot[..k].contains(&s) {
                continue;
            }
            let t = tree.triangle(s);
            let worst = v.iter().map(|&p| t.closest(p).1).fold(0.0, f64::max);
            convex2 = convex2.min(worst);
        }
        if margin(convex2.sqrt()) > settle {
            for (i, j) in [(0, 1), (1, 2), (0, 2)] {
                if slot[i] != slot[j]
                    && let Some(worst) =
                        split_bound(&v, tree.triangle(slot[i]), tree.triangle(slot[j]))
                {
                    convex2 = convex2.min(worst);
                }
            }
        }
        let upper = lipschitz.min(convex2.sqrt());
        Cell {
            v,
            d,
            slot,
            r,
            upper: margin(upper),
        }
    }
}

/// The *split* bound (squared, length²) of a cell `v` against two target triangles that
/// share an edge: `max over the cell of d(·, B)²`, at most `max(d(·, t_i)², d(·, t_j)²)`
/// taken part by part. The plane through the shared edge, perpendicular to the
/// triangles' mean plane, cuts the cell into two convex pieces; on `t_i`'s side
/// `d(·, B) ≤ d(·, t_i)`, a convex function, whose maximum over the piece is at one of its
/// vertices (cell corners on that side and the points where the cell's edges cross the
/// plane), and the same on `t_j`'s side. It holds for any plane; through the shared edge,
/// a cell that straddles the edge of two nearly coplanar triangles gets about its height
/// above them, where each triangle alone bounds it by its reach beyond the edge. None when
/// the triangles share no edge.
fn split_bound(v: &[DVec3; 3], ti: &PreparedTriangle, tj: &PreparedTriangle) -> Option<f64> {
    let (ci, cj) = (ti.corners(), tj.corners());
    // Corners are recomputed as `a + ab`: equal up to rounding of the coordinates.
    let tolerance =
        1e-20 * (ti.a.length_squared() + ti.ab.length_squared() + ti.ac.length_squared());
    let mut shared = [DVec3::ZERO; 2];
    let mut count = 0;
    let mut third = None;
    for &a in &ci {
        if cj.iter().any(|&b| (a - b).length_squared() <= tolerance) {
            if count < 2 {
                shared[count] = a;
            }
            count += 1;
        } else {
            third = Some(a);
        }
    }
    let third = third?;
    if count != 2 {
        return None;
    }
    let (ni, nj) = (ti.ab.cross(ti.ac), tj.ab.cross(tj.ac));
    let nj = if ni.dot(nj) < 0.0 { -nj } else { nj };
    let normal = (shared[1] - shared[0]).cross(ni.normalize_or_zero() + nj.normalize_or_zero());
    if normal.length_squared() == 0.0 {
        return None;
    }
    let orient = if (third - shared[0]).dot(normal) >= 0.0 {
        1.0
    } else {
        -1.0
    };
    let side = v.map(|p| orient * (p - shared[0]).dot(normal));
    let mut worst = 0.0_f64;
    for k in 0..3 {
        if side[k] >= 0.0 {
            worst = worst.max(ti.closest(v[k]).1);
        }
        if side[k] <= 0.0 {
            worst = worst.max(tj.closest(v[k]).1);
        }
    }
    for (a, b) in [(0, 1), (1, 2), (2, 0)] {
        if (side[a] > 0.0 && side[b] < 0.0) || (side[a] < 0.0 && side[b] > 0.0) {
            let cut = v[a] + (v[b] - v[a]) * (side[a] / (side[a] - side[b]));
            worst = worst.max(ti.closest(cut).1).max(tj.closest(cut).1);
        }
    }
    Some(worst)
}

/// A refinement point's outcome: the recorded upper bound on its distance and the target
/// triangle found for it; `exact` when the search ran to completion.
#[derive(Debug, Clone, Copy)]
struct Probe {
    point: DVec3,
    /// Upper bound on the distance (length): exact, or `t` after an early exit.
    d: f64,
    /// Squared distance to the triangle found (length²).
    d2: f64,
    slot: u32,
    exact: bool,
}

/// What one work unit of a refinement level leaves: the children still above the settling
/// level, the largest bound among those that settled (length), and the largest exact
/// distance among its midpoints with the point.
struct LevelPart {
    unsettled: Vec<Cell>,
    settled: f64,
    best: Best,
    point: DVec3,
}

/// Splits a cell at its edge midpoints, evaluating each with early exit below
/// `t = min(lower, limit - r/2)`: a child whose corners are within `t` has a Lipschitz
/// bound within `limit`, the level at which a piece settles.
fn split(
    tree: &TriangleTree,
    cell: &Cell,
    lower: f64,
    limit: f64,
    stack: &mut SearchStack,
) -> ([Cell; 4], [Probe; 3]) {
    let r = cell.r * 0.5;
    let t = lower.min(limit - r);
    let stop = if t > 0.0 { t * t } else { 0.0 };
    let [a, b, c] = cell.v;
    let mut hint = cell.slot[0];
    let mut probe = |p: DVec3| {
        let hit = tree
            .nearest_local(p, hint, stop, stack)
            .expect("tree is not empty");
        hint = hit.slot;
        let exact = hit.d2 >= stop;
        Probe {
            point: p,
            d: if exact { hit.d2.sqrt() } else { t },
            d2: hit.d2,
            slot: hit.slot,
            exact,
        }
    };
    let (m0, m1, m2) = (
        probe((a + b) * 0.5),
        probe((b + c) * 0.5),
        probe((c + a) * 0.5),
    );
    let [da, db, dc] = cell.d;
    let [sa, sb, sc] = cell.slot;
    let child = |v, d, slot| Cell::new(tree, v, d, slot, r, limit);
    let cells = [
        child(
            [a, m0.point, m2.point],
            [da, m0.d, m2.d],
            [sa, m0.slot, m2.slot],
        ),
        child(
            [m0.point, b, m1.point],
            [m0.d, db, m1.d],
            [m0.slot, sb, m1.slot],
        ),
        child(
            [m2.point, m1.point, c],
            [m2.d, m1.d, dc],
            [m2.slot, m1.slot, sc],
        ),
        child(
            [m0.point, m1.point, m2.point],
            [m0.d, m1.d, m2.d],
            [m0.slot, m1.slot, m2.slot],
        ),
    ];
    (cells, [m0, m1, m2])
}

/// The one-sided sampled distance from the source mesh to `tree`. See the module docs.
pub fn directed(
    vertices: &[[f64; 3]],
    faces: &[[u32; 3]],
    tree: &TriangleTree,
    opts: &Options,
) -> Result<Directed, MeshError> {
    if faces.is_empty() || vertices.is_empty() {
        return Err(MeshError::Empty("the source mesh has no faces".into()));
    }
    if tree.is_empty() {
        return Err(MeshError::Empty("the target mesh has no faces".into()));
    }
    check_finite(vertices)?;
    check_indices(faces, vertices.len())?;
    check_tolerance(opts)?;
    let samples = surface_samples(vertices, faces, tree.centre(), opts.area_samples, opts.seed)?;
    directed_from_samples(vertices, faces, &samples, tree, opts)
}

fn check_tolerance(opts: &Options) -> Result<(), MeshError> {
    for (name, value) in [
        ("tolerance", opts.tolerance),
        ("relative_tolerance", opts.relative_tolerance),
    ] {
        if let Some(tol) = value
            && !(tol > 0.0 && tol.is_finite())
        {
            return Err(MeshError::Parameter(format!(
                "{name} must be positive and finite, got {tol}"
            )));
        }
    }
    Ok(())
}

/// [`directed`] with the source's samples given (drawn with [`surface_samples`] from
/// `vertices` and `faces`, in any frame): a mesh measured against several targets is
/// sampled once. `opts.area_samples` and `opts.seed` are not used.
pub fn directed_from_samples(
    vertices: &[[f64; 3]],
    faces: &[[u32; 3]],
    samples: &SurfaceSamples,
    tree: &TriangleTree,
    opts: &Options,
) -> Result<Directed, MeshError> {
    if tree.is_empty() {
        return Err(MeshError::Empty("the target mesh has no faces".into()));
    }
    check_tolerance(opts)?;
    if samples.offsets.len() != faces.len() + 1 {
        return Err(MeshError::Parameter(format!(
            "the samples were drawn from a mesh of {} faces, not {}",
            samples.offsets.len().saturating_sub(1),
            faces.len()
        )));
    }
    let centre = tree.centre();
    let recentred;
    let samples = if samples.centre == centre {
        samples
    } else {
        recentred = samples.recentred(centre);
        &recentred
    };
    let points = &samples.points;
    if let Some((_, far)) = tree.beyond_reach(&points[..samples.vertex_count()]) {
        return Err(MeshError::Parameter(format!(
            "a vertex of one mesh lies {far:.3e} (length) from the centre of the other: more \
             than the supported {MAX_EXTENT:.0e}"
        )));
    }
    let nv = samples.vertex_count();
    let bounds_wanted =
        opts.bounds || opts.tolerance.is_some() || opts.relative_tolerance.is_some();
    // Exact distances where needed: every sample (return_samples); the vertices (bounds);
    // the area samples (statistics, which describe the surface: area samples only). The
    // rest only has to show it cannot raise the maximum.
    let na = points.len() - nv;
    let vertices_exact = opts.return_samples || bounds_wanted || (opts.statistics && na == 0);
    let area_exact = opts.return_samples || opts.statistics;
    let (exact_d2, vertex_slots, mut best) = match (vertices_exact, area_exact) {
        (true, true) => {
            let (d2, slots) = exact_distances(tree, points);
            let best = best_of(&d2, 0);
            (d2, slots, best)
        }
        (true, false) => {
            let (d2, slots) = exact_distances(tree, &points[..nv]);
            let vbest = best_of(&d2, 0);
            let rest = max_only(tree, &points[nv..], nv, vbest.d2.max(0.0));
            (d2, slots, vbest.merge(rest))
        }
        (false, true) => {
            let (d2, best) = exact_beyond(tree, points, nv);
            (d2, Vec::new(), best)
        }
        (false, false) => (Vec::new(), Vec::new(), max_only(tree, points, 0, 0.0)),
    };
    let mut argmax_point = points[best.index];

    // Per-vertex distances (NaN: unreferenced), from the exact vertex samples.
    let vertex_distances = vertices_exact.then(|| {
        let mut out = vec![f64::NAN; vertices.len()];
        for (k, &v) in samples.vertex_ids.iter().enumerate() {
            out[v as usize] = exact_d2[k].sqrt();
        }
        out
    });

    let mut bounds = None;
    if bounds_wanted {
        let vd = vertex_distances
            .as_ref()
            .expect("vertex distances are exact with bounds");
        let mut slot_of = vec![u32::MAX; vertices.len()];
        for (k, &v) in samples.vertex_ids.iter().enumerate() {
            slot_of[v as usize] = vertex_slots[k];
        }
        let level0 = |f: &[u32; 3], settle: f64| {
            let v = local_corners(vertices, *f, centre);
            let (d, slot) = (f.map(|i| vd[i as usize]), f.map(|i| slot_of[i as usize]));
            Cell::new(tree, v, d, slot, covering_radius(v[0], v[1], v[2]), settle)
        };
        let mut lower = best.d2.sqrt();
        let settle_at = |lower: f64, tol: f64| opts.threshold.unwrap_or(lower + tol);
        let (mut refined_points, mut refined_cells, mut converged) = (0, 0, None);
        let mut settled = 0.0_f64;
        let tolerance = opts.tolerance.or_else(|| {
            opts.relative_tolerance
                .map(|r| (r * lower).max(RELATIVE_FLOOR * tree.half_extent()))
        });
        if let Some(tol) = tolerance {
            let start = settle_at(lower, tol);
            let mut active: Vec<Cell> = faces.par_iter().map(|f| level0(f, start)).collect();
            let mut next_index = points.len();
            // The largest bound of the unsettled cells of one point (see `Cell::is_point`).
            let mut stuck = f64::NEG_INFINITY;
            loop {
                let limit = settle_at(lower, tol);
                settled = active
                    .par_iter()
                    .map(|c| c.upper)
                    .filter(|&u| u <= limit)
                    .reduce(|| settled, f64::max);
                stuck = active
                    .par_iter()
                    .filter(|c| c.upper > limit && c.is_point())
                    .map(|c| c.upper)
                    .reduce(|| stuck, f64::max);
                settled = settled.max(stuck);
                active = active
                    .into_par_iter()
                    .filter(|c| c.upper > limit && !c.is_point())
                    .collect();
                let decided = opts.threshold.is_some_and(|t| lower > t);
                if active.is_empty() || decided {
                    converged = Some(decided || stuck <= limit);
                    settled = active
                        .par_iter()
                        .map(|c| c.upper)
                        .reduce(|| settled, f64::max);
                    break;
                }
                if refined_points + 3 * active.len() > opts.refine_budget {
                    converged = Some(false);
                    settled = active
                        .par_iter()
                        .map(|c| c.upper)
                        .reduce(|| settled, f64::max);
                    break;
                }
                // Split every active cell; children that settle leave at once (only their
                // bound is kept), the others form the next level.
                let parts: Vec<LevelPart> = active
                    .par_chunks(CELL_CHUNK)
                    .enumerate()
                    .map(|(chunk, cells)| {
                        let mut stack = tree.stack();
                        let mut part = LevelPart {
                            unsettled: Vec::new(),
                            settled: f64::NEG_INFINITY,
                            best: Best::NONE,
                            point: DVec3::ZERO,
                        };
                        let first = next_index + 3 * chunk * CELL_CHUNK;
                        for (k, c) in cells.iter().enumerate() {
                            let (children, probes) = split(tree, c, lower, limit, &mut stack);
                            for child in children {
                                if child.upper <= limit {
                                    part.settled = part.settled.max(child.upper);
                                } else {
                                    part.unsettled.push(child);
                                }
                            }
                            for (j, p) in probes.iter().enumerate() {
                                let index = first + 3 * k + j;
                                let candidate = Best { d2: p.d2, index };
                                if p.exact && part.best.merge(candidate) == candidate {
                                    part.best = candidate;
                                    part.point = p.point;
                                }
                            }
                        }
                        part
                    })
                    .collect();
                refined_cells += active.len();
                refined_points += 3 * active.len();
                next_index += 3 * active.len();
                let mut unsettled =
                    Vec::with_capacity(parts.iter().map(|p| p.unsettled.len()).sum());
                for part in parts {
                    settled = settled.max(part.settled);
                    if best.merge(part.best) != best {
                        best = part.best;
                        argmax_point = part.point;
                    }
                    unsettled.extend(part.unsettled);
                }
                lower = best.d2.sqrt();
                active = unsettled;
            }
        } else {
            settled = faces
                .par_iter()
                .map(|f| level0(f, f64::NEG_INFINITY).upper)
                .reduce(|| 0.0, f64::max);
        }
        bounds = Some(Bounds {
            upper: settled.max(lower),
            refined_points,
            refined_cells,
            converged,
        });
    }

    // The closest point of the maximum, searched again in full (deterministic tie-break).
    let hit = tree
        .nearest_local(argmax_point, u32::MAX, 0.0, &mut tree.stack())
        .expect("tree is not empty");
    debug_assert_eq!(hit.d2, best.d2);
    let statistics = opts.statistics.then(|| {
        // The area samples' distances (the vertices' when there are none); `exact_d2`
        // starts at the area samples unless the vertices were measured exactly too.
        let first = if vertices_exact && na > 0 { nv } else { 0 };
        let d: Vec<f64> = exact_d2[first..].par_iter().map(|d2| d2.sqrt()).collect();
        statistics(&d)
    });
    let sample_data = opts.return_samples.then(|| SampleData {
        points: points
            .par_iter()
            .map(|p| (*p + centre).to_array())
            .collect(),
        faces: samples.faces(),
        distances: exact_d2.par_iter().map(|d2| d2.sqrt()).collect(),
        vertex_distances: vertex_distances.clone().unwrap_or_default(),
    });
    Ok(Directed {
        n_samples: points.len(),
        n_vertex_samples: nv,
        max: best.d2.sqrt(),
        argmax: (argmax_point + centre).to_array(),
        argmax_closest: (hit.point + centre).to_array(),
        argmax_face: hit.face,
        statistics,
        bounds,
        samples: sample_data,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn options() -> Options {
        Options {
            area_samples: 2000,
            seed: 1,
            statistics: true,
            bounds: true,
            tolerance: None,
            relative_tolerance: None,
            threshold: None,
            refine_budget: 1_000_000,
            return_samples: false,
        }
    }

    /// A unit square in the plane `z`, split into `2 n²` triangles.
    fn square(n: u32, z: f64) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
        crate::test_meshes::grid(n, |_, _| z)
    }

    #[test]
    fn parallel_squares_at_distance_d() {
        let (va, fa) = square(4, 0.0);
        let (vb, fb) = square(7, 0.3);
        let tree = TriangleTree::build(&vb, &fb).unwrap();
        for opts in [
            options(),
            Options {
                statistics: false,
                ..options()
            },
        ] {
            let r = directed(&va, &fa, &tree, &opts).unwrap();
            assert!((r.max - 0.3).abs() < 1e-12, "{}", r.max);
            assert!(r.bounds.unwrap().upper >= 0.3 - 1e-12);
            let refined = directed(
                &va,
                &fa,
                &tree,
                &Options {
                    tolerance: Some(1e-6),
                    ..opts
                },
            )
            .unwrap();
            let b = refined.bounds.unwrap();
            assert_eq!(b.converged, Some(true));
            assert!((b.upper - 0.3).abs() <= 1e-6, "{}", b.upper);
        }
        let s = directed(&va, &fa, &tree, &options())
            .unwrap()
            .statistics
            .unwrap();
        for x in [s.mean, s.rms, s.p50, s.p95, s.p99] {
            assert!((x - 0.3).abs() < 1e-12);
        }
    }

    /// A flat square (vertices, faces) and the tree of the same square with its centre
    /// vertex raised by 0.2 (a cone).
    fn flat_and_bump() -> (Vec<[f64; 3]>, Vec<[u32; 3]>, TriangleTree) {
        let (vb, fb) = square(2, 0.0);
        let (mut va, fa) = square(2, 0.0);
        va[4][2] = 0.2;
        (vb, fb, TriangleTree::build(&va, &fa).unwrap())
    }

    #[test]
    fn bump_refines_to_the_tolerance() {
        // h(flat, bump): the flat centre (0.5, 0.5, 0) against the raised cone.
        let (vb, fb, ta) = flat_and_bump();
        let opts = Options {
            area_samples: 50,
            statistics: false,
            tolerance: Some(1e-4),
            ..options()
        };
        let r = directed(&vb, &fb, &ta, &opts).unwrap();
        let b = r.bounds.unwrap();
        assert_eq!(b.converged, Some(true));
        assert!(b.upper - r.max <= 1e-4 + 1e-15, "{} {}", b.upper, r.max);
        let (d, _, _) = ta.query(&[[0.5, 0.5, 0.0]]).unwrap();
        let truth = d[0];
        assert!(
            r.max <= truth + 1e-12 && truth <= b.upper + 1e-12,
            "{} {} {}",
            r.max,
            truth,
            b.upper
        );
    }

    /// A relative tolerance refines to that fraction of the sampled maximum; on identical
    /// meshes (maximum 0) it still ends, at the floor.
    #[test]
    fn a_relative_tolerance_refines_to_a_fraction_of_the_maximum() {
        let (vb, fb, ta) = flat_and_bump();
        let opts = Options {
            area_samples: 50,
            statistics: false,
            relative_tolerance: Some(0.01),
            ..options()
        };
        let r = directed(&vb, &fb, &ta, &opts).unwrap();
        let b = r.bounds.unwrap();
        assert_eq!(b.converged, Some(true));
        assert!(b.upper - r.max <= 0.01 * r.max, "{} {}", b.upper, r.max);
        assert!(b.refined_points > 0);
        let tb = TriangleTree::build(&vb, &fb).unwrap();
        let same = directed(&vb, &fb, &tb, &opts).unwrap();
        assert_eq!(same.max, 0.0);
        let b = same.bounds.unwrap();
        assert_eq!(b.converged, Some(true));
        assert!(b.upper <= RELATIVE_FLOOR * tb.half_extent(), "{}", b.upper);
        let bad = Options {
            relative_tolerance: Some(-1.0),
            ..opts
        };
        assert!(directed(&vb, &fb, &ta, &bad).is_err());
    }

    #[test]
    fn a_threshold_decides_with_less_refinement() {
        // h(flat, bump) is the distance of the flat centre to the cone, about 0.14.
        let (vb, fb, ta) = flat_and_bump();
        let base = Options {
            area_samples: 50,
            statistics: false,
            tolerance: Some(1e-6),
            ..options()
        };
        let tight = directed(&vb, &fb, &ta, &base).unwrap();
        let truth = tight.max;
        for threshold in [truth * 1.2, truth * 0.8] {
            let r = directed(
                &vb,
                &fb,
                &ta,
                &Options {
                    threshold: Some(threshold),
                    ..base
                },
            )
            .unwrap();
            let b = r.bounds.unwrap();
            assert_eq!(b.converged, Some(true));
            assert!(r.max <= truth + 1e-12 && truth <= b.upper + 1e-12);
            if threshold > truth {
                assert!(b.upper <= threshold, "{} > {threshold}", b.upper);
            } else {
                assert!(r.max > threshold, "{} <= {threshold}", r.max);
            }
            assert!(
                b.refined_points < tight.bounds.unwrap().refined_points,
                "{} {}",
                b.refined_points,
                tight.bounds.unwrap().refined_points
            );
        }
    }

    #[test]
    fn samples_drawn_once_measure_every_target() {
        let (va, fa) = square(9, 0.0);
        let mut targets = Vec::new();
        for shift in [0.1, 0.7, -0.4] {
            let (mut vb, fb) = square(5, 0.2);
            for (i, p) in vb.iter_mut().enumerate() {
                p[0] += shift;
                p[2] += 0.05 * ((i * 7919) % 13) as f64 / 13.0;
            }
            targets.push(TriangleTree::build(&vb, &fb).unwrap());
        }
        let opts = Options {
            tolerance: Some(1e-4),
            ..options()
        };
        let samples = surface_samples(&va, &fa, DVec3::new(3.0, -1.0, 0.5), 2000, 1).unwrap();
        for tree in &targets {
            let fresh = directed(&va, &fa, tree, &opts).unwrap();
            let reused = directed_from_samples(&va, &fa, &samples, tree, &opts).unwrap();
            assert!(
                (fresh.max - reused.max).abs() <= 1e-14,
                "{} {}",
                fresh.max,
                reused.max
            );
            let (fu, ru) = (fresh.bounds.unwrap().upper, reused.bounds.unwrap().upper);
            assert!((fu - ru).abs() <= 1e-14, "{fu} {ru}");
            assert_eq!(fresh.n_samples, reused.n_samples);
        }
        let other = surface_samples(&va, &fa[1..], DVec3::ZERO, 100, 1).unwrap();
        assert!(directed_from_samples(&va, &fa, &other, &targets[0], &opts).is_err());
    }

    /// The split bound is never below the true maximum over the cell of the distance to
    /// the two triangles (a dense barycentric grid of the cell, brute force), and on a
    /// cell straddling the shared edge of two coplanar triangles it is the cell's height.
    #[test]
    fn split_bound_holds_and_is_tight_over_a_flat_edge() {
        use crate::closest::closest_point_on_triangle;
        use crate::sampling::SplitMix64;
        let mut rng = SplitMix64::new(7);
        let mut next = || rng.next_f64() - 0.5;
        let mut checked = 0;
        for _ in 0..300 {
            let p = |n: &mut dyn FnMut() -> f64| DVec3::new(n(), n(), n());
            let (a, b) = (p(&mut next), p(&mut next));
            let (c, d) = (p(&mut next), p(&mut next));
            let (ti, tj) = (
                PreparedTriangle::new(a, b, c),
                PreparedTriangle::new(b, a, d),
            );
            let cell = [p(&mut next), p(&mut next), p(&mut next)];
            let Some(bound) = split_bound(&cell, &ti, &tj) else {
                continue;
            };
            checked += 1;
            let n = 24;
            for i in 0..=n {
                for j in 0..=n - i {
                    let (u, w) = (f64::from(i) / f64::from(n), f64::from(j) / f64::from(n));
                    let q = cell[0] * (1.0 - u - w) + cell[1] * u + cell[2] * w;
                    let d2 = closest_point_on_triangle(q, a, b, c)
                        .1
                        .min(closest_point_on_triangle(q, b, a, d).1);
                    assert!(d2 <= bound * (1.0 + 1e-12) + 1e-15, "{d2} > {bound}");
                }
            }
        }
        assert!(checked > 250, "{checked}");
        // Two coplanar triangles (a square split on its diagonal) and a cell 0.01 above
        // that crosses the diagonal: each triangle alone bounds it by its reach beyond
        // the diagonal, the split bound by its height.
        let (a, b) = (DVec3::new(0.0, 0.0, 0.0), DVec3::new(1.0, 1.0, 0.0));
        let (c, d) = (DVec3::new(1.0, 0.0, 0.0), DVec3::new(0.0, 1.0, 0.0));
        let (ti, tj) = (
            PreparedTriangle::new(a, b, c),
            PreparedTriangle::new(b, a, d),
        );
        let h = 0.01;
        let cell = [
            DVec3::new(0.2, 0.6, h),
            DVec3::new(0.6, 0.2, h),
            DVec3::new(0.7, 0.8, h),
        ];
        let bound = split_bound(&cell, &ti, &tj).expect("they share an edge");
        assert!((bound.sqrt() - h).abs() < 1e-12, "{}", bound.sqrt());
        let alone = cell.iter().map(|&q| ti.closest(q).1).fold(0.0, f64::max);
        assert!(alone.sqrt() > 0.1, "{}", alone.sqrt());
    }

    /// A source collapsed to one point: its cells are points, never split. A reachable
    /// tolerance settles them at once; one under the rounding margin ends unconverged
    /// without refining (it split copies of the point until the budget ran out).
    #[test]
    fn cells_of_one_point_are_never_split() {
        let (vb, fb) = square(5, 0.0);
        let tree = TriangleTree::build(&vb, &fb).unwrap();
        let (_, fa) = square(9, 0.0);
        let va = vec![[0.3, 0.4, 0.25]; 100];
        for (tolerance, converged) in [(1e-6, true), (1e-18, false)] {
            let opts = Options {
                tolerance: Some(tolerance),
                ..options()
            };
            let r = directed(&va, &fa, &tree, &opts).unwrap();
            let b = r.bounds.unwrap();
            assert_eq!(b.converged, Some(converged), "tolerance {tolerance}");
            assert_eq!((b.refined_points, b.refined_cells), (0, 0));
            assert!((r.max - 0.25).abs() < 1e-15, "{}", r.max);
            assert!(b.upper >= r.max && b.upper - r.max < 1e-12, "{}", b.upper);
        }
    }

    #[test]
    fn max_only_agrees_with_full_statistics() {
        let (va, fa) = square(9, 0.0);
        let (mut vb, fb) = square(5, 0.0);
        for (i, p) in vb.iter_mut().enumerate() {
            p[2] = 0.05 * ((i * 7919) % 13) as f64 / 13.0;
        }
        let tree = TriangleTree::build(&vb, &fb).unwrap();
        let full = directed(
            &va,
            &fa,
            &tree,
            &Options {
                bounds: false,
                ..options()
            },
        )
        .unwrap();
        let fast = directed(
            &va,
            &fa,
            &tree,
            &Options {
                bounds: false,
                statistics: false,
                ..options()
            },
        )
        .unwrap();
        assert_eq!(full.max, fast.max);
        assert_eq!(full.argmax, fast.argmax);
        assert_eq!(full.argmax_closest, fast.argmax_closest);
        assert!(fast.statistics.is_none());
    }

    /// The statistics describe the area samples; the vertices, searched max-only, still
    /// give the maximum when it lies at one of them (here a spike vertex).
    #[test]
    fn statistics_are_the_area_samples_and_a_vertex_can_hold_the_maximum() {
        let (mut va, fa) = square(9, 0.0);
        va[37][2] = 0.3;
        let (mut vb, fb) = square(5, 0.0);
        for (i, p) in vb.iter_mut().enumerate() {
            p[2] = 0.05 * ((i * 7919) % 13) as f64 / 13.0;
        }
        let tree = TriangleTree::build(&vb, &fb).unwrap();
        let stats_only = Options {
            bounds: false,
            ..options()
        };
        let with_samples = Options {
            return_samples: true,
            ..stats_only
        };
        let fast = directed(&va, &fa, &tree, &stats_only).unwrap();
        let all = directed(&va, &fa, &tree, &with_samples).unwrap();
        let data = all.samples.as_ref().unwrap();
        let nv = all.n_vertex_samples;
        assert_eq!(nv, va.len());
        let brute: Vec<f64> = data
            .points
            .iter()
            .map(|&p| {
                let q = DVec3::from(p) - tree.centre();
                fb.iter()
                    .map(|f| {
                        let [a, b, c] = f.map(|i| DVec3::from(vb[i as usize]) - tree.centre());
                        crate::closest::closest_point_on_triangle(q, a, b, c).1
                    })
                    .fold(f64::INFINITY, f64::min)
                    .sqrt()
            })
            .collect();
        let argmax = (0..brute.len()).fold(0, |b, i| if brute[i] > brute[b] { i } else { b });
        assert!(argmax < nv, "the spike vertex holds the maximum");
        assert_eq!(fast.max, all.max);
        assert_eq!(fast.argmax, data.points[argmax]);
        assert!((fast.max - brute[argmax]).abs() < 1e-12);
        let area: Vec<f64> = data.distances[nv..].to_vec();
        assert_eq!(fast.statistics, Some(statistics(&area)));
        let mean = area.iter().sum::<f64>() / area.len() as f64;
        let got = fast.statistics.unwrap();
        assert!((got.mean - mean).abs() < 1e-12);
        let with_vertices = data.distances.iter().sum::<f64>() / data.distances.len() as f64;
        assert!(
            (got.mean - with_vertices).abs() > 1e-6,
            "the vertices are left out"
        );
    }
}
