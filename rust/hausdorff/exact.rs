//! The searches over the samples: exact distances where they are needed, max-only
//! searches against a shared running maximum elsewhere (see *Exact and max-only
//! searches* in the [module docs](super)).

use std::sync::atomic::{AtomicU64, Ordering};

use glam::DVec3;
use rayon::prelude::*;

use crate::bvh::{TriangleTree, coherent_order};

/// Samples per parallel work unit; a unit runs sequentially, in Morton order, each search
/// starting from the previous sample's nearest triangle.
const SAMPLE_CHUNK: usize = 1024;

/// The best exact distance so far: `(d², sample index)`, ties to the smaller index.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Best {
    pub(super) d2: f64,
    pub(super) index: usize,
}

impl Best {
    pub(super) const NONE: Best = Best {
        d2: f64::NEG_INFINITY,
        index: usize::MAX,
    };

    #[inline]
    pub(super) fn offer(&mut self, d2: f64, index: usize) {
        if d2 > self.d2 || (d2 == self.d2 && index < self.index) {
            *self = Best { d2, index };
        }
    }

    #[inline]
    pub(super) fn merge(self, other: Best) -> Best {
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

/// The searches the options ask for over `points` (the `nv` vertex samples first, then the
/// area samples): exact where `vertices_exact` / `area_exact`, max-only elsewhere. Returns
/// the exact squared distances (length², in sample order: all samples, the vertex samples,
/// or the area samples), the nearest target slots of the vertex samples when they are
/// exact, and the best exact distance of all.
pub(super) fn measure(
    tree: &TriangleTree,
    points: &[DVec3],
    nv: usize,
    vertices_exact: bool,
    area_exact: bool,
) -> (Vec<f64>, Vec<u32>, Best) {
    match (vertices_exact, area_exact) {
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
    }
}
