//! Statistics of the sample distances: mean, RMS and percentiles (length).

use rayon::prelude::*;

use crate::reduce::deterministic_sum;

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

/// Linear-interpolation percentile of sorted values, `q` in `[0, 100]`.
#[must_use]
fn percentile(sorted: &[f64], q: f64) -> f64 {
    let h = (sorted.len() - 1) as f64 * q / 100.0;
    let lo = h.floor() as usize;
    let hi = (lo + 1).min(sorted.len() - 1);
    sorted[lo] + (h - lo as f64) * (sorted[hi] - sorted[lo])
}

/// Mean, RMS and percentiles of `distances` (length), the sums in fixed chunks (the same
/// for any thread count).
pub(super) fn statistics(distances: &[f64]) -> Statistics {
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
