"""Tolerances and defaults, in one documented place.

Every threshold here is dimensionless unless stated otherwise.
"""

from __future__ import annotations

#: Bending angle (radians) at or below which an edge counts as flat: the sphere through
#: its four vertices is a plane (infinite radius) and the edge adds nothing to K.
FLAT_ANGLE = 1e-12

#: An edge whose bending angle is within ``ILL_ANGLE`` radians of 0 or pi *and* whose two
#: triangles' circumcentres lie within ``ILL_COCIRCULAR`` times the edge length of each
#: other is ill-conditioned: its four vertices are nearly coplanar and nearly co-circular,
#: so the circumsphere radius is 0/0. float32 rounding of a mesh with a million faces
#: perturbs these quantities by about 1e-4; 1e-3 keeps such noise out of K under the
#: "hybrid" estimator.
ILL_ANGLE = 1e-3
ILL_COCIRCULAR = 1e-3

#: Estimators of the per-edge term p(e)/r(e) of K.
ESTIMATORS = ("circumsphere", "dihedral", "hybrid")

#: Default area samples per face of each mesh for the sampled Hausdorff distance (Metro's
#: default density), clamped to [HAUSDORFF_MIN_SAMPLES, HAUSDORFF_MAX_SAMPLES]. Every
#: referenced vertex is sampled in addition.
HAUSDORFF_SAMPLES_PER_FACE = 10
HAUSDORFF_MIN_SAMPLES = 10_000
HAUSDORFF_MAX_SAMPLES = 1_000_000

#: Largest number of extra point queries the refinement of the certified upper bound may
#: spend per direction before it stops and reports ``converged=False``.
HAUSDORFF_REFINE_BUDGET = 20_000_000
