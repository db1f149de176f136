"""Step 4 of the paper's algorithm (Sec. 7): reduce a mesh to fewer vertices.

Two simplifiers, both quadric edge collapse (Garland & Heckbert 1997):

- ``"meshopt"`` (default): meshoptimizer's simplifier in the Rust core, the one gltfpack
  uses. It takes a vertex target, an *error* target (it stops before its error estimate
  would pass a length), or both; it keeps every output vertex at an input vertex's position
  (``vertex_ids`` says which), weighs per-vertex attributes (normals, UVs, colours) and
  keeps their seams, and can lock chosen vertices or the open borders.
- ``"fast-simplification"``: the ``fast-simplification`` package (Sp4cerat's
  Fast-Quadric-Mesh-Simplification), vertex targets only; it moves vertices to their
  quadric optimum.

Which to use by default was measured (``benches/frontier.py``, docs/frontier.md).
:func:`closest_level` picks, among precomputed levels of detail, the one whose vertex
count is closest to a target.
"""

from __future__ import annotations

import math
import numbers
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from . import _core
from .errors import MeshbitsError
from .mesh import MeshLike, as_mesh, compact, referenced
from .results import ArrayResult

__all__ = [
    "MAX_FACES_PER_VERTEX",
    "METHODS",
    "Simplified",
    "Simplifier",
    "check_untangled",
    "closest_level",
    "referenced_vertex_count",
    "simplify",
]

#: ``simplifier(vertices (n, 3) float64, faces (m, 3) int, target_vertices) -> (vertices, faces)``
Simplifier = Callable[[np.ndarray, np.ndarray, int], tuple[np.ndarray, np.ndarray]]

#: The simplifiers :func:`simplify` offers.
METHODS = ("meshopt", "fast-simplification")

#: Values of fast-simplification's ``agg`` tried in turn when a lower one stops short.
_ESCALATION = (3.0, 5.0, 7.0, 10.0)

#: Face-count requests meshopt gets to land a vertex target within ``rtol``.
_VERTEX_TARGET_TRIES = 5
#: Most faces per referenced vertex fast-simplification is given (an ordinary surface has
#: about 2). Its cost grows with the square of the faces around a vertex: Suzanne's faces
#: turned into polygons of 16 consecutive vertices and fan-triangulated (27 faces per
#: vertex) took 3 s in one call at agg = 10, polygons of 32 (57 per vertex) 30 s, and
#: ``meshbits.compress`` on polygons of 255 (483 per vertex) ran for over 10 minutes.
MAX_FACES_PER_VERTEX = 16

# fast-simplification keeps the mesh it works on in native globals: two calls must not
# overlap, so every call goes through this lock.
_FAST_SIMPLIFICATION_LOCK = threading.Lock()


@dataclass(frozen=True, eq=False)
class Simplified(ArrayResult):
    """A simplified mesh (see :func:`simplify`).

    Attributes
    ----------
    vertices : ndarray, shape (n, 3), float64
        The kept vertices (length), unreferenced ones removed.
    faces : ndarray, shape (m, 3), int64
    error : float or None
        The simplifier's own error estimate (length, mesh units): for ``"meshopt"`` the
        largest quadric error of a collapse it made, an estimate of the distance to the
        input surface, not a bound on the Hausdorff distance. None for
        ``"fast-simplification"``, which reports none.
    method : str
        The simplifier used.
    vertex_ids : ndarray, shape (n,), int64, or None
        ``"meshopt"``: the input vertex each output vertex is (same position, same
        attributes, unless ``update_positions`` moved it). None for
        ``"fast-simplification"``, which moves vertices and keeps no such map.
    attributes : ndarray, shape (n, k), or None
        The kept vertices' attributes, when some were given.
    """

    vertices: np.ndarray = field(repr=False)
    faces: np.ndarray = field(repr=False)
    error: float | None
    method: str
    vertex_ids: np.ndarray | None = field(default=None, repr=False)
    attributes: np.ndarray | None = field(default=None, repr=False)

    _arrays = ("vertices", "faces", "vertex_ids", "attributes")

    @property
    def vertex_count(self) -> int:
        return len(self.vertices)

    @property
    def mesh(self) -> tuple[np.ndarray, np.ndarray]:
        """``(vertices, faces)``."""
        return self.vertices, self.faces


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
    return int(referenced(faces).size)


