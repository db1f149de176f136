//! One source triangle, or a piece of it, in the certified bound: the Lipschitz, convex
//! and split bounds on `d(·, B)` over it (see *Certified upper bound* in the
//! [module docs](super)), and its split at the edge midpoints.

use glam::DVec3;

use crate::bvh::{SearchStack, TriangleTree};
use crate::closest::PreparedTriangle;

/// Relative margin added to every upper bound for the f64 rounding of the distances
/// (`2⁻⁴⁰`, times the target's half extent plus the bound; dimensionless).
const ROUNDING_MARGIN: f64 = 1.0 / (1u64 << 40) as f64;

/// A source triangle (or a piece of one) in the refinement (target's frame): its corners,
/// upper bounds `d` on their distances (length), the target triangle slots found for them,
/// its covering radius `r` (length) and its certified bound `upper` (length).
#[derive(Debug, Clone, Copy)]
pub(super) struct Cell {
    pub(super) v: [DVec3; 3],
    pub(super) d: [f64; 3],
    pub(super) slot: [u32; 3],
    pub(super) r: f64,
    pub(super) upper: f64,
}

impl Cell {
    /// Whether the cell is one point (covering radius 0: a source triangle collapsed to a
    /// point). Its pieces would be copies of it, with the same bound: it is never split,
    /// its bound is final.
    pub(super) fn is_point(&self) -> bool {
        self.r == 0.0
    }

    /// `min(Lipschitz bound, convex bound)`; see the [module docs](super). The convex bound
    /// is skipped when the Lipschitz one is already within `settle` (length): the cell
    /// settles either way.
    pub(super) fn new(
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
pub(super) struct Probe {
    pub(super) point: DVec3,
    /// Upper bound on the distance (length): exact, or `t` after an early exit.
    pub(super) d: f64,
    /// Squared distance to the triangle found (length²).
    pub(super) d2: f64,
    pub(super) slot: u32,
    pub(super) exact: bool,
}

/// Splits a cell at its edge midpoints, evaluating each with early exit below
/// `t = min(lower, limit - r/2)`: a child whose corners are within `t` has a Lipschitz
/// bound within `limit`, the level at which a piece settles.
pub(super) fn split(
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

#[cfg(test)]
mod tests {
    use super::*;

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
}
