"""Step 4 of the paper's algorithm (Sec. 7): reduce a mesh to about V vertices.

The default simplifier is fast-simplification (quadric edge collapse, Garland & Heckbert).
Any callable ``simplifier(vertices, faces, target_vertices) -> (vertices, faces)`` can be
plugged in instead; and :func:`closest_level` picks, among precomputed levels of detail,
the one whose vertex count is closest to the target.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence

import numpy as np

from .mesh import MeshLike, as_mesh

__all__ = ["Simplifier", "closest_level", "referenced_vertex_count", "simplify"]

#: ``simplifier(vertices (n, 3) float64, faces (m, 3) int, target_vertices) -> (vertices, faces)``
Simplifier = Callable[[np.ndarray, np.ndarray, int], tuple[np.ndarray, np.ndarray]]

# fast-simplification keeps the mesh it works on in native globals: two calls must not
# overlap, so every call goes through this lock.
_FAST_SIMPLIFICATION_LOCK = threading.Lock()


def referenced_vertex_count(faces: np.ndarray) -> int:
    """Number of distinct vertices that some face uses."""
    return int(np.unique(np.asarray(faces).ravel()).size)


def _compact(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    used, inverse = np.unique(faces.ravel(), return_inverse=True)
    return vertices[used], inverse.reshape(-1, 3).astype(np.int64)


def _fast_simplification(
    vertices: np.ndarray, faces: np.ndarray, target_faces: int, aggressiveness: float
) -> tuple[np.ndarray, np.ndarray]:
    import fast_simplification

    with _FAST_SIMPLIFICATION_LOCK:
        out_vertices, out_faces = fast_simplification.simplify(
            vertices, faces.astype(np.int64), target_count=int(target_faces), agg=aggressiveness
        )
    return _compact(np.asarray(out_vertices, dtype=np.float64), np.asarray(out_faces))


def simplify(
    mesh: MeshLike,
    target_vertices: int,
    *,
    aggressiveness: float = 7.0,
    rtol: float = 0.05,
) -> tuple[np.ndarray, np.ndarray]:
    """Simplify to about ``target_vertices`` referenced vertices with fast-simplification.

    fast-simplification takes a triangle count; the first request uses the mesh's own
    triangles-per-vertex ratio, and one corrected request follows when the result misses
    the target by more than ``rtol`` (relative). Unreferenced vertices are removed.

    Returns
    -------
    vertices : (n, 3) float64
    faces : (m, 3) int64
    """
    vertices, faces = as_mesh(mesh)
    target_vertices = int(target_vertices)
    if target_vertices < 4:
        raise ValueError(f"target_vertices must be at least 4, got {target_vertices}")
    used = referenced_vertex_count(faces)
    if target_vertices >= used:
        return _compact(vertices, faces.astype(np.int64))
    ratio = len(faces) / used
    target_faces = max(4, round(target_vertices * ratio))
    out = _fast_simplification(vertices, faces, target_faces, aggressiveness)
    got = len(out[0])
    if got > 0 and abs(got - target_vertices) > rtol * target_vertices:
        target_faces = max(4, round(target_faces * target_vertices / got))
        out = _fast_simplification(vertices, faces, target_faces, aggressiveness)
    return out


def closest_level(levels: Sequence[MeshLike], target_vertices: float) -> int:
    """Index of the level of detail whose referenced vertex count is closest to the target
    (on a log scale, so 1,000 is as far from 2,000 as from 500); ties go to the finer one."""
    if len(levels) == 0:
        raise ValueError("lods is empty: give at least one level of detail")
    counts = np.array([referenced_vertex_count(as_mesh(level)[1]) for level in levels])
    distance = np.abs(np.log(counts) - np.log(max(float(target_vertices), 1.0)))
    best = np.flatnonzero(distance == distance.min())
    return int(best[np.argmax(counts[best])])