def _check_target(name: str, value: Any, smallest: float) -> Any:
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be a number, got {value!r}")
    try:
        finite = math.isfinite(value)
    except OverflowError:  # an int beyond the float range
        finite = False
    if not (finite and value >= smallest):
        raise MeshbitsError(f"{name} must be a finite number >= {smallest:g}, got {value!r}")
    return value


def simplify(
    mesh: MeshLike,
    vertices: int | None = None,
    *,
    error: float | None = None,
    method: str = "meshopt",
    lock_border: bool = False,
    locked: Any = None,
    attributes: Any = None,
    attribute_weights: Any = None,
    prune: bool = False,
    update_positions: bool = False,
    rtol: float = 0.05,
) -> Simplified:
    """Simplify a mesh to about ``vertices`` vertices, or until its error would pass
    ``error``, whichever comes first.

    Parameters
    ----------
    mesh
        ``trimesh.Trimesh`` or ``(vertices, faces)``.
    vertices : int, optional
        Target number of referenced vertices (>= 4); the result lands within ``rtol`` of
        it where the simplifier can reach it.
    error : float, optional
        ``"meshopt"`` only: largest error estimate allowed (length, mesh units, >= 0).
        meshoptimizer stops collapsing before its error would pass it.
    method : {"meshopt", "fast-simplification"}
    lock_border : bool
        Keep the vertices of open borders in place (holes do not grow).
    locked : (n,) bool, optional
        ``"meshopt"`` only: vertices that must stay.
    attributes : (n, k) float, optional
        ``"meshopt"`` only: per-vertex attributes (normals, UVs, colours) weighed in the
        collapse cost; vertices that share a position but not their attributes form a
        seam, which is kept. Without attributes, vertices with identical coordinates are
        welded first (an STL triangle soup becomes a surface).
    attribute_weights : (k,) float, optional
        Weight of each attribute column (default 1): an attribute difference of 1 costs
        like ``weight`` mesh units of distance.
    prune : bool
        ``"meshopt"`` only: let small disconnected pieces vanish when they fit the error.
    update_positions : bool
        ``"meshopt"`` only: move each kept vertex (and its attributes) to where the
        collapse quadrics are least, as fast-simplification does, instead of keeping input
        vertices where they were (positions then pass through float32 relative to the
        bounding-box centre).
    rtol : float
        Relative tolerance on a vertex target.

    Returns
    -------
    Simplified

    Raises
    ------
    MeshbitsError
        Bad mesh, no target, a target out of range, an option the method does not have.
    """
    vertex_array, face_array = as_mesh(mesh)
    target_vertices = _check_target("vertices", vertices, 4)
    target_error = _check_target("error", error, 0)
    if target_vertices is None and target_error is None:
        raise MeshbitsError("give a target: vertices, error, or both")
    if method not in METHODS:
        raise MeshbitsError(f"method must be one of {METHODS}, got {method!r}")
    if method == "fast-simplification":
        extras = {
            "error": error,
            "locked": locked,
            "attributes": attributes,
            "prune": prune,
            "update_positions": update_positions,
        }
        given = [name for name, value in extras.items() if value not in (None, False)]
        if given or target_vertices is None:
            raise MeshbitsError(
                "fast-simplification takes a vertex target only"
                + (f", not {', '.join(given)}" if given else "")
            )
        out_v, out_f = _fast_simplification_to(
            vertex_array, face_array, int(target_vertices), lock_border, rtol
        )
        return Simplified(out_v, out_f, None, method)
    return _meshopt(
        vertex_array,
        face_array,
        None if target_vertices is None else int(target_vertices),
        None if target_error is None else float(target_error),
        lock_border,
        locked,
        attributes,
        attribute_weights,
        prune,
        update_positions,
        rtol,
    )


