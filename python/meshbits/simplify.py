"""Step 4 of the paper's algorithm (Sec. 7): reduce a mesh to about V vertices.

The default simplifier is fast-simplification (quadric edge collapse, Garland & Heckbert).
Any callable ``simplifier(vertices, faces, target_vertices) -> (vertices, faces)`` can be
plugged in instead; and :func:`closest_level` picks, among precomputed levels of detail,
the one whose vertex count is closest to the target.
"""

from __future__ import annotations

import math
import numbers
import threading
from collections.abc import Callable, Sequence

import numpy as np

from .errors import MeshbitsError
from .mesh import MeshLike, as_mesh

__all__ = [
    "MAX_FACES_PER_VERTEX",
    "Simplifier",
    "check_untangled",
    "closest_level",
    "referenced_vertex_count",
    "simplify",
]

#: ``simplifier(vertices (n, 3) float64, faces (m, 3) int, target_vertices) -> (vertices, faces)``
Simplifier = Callable[[np.ndarray, np.ndarray, int], tuple[np.ndarray, np.ndarray]]

#: Values of fast-simplification's ``agg`` tried in turn when a lower one stops short.
_ESCALATION = (3.0, 5.0, 7.0, 10.0)

#: Most faces per referenced vertex fast-simplification is given (an ordinary surface has
#: about 2). Its cost grows with the square of the faces around a vertex: Suzanne's faces
#: turned into polygons of 16 consecutive vertices and fan-triangulated (27 faces per
#: vertex) took 3 s in one call at agg = 10, polygons of 32 (57 per vertex) 30 s, and
#: ``meshbits.compress`` on polygons of 255 (483 per vertex) ran for over 10 minutes.
MAX_FACES_PER_VERTEX = 16

# fast-simplification keeps the mesh it works on in native globals: two calls must not
# overlap, so every call goes through this lock.
_FAST_SIMPLIFICATION_LOCK = threading.Lock()


def check_untangled(face_count: int, used: int, what: str) -> None:
    """Refuse more than :data:`MAX_FACES_PER_VERTEX` faces per referenced vertex."""
    ratio = face_count / max(used, 1)
    if ratio > MAX_FACES_PER_VERTEX:
        raise MeshbitsError(
            f"the mesh has {face_count:,} faces on {used:,} vertices, {ratio:.0f} per vertex "
            f"(a surface has about 2; at most {MAX_FACES_PER_VERTEX} are {what}): its "
            "triangles overlap so much that simplifying or measuring it would take minutes "
            "to hours. Remove repeated or overlapping faces first (polygons of many corners "
            "fan-triangulated?)"
        )


def referenced_vertex_count(faces: np.ndarray) -> int:
    """Number of distinct vertices that some face uses."""
    return int(np.unique(np.asarray(faces).ravel()).size)


def _compact(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    used, inverse = np.unique(faces.ravel(), return_inverse=True)
    return vertices[used], inverse.reshape(-1, 3).astype(np.int64)


def _fast_simplification(
    vertices: np.ndarray,
    faces: np.ndarray,
    target_faces: int,
    aggressiveness: float,
    preserve_border: bool,
) -> tuple[np.ndarray, np.ndarray]:
    import fast_simplification

    with _FAST_SIMPLIFICATION_LOCK:
        out_vertices, out_faces = fast_simplification.simplify(
            vertices,
            faces.astype(np.int64),
            target_count=int(target_faces),
            agg=aggressiveness,
            preserve_border=preserve_border,
        )
    return _compact(np.asarray(out_vertices, dtype=np.float64), np.asarray(out_faces))


def simplify(
    mesh: MeshLike,
    target_vertices: int,
    *,
    aggressiveness: float = 1.5,
    preserve_border: bool = True,
    rtol: float = 0.05,
) -> tuple[np.ndarray, np.ndarray]:
    """Simplify to about ``target_vertices`` referenced vertices with fast-simplification.

    ``aggressiveness`` is fast-simplification's ``agg``: lower is slower and closer to a
    true quadric-error ordering. Its default there is 7; 2 is used here because the
    Hausdorff error is what meshbits answers for: on the Stanford bunny halved to 30,000
    vertices, agg = 7 gave a maximum error of 2.6e-3 S and agg = 1.5 gave 3.3e-4 S
    (S = largest bounding-box side), in 0.1 s either way. ``preserve_border`` keeps the
    vertices of open borders, so that holes do not grow (bunny at 6,000 vertices, agg = 7:
    1.8e-2 S without it, 6.8e-3 S with it).

    fast-simplification takes a triangle count; the request uses the mesh's own
    triangles-per-vertex ratio. When a low ``aggressiveness`` stops short of the target
    (its sweeps run out), it is raised step by step (3, 5, 7, 10); when the result
    undershoots by more than ``rtol`` (relative), one corrected request follows.
    Unreferenced vertices are removed.

    Returns
    -------
    vertices : (n, 3) float64
    faces : (m, 3) int64
    """
    vertices, faces = as_mesh(mesh)
    if isinstance(target_vertices, bool) or not isinstance(target_vertices, numbers.Real):
        raise TypeError(f"target_vertices must be a number, got {target_vertices!r}")
    try:
        finite = math.isfinite(target_vertices)
    except OverflowError:  # an int beyond the float range
        finite = False
    if not finite:
        raise MeshbitsError(f"target_vertices must be finite, got {target_vertices}")
    target_vertices = int(target_vertices)
    if target_vertices < 4:
        raise MeshbitsError(f"target_vertices must be at least 4, got {target_vertices}")
    used = referenced_vertex_count(faces)
    if target_vertices >= used or len(faces) < 2:
        return _compact(vertices, faces.astype(np.int64))
    check_untangled(len(faces), used, "simplified")
    ratio = len(faces) / used

    def request(count: float) -> int:
        # fast-simplification refuses a target of all the faces or more.
        return int(min(max(4, round(count)), len(faces) - 1))

    target_faces = request(target_vertices * ratio)
    # fast-simplification stops after a fixed number of sweeps whose collapse threshold
    # grows like (sweep + 3) ** agg: a low agg may stop short of the target. Escalate.
    for agg in [aggressiveness, *(a for a in _ESCALATION if a > aggressiveness)]:
        out = _fast_simplification(vertices, faces, target_faces, agg, preserve_border)
        if len(out[0]) <= (1 + rtol) * target_vertices:
            break
    got = len(out[0])
    if 0 < got < (1 - rtol) * target_vertices:
        target_faces = request(target_faces * target_vertices / got)
        out = _fast_simplification(vertices, faces, target_faces, agg, preserve_border)
    return out


def closest_level(levels: Sequence[MeshLike], target_vertices: float) -> int:
    """Index of the level of detail whose referenced vertex count is closest to the target
    (on a log scale, so 1,000 is as far from 2,000 as from 500); ties go to the finer one."""
    if len(levels) == 0:
        raise MeshbitsError("lods is empty: give at least one level of detail")
    counts = np.array([referenced_vertex_count(as_mesh(level)[1]) for level in levels])
    distance = np.abs(np.log(counts) - np.log(max(float(target_vertices), 1.0)))
    best = np.flatnonzero(distance == distance.min())
    return int(best[np.argmax(counts[best])])
