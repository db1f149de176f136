"""Shape complexity K (King & Rossignac 1999, Sec. 4, Eq. 8)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from . import _core
from .constants import ESTIMATORS, FLAT_ANGLE, ILL_ANGLE, ILL_COCIRCULAR
from .errors import MeshbitsError
from .mesh import MeshLike, as_mesh
from .results import ArrayResult

__all__ = ["EDGE_KINDS", "ShapeComplexity", "shape_complexity"]

#: Names of the codes in :attr:`ShapeComplexity.edge_kind`.
EDGE_KINDS = ("curved", "flat", "ill_conditioned", "boundary", "nonmanifold", "degenerate")


@dataclass(frozen=True, eq=False)
class ShapeComplexity(ArrayResult):
    """K of one mesh, its normalisations, and what the estimate skipped.

    Attributes
    ----------
    k : float
        ``K_raw / S`` with ``S`` = :attr:`grid_size`: the paper's Eq. 8 on the quantization
        grid (dimensionless; a sphere gives ``2 pi``). This is the K the bit-allocation
        formulas take.
    k_area : float
        ``K_raw / sqrt(area)`` (dimensionless; a sphere gives ``sqrt(4 pi) = 3.545``): the
        convention of the paper's Table 1, where models are scaled to equal area.
    k_raw : float
        ``sum_e p(e) / r(e)`` over interior edges, in the mesh's length unit.
    grid_size : float
        ``S``, the largest side of the bounding box of the referenced vertices (length).
    area : float
        Total surface area of all faces (length squared).
    estimator : str
        ``"circumsphere"``, ``"dihedral"`` or ``"hybrid"``.
    edges, interior_edges, boundary_edges, nonmanifold_edges : int
        Unique edges; those with exactly two, one, and three or more incident faces.
        Boundary and non-manifold edges are skipped (they contribute 0).
    flat_edges : int
        Interior edges whose two triangles are coplanar (infinite radius, contribute 0).
    ill_conditioned_edges : int
        Interior edges whose four vertices are nearly coplanar and nearly co-circular
        (see :func:`shape_complexity`).
    degenerate_edges : int
        Interior edges next to a zero-area triangle, of zero length, or whose triangles
        share their third vertex; they contribute 0.
    merged_vertices : int
        Vertices welded onto an identical earlier vertex (``merge_vertices=True``).
    degenerate_faces : int
        Faces that repeat a vertex index (after welding); left out of the edge table.
    edge_vertices, edge_kind, edge_radius, edge_weight, edge_contribution : ndarray or None
        With ``per_edge=True``: per unique edge, the vertex pair ``(E, 2) uint32``, the
        class code ``(E,) uint8`` (names in :data:`EDGE_KINDS`), the circumsphere radius
        ``r(e)`` (length; ``inf`` when flat, NaN when not interior), the weight ``p(e)``
        (area; NaN when not interior) and the estimator's term ``p(e)/r(e)`` (length).
    """

    k: float
    k_area: float
    k_raw: float
    grid_size: float
    area: float
    estimator: str
    edges: int
    interior_edges: int
    boundary_edges: int
    nonmanifold_edges: int
    flat_edges: int
    ill_conditioned_edges: int
    degenerate_edges: int
    merged_vertices: int
    degenerate_faces: int
    edge_vertices: np.ndarray | None = field(default=None, repr=False)
    edge_kind: np.ndarray | None = field(default=None, repr=False)
    edge_radius: np.ndarray | None = field(default=None, repr=False)
    edge_weight: np.ndarray | None = field(default=None, repr=False)
    edge_contribution: np.ndarray | None = field(default=None, repr=False)

    _arrays = ("edge_vertices", "edge_kind", "edge_radius", "edge_weight", "edge_contribution")


def shape_complexity(
    mesh_or_vertices: MeshLike,
    faces: Any = None,
    *,
    estimator: str = "circumsphere",
    merge_vertices: bool = True,
    per_edge: bool = False,
) -> ShapeComplexity:
    """Shape complexity K of a triangle mesh (paper Sec. 4.2, Eq. 8).

    For each interior edge ``e = (a, b)`` with triangles ``(a, b, c)`` and ``(b, a, d)``,
    ``r(e)`` is the radius of the sphere through ``a, b, c, d`` and ``p(e)`` a third of the
    two triangles' areas; ``K_raw = sum p(e) / r(e)`` approximates ``integral dA / r``.

    Parameters
    ----------
    mesh_or_vertices
        A ``trimesh.Trimesh``, a ``(vertices, faces)`` pair, or ``(n, 3)`` float vertices.
    faces
        ``(m, 3)`` integer vertex indices when ``mesh_or_vertices`` is an array.
    estimator
        ``"circumsphere"``: the paper's sphere (default). ``"dihedral"``: per edge
        ``phi * |e| / 2`` with ``phi`` the bending angle (pi minus the dihedral angle); the
        sum is the integral of mean curvature, which is exactly ``integral dA / r`` on a
        sphere. ``"hybrid"``: circumsphere, but the dihedral value on ill-conditioned
        edges.
    merge_vertices
        Weld vertices with identical coordinates first (triangle soups such as STL files
        have no shared vertices: without welding every edge is a boundary and K is 0).
    per_edge
        Also return per-edge arrays (vertex pair, class, radius, weight, term).

    Notes
    -----
    An interior edge is **flat** when its bending angle is at most
    :data:`meshbits.constants.FLAT_ANGLE`; it contributes 0. It is **ill-conditioned**
    when it is nearly coplanar (bending angle within
    :data:`~meshbits.constants.ILL_ANGLE` of 0 or pi) *and* nearly co-circular (the
    circumcentres of its two triangles lie within
    :data:`~meshbits.constants.ILL_COCIRCULAR` times the edge length of each other). The
    sphere through such four points is 0/0: a square split in two with 1e-9 noise gets
    ``r`` of the order of its side, so a flat region reads as curved. ``"circumsphere"``
    keeps that value (as the paper does) and counts the edge; ``"hybrid"`` replaces it by
    the dihedral value, which is about 0 there.

    Boundary edges (one face) and non-manifold edges (three or more faces) are skipped
    and counted; faces that repeat a vertex index are left out and counted; zero-area
    triangles make their edges degenerate (counted, contribute 0). Unreferenced vertices
    are ignored, also for the bounding box.

    Raises
    ------
    ValueError
        Bad shapes, NaN or infinite coordinates, out-of-range indices, an empty mesh, or a
        mesh whose faces all have zero area (:class:`meshbits.MeshbitsError`).
    TypeError
        Non-numeric vertices or non-integer faces.
    """
    if estimator not in ESTIMATORS:
        raise MeshbitsError(f"estimator must be one of {ESTIMATORS}, got {estimator!r}")
    for name, flag in (("merge_vertices", merge_vertices), ("per_edge", per_edge)):
        if not isinstance(flag, (bool, np.bool_)):
            raise TypeError(f"{name} must be True or False, got {flag!r}")
    # The kernel reads int64 faces as they are, checks the indices and refuses NaN or
    # infinite coordinates in its own passes; a refused mesh is checked again here for a
    # message naming the row.
    vertices, triangles = as_mesh(mesh_or_vertices, faces, keep_int64=True, check_finite=False)
    try:
        raw: dict[str, Any] = dict(
            _core.shape_complexity(
                vertices,
                triangles,
                estimator,
                bool(merge_vertices),
                bool(per_edge),
                FLAT_ANGLE,
                ILL_ANGLE,
                ILL_COCIRCULAR,
            )
        )
    except MeshbitsError:
        as_mesh(mesh_or_vertices, faces)
        raise
    grid_size = float(np.max(np.subtract(raw.pop("bbox_max"), raw.pop("bbox_min"))))
    k_raw = raw.pop("k_raw")
    return ShapeComplexity(
        k=k_raw / grid_size,
        k_area=k_raw / math.sqrt(raw["area"]),
        k_raw=k_raw,
        grid_size=grid_size,
        estimator=estimator,
        **raw,
    )
