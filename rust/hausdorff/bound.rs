//! The certified upper bound on `h(A, B)`: the largest bound of the source triangles
//! ([`Cell`]), refined level by level, with a tolerance or a threshold, until every piece
//! settles or the query budget is spent (see *Certified upper bound* in the
//! [module docs](super)).

use glam::DVec3;
use rayon::prelude::*;

use super::cell::{Cell, split};
use super::exact::Best;
use super::options::{Options, RELATIVE_FLOOR};
use crate::bvh::TriangleTree;
use crate::closest::covering_radius;
use crate::sampling::local_corners;

/// Cells per parallel work unit during refinement.
const CELL_CHUNK: usize = 256;

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

/// The source mesh as the bound starts from it: its triangles in the target tree's frame,
/// with each vertex's exact distance (length) and the target triangle slot found for it.
pub(super) struct Source<'a> {
    vertices: &'a [[f64; 3]],
    faces: &'a [[u32; 3]],
    /// The tree's centre, subtracted from the source's coordinates.
    centre: DVec3,
    /// Per source vertex, its exact distance (NaN: unreferenced).
    distances: &'a [f64],
    /// Per source vertex, the target triangle slot of its nearest point (`u32::MAX`:
    /// unreferenced).
    slots: Vec<u32>,
}

impl<'a> Source<'a> {
    /// The source mesh, with the exact distance of each vertex (`distances`) and, for each
    /// vertex sample (`vertex_ids`, in sample order), the target slot found for it.
    pub(super) fn new(
        vertices: &'a [[f64; 3]],
        faces: &'a [[u32; 3]],
        centre: DVec3,
        distances: &'a [f64],
        vertex_ids: &[u32],
        vertex_slots: &[u32],
    ) -> Self {
        let mut slots = vec![u32::MAX; vertices.len()];
        for (k, &v) in vertex_ids.iter().enumerate() {
            slots[v as usize] = vertex_slots[k];
        }
        Source {
            vertices,
            faces,
            centre,
            distances,
            slots,
        }
    }

    /// The cell of source face `f` (level 0 of the refinement), settling at `settle`.
    fn cell(&self, tree: &TriangleTree, f: &[u32; 3], settle: f64) -> Cell {
        let v = local_corners(self.vertices, *f, self.centre);
        let (d, slot) = (
            f.map(|i| self.distances[i as usize]),
            f.map(|i| self.slots[i as usize]),
        );
        Cell::new(tree, v, d, slot, covering_radius(v[0], v[1], v[2]), settle)
    }
}

/// The largest exact distance found so far (`best`, sample indices; refinement points are
/// numbered after the samples) and the point achieving it (the tree's frame).
pub(super) struct Lower {
    pub(super) best: Best,
    pub(super) point: DVec3,
}

/// The certified interval of the source against `tree`. Without a tolerance (absolute or
/// relative, `opts`), the largest bound of the source's triangles; with one, refined
/// ([`refine`]), the refinement points numbered from `first_index` and `lower` raised by
/// those that are farther.
pub(super) fn certify(
    tree: &TriangleTree,
    source: &Source<'_>,
    opts: &Options,
    lower: &mut Lower,
    first_index: usize,
) -> Bounds {
    let start = lower.best.d2.sqrt();
    let tolerance = opts.tolerance.or_else(|| {
        opts.relative_tolerance
            .map(|r| (r * start).max(RELATIVE_FLOOR * tree.half_extent()))
    });
    match tolerance {
        Some(tol) => refine(tree, source, opts, tol, lower, first_index),
        None => {
            let settled = source
                .faces
                .par_iter()
                .map(|f| source.cell(tree, f, f64::NEG_INFINITY).upper)
                .reduce(|| 0.0, f64::max);
            Bounds {
                upper: settled.max(start),
                refined_points: 0,
                refined_cells: 0,
                converged: None,
            }
        }
    }
}

/// The refinement to tolerance `tol` (length): level by level, every cell whose bound is
/// above the settling level (`lower + tol`, or the threshold) is split and its midpoints
/// evaluated, until none is left, the threshold is decided, or the next level would pass
/// the query budget. A level is evaluated against the `lower` of its start, so the result
/// does not depend on the thread count.
fn refine(
    tree: &TriangleTree,
    source: &Source<'_>,
    opts: &Options,
    tol: f64,
    lower: &mut Lower,
    first_index: usize,
) -> Bounds {
    let settle_at = |lower: f64| opts.threshold.unwrap_or(lower + tol);
    let mut lower_d = lower.best.d2.sqrt();
    let start = settle_at(lower_d);
    let mut active: Vec<Cell> = source
        .faces
        .par_iter()
        .map(|f| source.cell(tree, f, start))
        .collect();
    let (mut refined_points, mut refined_cells) = (0, 0);
    let mut next_index = first_index;
    let mut settled = 0.0_f64;
    // The largest bound of the unsettled cells of one point (see `Cell::is_point`).
    let mut stuck = f64::NEG_INFINITY;
    let converged = loop {
        let limit = settle_at(lower_d);
        active = settle_level(active, limit, &mut settled, &mut stuck);
        let decided = opts.threshold.is_some_and(|t| lower_d > t);
        if active.is_empty() || decided {
            break decided || stuck <= limit;
        }
        if refined_points + 3 * active.len() > opts.refine_budget {
            break false;
        }
        let parts = split_level(tree, &active, lower_d, limit, next_index);
        refined_cells += active.len();
        refined_points += 3 * active.len();
        next_index += 3 * active.len();
        let mut unsettled = Vec::with_capacity(parts.iter().map(|p| p.unsettled.len()).sum());
        for part in parts {
            settled = settled.max(part.settled);
            if lower.best.merge(part.best) != lower.best {
                lower.best = part.best;
                lower.point = part.point;
            }
            unsettled.extend(part.unsettled);
        }
        lower_d = lower.best.d2.sqrt();
        active = unsettled;
    };
    // The cells left unsettled (the threshold decided, or the budget ran out) bound too.
    let settled = active
        .par_iter()
        .map(|c| c.upper)
        .reduce(|| settled, f64::max);
    Bounds {
        upper: settled.max(lower_d),
        refined_points,
        refined_cells,
        converged: Some(converged),
    }
}

/// Sorts a level's cells at the settling level `limit` (length): the largest bound of
/// those at or below it goes into `settled`; cells of one point above it are never split
/// (their bound is final), the largest of their bounds goes into `stuck` and `settled`;
/// returns the others, to be split.
fn settle_level(active: Vec<Cell>, limit: f64, settled: &mut f64, stuck: &mut f64) -> Vec<Cell> {
    let (before, stuck_before) = (*settled, *stuck);
    *settled = active
        .par_iter()
        .map(|c| c.upper)
        .filter(|&u| u <= limit)
        .reduce(|| before, f64::max);
    *stuck = active
        .par_iter()
        .filter(|c| c.upper > limit && c.is_point())
        .map(|c| c.upper)
        .reduce(|| stuck_before, f64::max);
    *settled = settled.max(*stuck);
    active
        .into_par_iter()
        .filter(|c| c.upper > limit && !c.is_point())
        .collect()
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

/// Splits every cell of `active` ([`split`]) in parallel units of [`CELL_CHUNK`] cells;
/// children that settle at `limit` leave at once (only their bound is kept), the others
/// form the next level. The midpoints of the cells are numbered from `next_index`, three
/// per cell in order.
fn split_level(
    tree: &TriangleTree,
    active: &[Cell],
    lower: f64,
    limit: f64,
    next_index: usize,
) -> Vec<LevelPart> {
    active
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
        .collect()
}