def _meshopt(
    vertices: np.ndarray,
    faces: np.ndarray,
    target_vertices: int | None,
    target_error: float | None,
    lock_border: bool,
    locked: Any,
    attributes: Any,
    weights: Any,
    prune: bool,
    update: bool,
    rtol: float,
) -> Simplified:
    n = len(vertices)
    lock_array = None
    if locked is not None:
        lock_array = np.ascontiguousarray(np.asarray(locked, dtype=bool))
        if lock_array.shape != (n,):
            raise MeshbitsError(f"locked must have shape ({n},), got {lock_array.shape}")
    values = weight_array = None
    if attributes is not None:
        values = np.ascontiguousarray(np.asarray(attributes, dtype=np.float32))
        if values.ndim == 1:
            values = values.reshape(-1, 1)
        if values.ndim != 2 or len(values) != n:
            raise MeshbitsError(f"attributes must have shape ({n}, k), got {values.shape}")
        k = values.shape[1]
        weight_array = np.ones(k, dtype=np.float32)
        if weights is not None:
            weight_array = np.ascontiguousarray(np.asarray(weights, dtype=np.float32))
            if weight_array.shape != (k,):
                raise MeshbitsError(
                    f"attribute_weights must have shape ({k},), got {weight_array.shape}"
                )
    elif weights is not None:
        raise MeshbitsError("attribute_weights needs attributes")

    def run(target_faces: int | None) -> dict[str, Any]:
        return _core.simplify(
            vertices,
            faces,
            target_faces,
            target_error,
            lock_border,
            lock_array,
            values,
            weight_array,
            prune,
            values is None,
            update,
        )

    if target_vertices is None:
        raw = run(None)
    else:
        raw = _meshopt_to_vertex_count(run, faces, target_vertices, rtol, target_error is not None)
    ids = raw["vertex_ids"].astype(np.int64)
    kept_attributes = None
    if values is not None:
        kept_attributes = raw["attributes"] if update else np.asarray(attributes)[ids]
    return Simplified(
        vertices=raw["positions"] if update else vertices[ids],
        faces=raw["faces"].astype(np.int64),
        error=float(raw["error"]),
        method="meshopt",
        vertex_ids=ids,
        attributes=kept_attributes,
    )


def _meshopt_to_vertex_count(
    run: Callable[[int | None], dict[str, Any]],
    faces: np.ndarray,
    target: int,
    rtol: float,
    error_limited: bool,
) -> dict[str, Any]:
    """Face-count requests until the kept vertices land within ``rtol`` of ``target``:
    meshoptimizer counts triangles, and a mesh keeps about its own faces-per-vertex ratio."""
    used = referenced_vertex_count(faces)
    if target >= used:
        return run(len(faces))
    target_faces = max(1, round(target * len(faces) / used))
    best: dict[str, Any] | None = None
    for _ in range(_VERTEX_TARGET_TRIES):
        raw = run(target_faces)
        got = len(raw["vertex_ids"])
        if best is None or abs(got - target) < abs(len(best["vertex_ids"]) - target):
            best = raw
        if abs(got - target) <= rtol * target or got == 0:
            break
        if error_limited and got > target and len(raw["faces"]) > 1.1 * target_faces:
            break  # the error target stopped it first: fewer faces will not come
        target_faces = max(1, min(len(faces), round(target_faces * target / max(got, 1))))
    assert best is not None
    return best


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
    return compact(np.asarray(out_vertices, dtype=np.float64), np.asarray(out_faces))


def _fast_simplification_to(
    vertices: np.ndarray,
    faces: np.ndarray,
    target_vertices: int,
    preserve_border: bool,
    rtol: float,
    aggressiveness: float = 1.5,
) -> tuple[np.ndarray, np.ndarray]:
    """fast-simplification to about ``target_vertices`` referenced vertices.

    ``aggressiveness`` is its ``agg``: lower is slower and closer to a true quadric-error
    ordering; its own default is 7, 1.5 is used because the Hausdorff error is what
    meshbits answers for (bunny halved to 30,000 vertices: 2.6e-3 S at 7, 3.3e-4 S at 1.5,
    0.1 s either way). It takes a triangle count, asked for at the mesh's own
    triangles-per-vertex ratio; when a low ``agg`` stops short (its sweeps run out) it is
    raised step by step (3, 5, 7, 10), and an undershoot beyond ``rtol`` gets one
    corrected request.
    """
    used = referenced_vertex_count(faces)
    if target_vertices >= used or len(faces) < 2:
        return compact(vertices, faces.astype(np.int64))
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
