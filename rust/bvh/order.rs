//! A Morton (Z-order) processing order for queries: consecutive queries are close, so
//! each search starts from the previous answer and finds the tree's nodes in cache.

use glam::DVec3;
use rayon::prelude::*;

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
