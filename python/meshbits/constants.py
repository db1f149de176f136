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

# --- The bit-allocation model (meshbits.model) ---------------------------------------

#: Smallest sphere-equivalent vertex count ``V_S = 4 pi V / K`` at which the sphere model
#: of the tessellation error (paper Eq. 10, 11) is trusted: there ``theta = 1.10`` rad. A
#: plan below it is returned with ``in_model_domain = False``.
MODEL_MIN_SPHERE_VERTICES = 12.0

#: Fewest vertices of a closed triangle mesh (a tetrahedron). A size budget that cannot
#: hold this many vertices at :data:`MODEL_MIN_BITS` bits per coordinate is refused; a
#: plan with fewer (continuous) vertices is flagged out of the model's domain.
MODEL_MIN_VERTICES = 4.0

#: Fewest bits per coordinate (bits) any plan uses: one bit puts each coordinate on
#: one of two grid planes.
MODEL_MIN_BITS = 1.0

#: The paper's printed constant ``B0`` of Eq. 13-15 (bits). The value derived from the
#: paper's own definitions is ``log2(4.5 ln 2) = 1.6412`` (``meshbits.model.DERIVED_B0``).
PAPER_B0 = 1.838

#: Size model (paper Eq. 1) fitted to Draco at compression level 7:
#: ``F = (3 * alpha * B + T) * V`` with T constrained to be >= 0. Measured by
#: ``benches/calibrate_draco.py`` on spot, bunny, horse, hand and fandisk simplified to
#: 500, 2,000 and 8,000 vertices at B = 6..16 (90 encodings): alpha = 0.595, T = 0
#: (the unconstrained fit wants T < 0), relative RMS misfit 36%. ``compress`` corrects the
#: misfit by measuring; ``meshbits calibrate`` fits a mesh of your own.
DRACO_ALPHA = 0.595
DRACO_CONNECTIVITY_BITS = 0.0
#: Default area samples per face of each mesh for the sampled Hausdorff distance (Metro's
#: default density), clamped to [HAUSDORFF_MIN_SAMPLES, HAUSDORFF_MAX_SAMPLES]. Every
#: referenced vertex is sampled in addition.
HAUSDORFF_SAMPLES_PER_FACE = 10
HAUSDORFF_MIN_SAMPLES = 10_000
HAUSDORFF_MAX_SAMPLES = 1_000_000

#: Largest number of extra point queries the refinement of the certified upper bound may
#: spend per direction before it stops and reports ``converged=False``.
HAUSDORFF_REFINE_BUDGET = 20_000_000
#: ``meshbits hausdorff --bounds`` without ``--tolerance``: each direction's certified
#: upper bound is refined to within this fraction of its sampled maximum.
BOUNDS_RELATIVE_TOLERANCE = 0.01
#: The same for the error of ``compress``'s answer to a size or vertex budget: looser, as
#: a result whose error is quantization's, spread evenly over the surface, refines nearly
#: everywhere (the fandisk at 16 kB: 63.6 s at 1%, on a shared machine).
ANSWER_RELATIVE_TOLERANCE = 0.05
#: Quantization grids: ``"cube"``, one step ``S / (2^B - 1)`` on every axis with ``S`` the
#: largest box side (the paper, Draco, gltfpack); ``"axes"``, a step per axis.
GRIDS = ("cube", "axes")

#: Code conventions: ``"corner"``, codes in ``[0, 2^B - 1]`` (paper Sec. 1.1);
#: ``"centered"``, codes in ``[-2^(B-1) + 1, 2^(B-1)]`` (paper Sec. 8), same grid.
CONVENTIONS = ("corner", "centered")

#: Which repeated faces clustering drops: none, same corners in the same cyclic order,
#: or same corner set in any order.
DUPLICATES = ("keep", "oriented", "any")

#: Bits per coordinate accepted by the quantizer (codes are 32-bit integers).
MIN_BITS, MAX_BITS = 1, 32

#: Largest bits per coordinate each output format holds: Draco quantizes positions to at
#: most 30 bits; KHR_mesh_quantization stores positions as (unsigned) shorts at most; the
#: quantized PLY stores float32, whose 24-bit significand cannot hold a finer grid.
FORMAT_MAX_BITS = {"draco": 30, "glb": 16, "ply": 24}

#: With ``certify`` (the default of ``compress`` and ``compress_scene``), the refinement
#: tolerance of a certified upper bound on the Hausdorff distance, as a fraction of the
#: error budget; the bound of an answer is refined until it decides the budget (within it,
#: or a point beyond it found), the tolerance then only sets where a bound with no
#: threshold would stop.
CERTIFY_TOLERANCE = 0.05

#: The shape complexity a mesh is planned with when its K is 0 (grid-normalised,
#: dimensionless): a flat mesh, or one whose every edge is skipped (a single triangle).
#: The model then plans the fewest vertices the budget allows, and the search measures
#: from there, as for any mesh.
FLAT_K = 1e-6
