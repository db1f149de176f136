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
