//! What [`directed`](super::directed) computes: samples, statistics, the certified bound
//! and its tolerance or threshold, the refinement budget.

use crate::error::MeshError;

/// The least tolerance a relative one becomes, relative to the target's half extent
/// (dimensionless): well above the rounding margin, so that it can be reached.
pub const RELATIVE_FLOOR: f64 = 1e-9;

/// What to compute; see the [module docs](super).
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

/// Refuses a tolerance (absolute or relative) that is not positive and finite.
pub(super) fn check_tolerance(opts: &Options) -> Result<(), MeshError> {
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
