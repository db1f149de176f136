//! The nearest-triangle search: nearest-first branch and bound from the root or from a
//! hint's subtree, ties to the smallest face index, with an optional early exit (see
//! *Search*, *Ties* and *Early exit* in the [module docs](super)).

use glam::DVec3;

use super::tree::{IDENTICAL, RUN, TriangleTree};

/// Levels above the hint's leaf where a hinted search starts before climbing to the root
/// (a subtree of up to `2^(RESTART_LEVELS + 1)` triangles; 2, 4, 6 and 9 measured alike).
const RESTART_LEVELS: usize = 6;

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

impl TriangleTree {
    /// A stack sized for this tree.
    #[must_use]
    pub fn stack(&self) -> SearchStack {
        SearchStack(Vec::with_capacity(self.depth + 1))
    }

    /// Tests the triangles of the leaf `first`, `count` (flags included: only the first of
    /// identical ones; a run's one face for `p`), keeping the best.
    #[inline(always)]
    fn test_leaf(&self, p: DVec3, first: u32, count: u32, best: &mut Nearest) {
        if count & RUN != 0 {
            return self.test_slot(p, first, best);
        }
        let tested = if count & IDENTICAL != 0 { 1 } else { count };
        for slot in first..first + tested {
            self.test_triangle(p, slot, best);
        }
    }

    /// Tests the triangle in `slot` or, when a run holds it, the run's face for `p` (so a
    /// hint inside a run answers as the run does).
    #[inline(always)]
    fn test_slot(&self, p: DVec3, slot: u32, best: &mut Nearest) {
        match self.run_holding(slot) {
            Some(run) => self.test_triangle(p, run.slot_for(p), best),
            None => self.test_triangle(p, slot, best),
        }
    }

    /// Tests the triangle in `slot`, keeping the smaller `(d², face)`.
    #[inline(always)]
    fn test_triangle(&self, p: DVec3, slot: u32, best: &mut Nearest) {
        #[cfg(test)]
        counters::count_tested(1);
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
            self.test_slot(p, hint, &mut best);
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
            counters::count_pair();
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
}

/// Triangles tested and pairs visited by this thread's searches: the tests bound them.
#[cfg(test)]
pub(super) mod counters {
    use std::cell::Cell;

    thread_local! {
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
    pub(in crate::bvh) fn counted<T>(f: impl FnOnce() -> T) -> (T, u64, u64) {
        let (t0, p0) = (TESTED.with(Cell::get), PAIRS.with(Cell::get));
        let out = f();
        let (t1, p1) = (TESTED.with(Cell::get), PAIRS.with(Cell::get));
        (out, t1 - t0, p1 - p0)
    }
}
