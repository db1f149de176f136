"""Plain-numpy reference implementations, written independently of the Rust kernels.

They follow the specification (docs/model.md) with vectorised numpy, one formula at a
time, so that a disagreement points at a bug in one of the two. Also used by ``benches/``
as the "numpy" column.
"""

from __future__ import annotations

import numpy as np

FLAT_ANGLE = 1e-12
ILL_ANGLE = 1e-3
ILL_COCIRCULAR = 1e-3


def weld(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, int]:
    """Map each face corner to the first vertex with identical coordinates."""
    v = np.where(vertices == 0.0, 0.0, vertices)  # fold -0.0 onto 0.0
    _, first, inverse = np.unique(v, axis=0, return_index=True, return_inverse=True)
    canonical = first[inverse.ravel()]
    return canonical[faces], len(vertices) - len(first)


def circumsphere_radius(u: np.ndarray, v: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Radius of the sphere through 0, u, v, w (rows); inf where they are coplanar."""
    with np.errstate(divide="ignore", invalid="ignore"):
        det = np.einsum("ij,ij->i", u, np.cross(v, w))
        centre = (
            (u * u).sum(1)[:, None] * np.cross(v, w)
            + (v * v).sum(1)[:, None] * np.cross(w, u)
            + (w * w).sum(1)[:, None] * np.cross(u, v)
        ) / (2.0 * det[:, None])
        radius = np.linalg.norm(centre, axis=1)
    radius[~np.isfinite(radius) | (det == 0)] = np.inf
    return radius


def shape_complexity(
    vertices: np.ndarray,
    faces: np.ndarray,
    estimator: str = "circumsphere",
    merge_vertices: bool = True,
) -> dict[str, float | int]:
    """K_raw and edge counts of a mesh (paper Sec. 4.2), in numpy."""
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    merged = 0
    if merge_vertices:
        faces, merged = weld(vertices, faces)
    corners = vertices[faces]
    area = (
        0.5
        * np.linalg.norm(
            np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1
        ).sum()
    )
    if area == 0:
        raise ValueError("zero surface area")
    repeated = (
        (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 2] == faces[:, 0])
    )
    good = faces[~repeated]
    # Half-edge k of a face runs from corner k to corner k+1; its opposite corner is k+2.
    start = good.ravel()
    end = np.roll(good, -1, axis=1).ravel()
    opposite = np.roll(good, -2, axis=1).ravel()
    lo, hi = np.minimum(start, end), np.maximum(start, end)
    order = np.lexsort((hi, lo))
    lo, hi, opposite = lo[order], hi[order], opposite[order]
    new_edge = np.ones(len(lo), dtype=bool)
    new_edge[1:] = (lo[1:] != lo[:-1]) | (hi[1:] != hi[:-1])
    first = np.flatnonzero(new_edge)
    counts = np.diff(np.append(first, len(lo)))
    interior = first[counts == 2]

    a = vertices[lo[interior]]
    b = vertices[hi[interior]]
    c = vertices[opposite[interior]]
    d = vertices[opposite[interior + 1]]
    u, v, w = b - a, c - a, d - a
    n1, n2 = np.cross(u, v), np.cross(u, w)
    weight = (np.linalg.norm(n1, axis=1) + np.linalg.norm(n2, axis=1)) / 6.0
    length = np.linalg.norm(u, axis=1)
    bending = np.arctan2(np.linalg.norm(np.cross(n1, n2), axis=1), -np.einsum("ij,ij->i", n1, n2))
    degenerate = (
        (length == 0)
        | ~n1.any(axis=1)
        | ~n2.any(axis=1)
        | (opposite[interior] == opposite[interior + 1])
        | (c == d).all(axis=1)
    )
    flat = ~degenerate & (bending <= FLAT_ANGLE)
    radius = circumsphere_radius(u, v, w)
    with np.errstate(divide="ignore", invalid="ignore"):

        def circumcentre(p: np.ndarray, q: np.ndarray, n: np.ndarray) -> np.ndarray:
            return (
                (q * q).sum(1)[:, None] * np.cross(n, p) + (p * p).sum(1)[:, None] * np.cross(q, n)
            ) / (2.0 * (n * n).sum(1)[:, None])

        offset = np.linalg.norm(circumcentre(u, v, n1) - circumcentre(u, w, n2), axis=1)
    near_coplanar = np.minimum(bending, np.pi - bending) < ILL_ANGLE
    ill = ~degenerate & ~flat & near_coplanar & (offset < ILL_COCIRCULAR * length)
    curved = ~degenerate & ~flat & ~ill

    sphere_term = np.where(curved | ill, weight / radius, 0.0)
    dihedral_term = np.where(curved | ill, bending * length / 2.0, 0.0)
    if estimator == "circumsphere":
        term = sphere_term
    elif estimator == "dihedral":
        term = dihedral_term
    elif estimator == "hybrid":
        term = np.where(ill, dihedral_term, sphere_term)
    else:
        raise ValueError(estimator)
    used = np.unique(faces.ravel())
    extent = vertices[used].max(axis=0) - vertices[used].min(axis=0)
    k_raw = float(term.sum())
    return {
        "k_raw": k_raw,
        "k": k_raw / float(extent.max()),
        "k_area": k_raw / float(np.sqrt(area)),
        "area": float(area),
        "edges": len(first),
        "interior_edges": int((counts == 2).sum()),
        "boundary_edges": int((counts == 1).sum()),
        "nonmanifold_edges": int((counts > 2).sum()),
        "flat_edges": int(flat.sum()),
        "ill_conditioned_edges": int(ill.sum()),
        "degenerate_edges": int(degenerate.sum()),
        "merged_vertices": int(merged),
        "degenerate_faces": int(repeated.sum()),
    }
