"""Closest points and the sampled Hausdorff distance (King & Rossignac 1999, Sec. 3.2).

The error ``E`` of the paper is the Hausdorff distance ``H(O, A)`` between the original
``O`` and its approximation ``A``: ``H(A, B) = max(h(A, B), h(B, A))`` with the one-sided
``h(A, B) = max over p in A of min over q in B of |p - q|``. :func:`hausdorff` measures it
on seeded samples of both surfaces, with exact float64 point-to-triangle distances found
through a BVH (``rust/bvh/``), and can certify an upper bound.

One concept: the sampled Hausdorff distance, with its parts (closest points on a mesh, the
seeded surface samples) and :class:`Reference`, the same measurement against many
candidates.
"""

from __future__ import annotations

import math
import numbers
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from . import _core
from .constants import (
    HAUSDORFF_MAX_SAMPLES,
    HAUSDORFF_MIN_SAMPLES,
    HAUSDORFF_REFINE_BUDGET,
    HAUSDORFF_SAMPLES_PER_FACE,
)
from .errors import MeshbitsError
from .mesh import MeshLike, as_mesh, as_points, refuse_overlap
from .results import ArrayResult, Progress, ProgressCallback

__all__ = [
    "Closest",
    "ClosestPoints",
    "DirectedHausdorff",
    "Hausdorff",
    "Reference",
    "SurfaceSamples",
    "default_samples",
    "hausdorff",
    "surface_samples",
]

_U64 = 2**64

#: Area samples per mesh of :meth:`Reference.quick_distance`.
QUICK_SAMPLES = 20_000


def default_samples(n_faces: int) -> int:
    """Default number of area samples for a mesh of ``n_faces`` faces.

    ``HAUSDORFF_SAMPLES_PER_FACE * n_faces`` (10 per face, as Metro), clamped to
    ``[HAUSDORFF_MIN_SAMPLES, HAUSDORFF_MAX_SAMPLES]`` = ``[10_000, 1_000_000]`` (see
    :mod:`meshbits.constants`). The referenced vertices are sampled on top of these.
    """
    per_face = HAUSDORFF_SAMPLES_PER_FACE * int(n_faces)
    return int(min(max(per_face, HAUSDORFF_MIN_SAMPLES), HAUSDORFF_MAX_SAMPLES))


#: Largest sample count or refinement budget accepted: 2**32 - 1 samples would take
#: 100 GB for their positions alone.
MAX_COUNT = 2**32 - 1


def _check_count(value: Any, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name} must be an integer, got {type(value).__name__}")
    if value < 0:
        raise MeshbitsError(f"{name} must be non-negative, got {value}")
    if value > MAX_COUNT:
        raise MeshbitsError(f"{name} must be at most 2**32 - 1, got {value}")
    return int(value)


def _check_seed(seed: Any) -> int:
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
        raise TypeError(f"seed must be an integer, got {type(seed).__name__}")
    if not 0 <= seed < _U64:
        raise MeshbitsError(f"seed must be in [0, 2**64), got {seed}")
    return int(seed)


@dataclass(frozen=True, eq=False)
class Closest(ArrayResult):
    """Nearest points on a mesh, one row per query point.

    Attributes
    ----------
    distances : ndarray, shape (n,), float64
        Exact distance from each query to the mesh (length).
    points : ndarray, shape (n, 3), float64
        The closest point of the mesh to each query (length).
    faces : ndarray, shape (n,), int64
        The face holding it; ties between faces at exactly the same distance go to the
        smallest face index.
    """

    distances: np.ndarray
    points: np.ndarray
    faces: np.ndarray

    def to_dict(self, *, arrays: bool = True) -> dict[str, Any]:
        """JSON-ready dict: the number of queries and the largest distance, and (by
        default) the three arrays as nested lists."""
        out: dict[str, Any] = {
            "count": len(self.distances),
            "max_distance": float(self.distances.max()) if len(self.distances) else None,
        }
        return out | (super().to_dict() if arrays else {})


class ClosestPoints:
    """Exact closest points on a triangle mesh, through a reusable BVH.

    The tree (obvhs PLOC over the triangles' boxes, stored in float32 but rounded
    outward, coordinates recentred on the bounding-box centre) is built once here;
    :meth:`query` then runs in parallel with the GIL released. Distances are exact
    float64 point-to-triangle distances (Ericson's region method); zero-area triangles
    count as their edges.

    Parameters
    ----------
    mesh_or_vertices
        A ``trimesh.Trimesh``, a ``(vertices, faces)`` pair, or ``(n, 3)`` float vertices.
    faces
        ``(m, 3)`` integer vertex indices when ``mesh_or_vertices`` is an array.
    check
        Refuse a mesh whose triangles overlap beyond :data:`meshbits.mesh.MAX_BOX_OVERLAP`
        (queries would take minutes); False skips the test, for a mesh derived from one
        that passed it.

    Raises
    ------
    ValueError
        Bad shapes, NaN or infinite coordinates, out-of-range indices, an empty mesh.
    TypeError
        Non-numeric vertices or non-integer faces.

    Examples
    --------
    >>> import meshbits, numpy as np
    >>> square = (np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]), [[0, 1, 2], [0, 2, 3]])
    >>> meshbits.ClosestPoints(square).query([[0.5, 0.5, 2.0]]).distances
    array([2.])
    """

    def __init__(
        self, mesh_or_vertices: MeshLike, faces: Any = None, *, check: bool = True
    ) -> None:
        vertices, triangles = as_mesh(mesh_or_vertices, faces)
        self._tree = _core.build_tree(vertices, triangles)
        if check:
            refuse_overlap(self._tree.box_overlap, len(triangles))

    @property
    def n_faces(self) -> int:
        """Number of triangles in the tree."""
        return int(self._tree.n_faces)

    @property
    def n_vertices(self) -> int:
        """Number of vertices of the mesh (referenced or not)."""
        return int(self._tree.n_vertices)

    def query(self, points: Any) -> Closest:
        """Closest point of the mesh to each of ``points`` ((n, 3) float, length)."""
        array = as_points(points, "points", allow_empty=True)
        distances, closest, faces = self._tree.query(array)
        return Closest(distances, closest, faces.astype(np.int64))

    def farther_than(self, points: Any, distance: float) -> np.ndarray:
        """Whether each of ``points`` ((n, 3) float) lies farther than ``distance``
        (length, >= 0) from the mesh: ``query(points).distances > distance``, decided
        exactly, but each search stops at the first triangle within ``distance``."""
        array = as_points(points, "points", allow_empty=True)
        if isinstance(distance, bool) or not isinstance(distance, numbers.Real):
            raise TypeError(f"distance must be a number, got {distance!r}")
        return self._tree.farther_than(array, float(distance))

    def validate(self) -> None:
        """Check the tree's invariants (every triangle reachable once, boxes containing
        their triangles and children); raises ``RuntimeError`` if one is broken."""
        self._tree.validate()

    def __repr__(self) -> str:
        return f"ClosestPoints({self.n_faces} faces, depth {self._tree.depth})"


@dataclass(frozen=True, eq=False)
class SurfaceSamples(ArrayResult):
    """The points a mesh is sampled at (see :func:`surface_samples`).

    Attributes
    ----------
    points : ndarray, shape (n, 3), float64
        Vertex samples first, then area samples grouped by face (length).
    faces : ndarray, shape (n,), int64
        Face of each area sample; -1 for vertex samples.
    n_vertex_samples : int
        Number of vertex samples (the referenced vertices, in index order).
    """

    points: np.ndarray
    faces: np.ndarray
    n_vertex_samples: int

    _arrays = ("points", "faces")

    @property
    def n_samples(self) -> int:
        """All samples: vertices and area samples."""
        return len(self.points)

    def to_dict(self, *, arrays: bool = False) -> dict[str, Any]:
        """JSON-ready dict: the counts (with ``arrays=True``, also the points and faces)."""
        return {"n_samples": self.n_samples} | super().to_dict(arrays=arrays)


def surface_samples(
    mesh_or_vertices: MeshLike, faces: Any = None, *, samples: int | None = None, seed: int = 0
) -> SurfaceSamples:
    """The sample set of a mesh, as :func:`hausdorff` uses it.

    Every vertex referenced by a face (unreferenced vertices are not on the surface and
    are skipped), then ``samples`` points drawn by area: each face receives its expected
    share ``samples * area_i / area`` rounded up or down (systematic sampling along the
    cumulative area, one random offset), placed uniformly in the face by a random stream
    seeded by ``(seed, face index)``. The same seed gives the same points on any number of
    threads. Zero-area faces receive no area samples.

    Parameters
    ----------
    samples
        Area samples; default :func:`default_samples` (10 per face, clamped to
        ``[10_000, 1_000_000]``).
    seed
        Any integer in ``[0, 2**64)``.
    """
    vertices, triangles = as_mesh(mesh_or_vertices, faces)
    count = default_samples(len(triangles)) if samples is None else _check_count(samples, "samples")
    raw = _core.surface_samples(vertices, triangles, count, _check_seed(seed))
    sample_faces = raw["faces"].astype(np.int64)
    sample_faces[: raw["n_vertex_samples"]] = -1
    return SurfaceSamples(raw["points"], sample_faces, int(raw["n_vertex_samples"]))


@dataclass(frozen=True, eq=False)
class DirectedHausdorff(ArrayResult):
    """One direction, ``h(source, target)``, of the sampled Hausdorff distance.

    All distances are in the meshes' length unit.

    Attributes
    ----------
    max : float
        The largest exact distance found at any evaluated point: the samples and, when a
        tolerance was given, the refinement points. A lower bound on the true ``h``.
    argmax : ndarray, shape (3,)
        The point achieving ``max`` (on the source).
    argmax_closest : ndarray, shape (3,)
        Its closest point on the target.
    argmax_face : int
        The target face holding ``argmax_closest``.
    n_samples : int
        Samples evaluated: referenced vertices plus area samples.
    n_vertex_samples : int
        How many of them are vertices.
    mean, rms, p50, p95, p99 : float or None
        Mean, root mean square and 50th / 95th / 99th percentiles (linear interpolation,
        as numpy's default) of the area samples' distances (uniform by area: estimates of
        the surface's own statistics; the vertex samples count for ``max`` only; a mesh
        sampled with ``samples=0`` gets its vertices'); ``None`` with ``statistics=False``.
    upper : float or None
        Certified upper bound on the true ``h`` (``bounds=True`` or a tolerance).
    refined_points : int
        Extra points evaluated by the refinement.
    converged : bool or None
        With a tolerance: whether ``upper - max <= tolerance`` was reached (``False``: the
        refinement budget ran out first). ``None`` without a tolerance.
    samples : ndarray, shape (n, 3), or None
        With ``return_samples=True``: the sample points (vertices first).
    sample_faces : ndarray, shape (n,), int64, or None
        Source face of each sample, -1 for vertex samples.
    distances : ndarray, shape (n,), or None
        Exact distance of each sample.
    vertex_distances : ndarray, shape (source vertices,), or None
        Exact distance of each source vertex (NaN for unreferenced ones): colour the
        source mesh by error with it.
    """

    max: float
    argmax: np.ndarray
    argmax_closest: np.ndarray
    argmax_face: int
    n_samples: int
    n_vertex_samples: int
    mean: float | None = None
    rms: float | None = None
    p50: float | None = None
    p95: float | None = None
    p99: float | None = None
    upper: float | None = None
    refined_points: int = 0
    converged: bool | None = None
    samples: np.ndarray | None = field(default=None, repr=False)
    sample_faces: np.ndarray | None = field(default=None, repr=False)
    distances: np.ndarray | None = field(default=None, repr=False)
    vertex_distances: np.ndarray | None = field(default=None, repr=False)

    @property
    def lower(self) -> float:
        """Certified lower bound on the true ``h``: the same as :attr:`max`."""
        return self.max

    def to_dict(self, *, arrays: bool = False) -> dict[str, Any]:
        """JSON-ready dict of the scalars (and, with ``arrays=True``, the sample arrays)."""
        out = asdict(self)
        for name in ("samples", "sample_faces", "distances", "vertex_distances"):
            value = out.pop(name)
            if arrays and value is not None:
                out[name] = value.tolist()
        out["argmax"] = self.argmax.tolist()
        out["argmax_closest"] = self.argmax_closest.tolist()
        out["lower"] = self.max
        return out


@dataclass(frozen=True)
class Hausdorff:
    """The symmetric sampled Hausdorff distance of two meshes, and both directions.

    Attributes
    ----------
    distance : float
        ``max(a_to_b.max, b_to_a.max)``: the sampled (lower-bound) Hausdorff distance
        (length).
    upper : float or None
        ``max(a_to_b.upper, b_to_a.upper)``: a certified upper bound (length), with
        ``bounds=True`` or a tolerance.
    a_to_b, b_to_a : DirectedHausdorff
        The two one-sided distances.
    seed : int
        The seed of both sample sets.
    statistics : bool
        Whether every area sample's distance was computed (mean, RMS, percentiles).
    tolerance : float or None
        The requested ``upper - distance`` (length).
    relative_tolerance : float or None
        The requested ``upper - max`` of each direction, relative to its sampled ``max``
        (dimensionless).
    """

    distance: float
    upper: float | None
    a_to_b: DirectedHausdorff
    b_to_a: DirectedHausdorff
    seed: int
    statistics: bool
    tolerance: float | None
    relative_tolerance: float | None = None

    @property
    def lower(self) -> float:
        """Certified lower bound on the true Hausdorff distance: :attr:`distance`."""
        return self.distance

    def to_dict(self, *, arrays: bool = False) -> dict[str, Any]:
        """JSON-ready nested dict."""
        return {
            "distance": self.distance,
            "lower": self.distance,
            "upper": self.upper,
            "seed": self.seed,
            "statistics": self.statistics,
            "tolerance": self.tolerance,
            "relative_tolerance": self.relative_tolerance,
            "a_to_b": self.a_to_b.to_dict(arrays=arrays),
            "b_to_a": self.b_to_a.to_dict(arrays=arrays),
        }


def _directed(raw: dict[str, Any]) -> DirectedHausdorff:
    sample_faces = raw.get("sample_faces")
    if sample_faces is not None:
        sample_faces = sample_faces.astype(np.int64)
        sample_faces[: raw["n_vertex_samples"]] = -1
    return DirectedHausdorff(
        max=float(raw["max"]),
        argmax=np.asarray(raw["argmax"]),
        argmax_closest=np.asarray(raw["argmax_closest"]),
        argmax_face=int(raw["argmax_face"]),
        n_samples=int(raw["n_samples"]),
        n_vertex_samples=int(raw["n_vertex_samples"]),
        mean=raw.get("mean"),
        rms=raw.get("rms"),
        p50=raw.get("p50"),
        p95=raw.get("p95"),
        p99=raw.get("p99"),
        upper=raw.get("upper"),
        refined_points=int(raw.get("refined_points", 0)),
        converged=raw.get("converged"),
        samples=raw.get("samples"),
        sample_faces=sample_faces,
        distances=raw.get("distances"),
        vertex_distances=raw.get("vertex_distances"),
    )


def hausdorff(
    a: MeshLike,
    b: MeshLike,
    *,
    samples: int | None = None,
    seed: int = 0,
    statistics: bool = True,
    bounds: bool = False,
    tolerance: float | None = None,
    relative_tolerance: float | None = None,
    return_samples: bool = False,
    refine_budget: int = HAUSDORFF_REFINE_BUDGET,
    progress: ProgressCallback | None = None,
) -> Hausdorff:
    """Sampled Hausdorff distance between two triangle meshes (paper Sec. 3.2, the error E).

    Each surface is sampled (:func:`surface_samples`): every referenced vertex, plus
    ``samples`` points by area (default 10 per face, clamped to ``[10_000, 1_000_000]``,
    per mesh). Each sample's distance to the other mesh is the exact float64 distance to
    its nearest triangle. ``h(A, B)`` is the largest over A's samples, and the result's
    ``distance`` is ``max(h(A, B), h(B, A))``: a lower bound on the true Hausdorff distance.

    Parameters
    ----------
    a, b
        ``trimesh.Trimesh`` objects or ``(vertices, faces)`` pairs.
    samples
        Area samples per mesh (the vertices come on top).
    seed
        Seed of both sample sets, in ``[0, 2**64)``. The same seed gives bit-identical
        results on any number of threads.
    statistics
        ``True``: compute every area sample's distance in full, for the mean, RMS and
        percentiles over the surface. ``False``: the maximum only, which is faster: a
        sample's search stops as soon as it finds a triangle closer than the largest
        distance found so far, since it can no longer raise the maximum. ``max``,
        ``argmax`` and ``upper`` are identical either way.
    bounds
        Also compute a certified upper bound per direction from the exact distances of
        the vertices: on each source triangle, the smaller of
        ``max corner distance + covering radius`` (the distance is 1-Lipschitz) and
        ``max corner distance to one target triangle`` (a convex function, maximal at a
        corner).
    tolerance
        Refine (split triangles at their edge midpoints, evaluate the midpoints) where the
        bound exceeds ``max + tolerance``, until ``upper - max <= tolerance`` in each
        direction (length). Implies ``bounds``.
    relative_tolerance
        Instead of ``tolerance``: refine each direction until ``upper - max`` is at most
        this fraction of its sampled ``max`` (for example 0.01; at least 1e-9 of the
        target's half extent, so identical meshes end too). Implies ``bounds``.
    return_samples
        Also return each direction's sample points, their exact distances and the
        per-vertex distances of the source (implies the full computation).
    refine_budget
        Largest number of refinement points per direction; when it runs out, the
        result has ``converged=False`` and the bounds reached so far.
    progress
        Called with a :class:`meshbits.Progress` at the start and end of each phase
        (``str(event)`` is its line).

    Returns
    -------
    Hausdorff
        ``distance``, ``upper``, and the per-direction :class:`DirectedHausdorff`
        ``a_to_b`` (samples of ``a`` against ``b``) and ``b_to_a``.

    Raises
    ------
    ValueError
        Bad meshes (shapes, NaN, indices, no faces), a negative sample count, a
        non-positive tolerance.
    TypeError
        Non-numeric input, a non-integer seed or sample count.

    Notes
    -----
    Unlike PyMeshLab's Hausdorff filter, unreferenced vertices are not sampled (they are
    not on the surface). Zero-area faces get no area samples but their vertices are
    sampled, and the bounds cover them.
    """
    seed = _check_seed(seed)
    if samples is not None:
        samples = _check_count(samples, "samples")
    refine_budget = _check_count(refine_budget, "refine_budget")
    bounds, tolerance, relative_tolerance = _bounds_asked(bounds, tolerance, relative_tolerance)

    say = _progress_lines(progress)
    meshes = {"A": as_mesh(a), "B": as_mesh(b)}
    trees = _build_trees(meshes, say)
    # What both directions are asked, after their source, target, sample count and seed.
    asked = (statistics, bounds, tolerance, refine_budget, return_samples, None, relative_tolerance)
    a_to_b = _measure_direction("A", "B", meshes, trees, samples, seed, asked, say)
    b_to_a = _measure_direction("B", "A", meshes, trees, samples, seed, asked, say)
    return _symmetric(a_to_b, b_to_a, seed, statistics, tolerance, relative_tolerance)


def _progress_lines(progress: ProgressCallback | None) -> Callable[[str], None]:
    """A function passing each line to ``progress`` as a ``"hausdorff"`` event (if any)."""

    def say(line: str) -> None:
        if progress is not None:
            progress(Progress("hausdorff", line))

    return say


def _build_trees(
    meshes: dict[str, tuple[np.ndarray, np.ndarray]], say: Callable[[str], None]
) -> dict[str, Any]:
    """One BVH per named mesh (built together), each checked for overlapping boxes."""
    start = time.perf_counter()
    sizes = {name: f"{len(faces):,}" for name, (_, faces) in meshes.items()}
    say(f"building the BVHs of A ({sizes['A']} faces) and B ({sizes['B']} faces)")
    trees = dict(zip(meshes, _core.build_trees(list(meshes.values())), strict=True))
    for name, (_, faces) in meshes.items():
        refuse_overlap(trees[name].box_overlap, len(faces), f"mesh {name.lower()}")
    say(f"built the BVHs in {time.perf_counter() - start:.2f} s")
    return trees


def _measure_direction(
    source: str,
    target: str,
    meshes: dict[str, tuple[np.ndarray, np.ndarray]],
    trees: dict[str, Any],
    samples: int | None,
    seed: int,
    asked: tuple[Any, ...],
    say: Callable[[str], None],
) -> DirectedHausdorff:
    """``h(source, target)``: ``samples`` area samples (default :func:`default_samples`)
    of the source mesh, plus its vertices, against the target's BVH; ``asked`` is the rest
    of ``_core.hausdorff_directed``'s arguments."""
    vertices, faces = meshes[source]
    count = default_samples(len(faces)) if samples is None else samples
    start = time.perf_counter()
    say(f"{source} -> {target}: {count:,} area samples + vertices")
    raw = _core.hausdorff_directed(vertices, faces, trees[target], count, seed, *asked)
    say(f"{source} -> {target}: max {raw['max']:.6g} in {time.perf_counter() - start:.2f} s")
    return _directed(raw)


def _symmetric(
    a_to_b: DirectedHausdorff,
    b_to_a: DirectedHausdorff,
    seed: int,
    statistics: bool,
    tolerance: float | None,
    relative_tolerance: float | None = None,
) -> Hausdorff:
    upper = None
    if a_to_b.upper is not None and b_to_a.upper is not None:
        upper = max(float(a_to_b.upper), float(b_to_a.upper))
    return Hausdorff(
        distance=max(a_to_b.max, b_to_a.max),
        upper=upper,
        a_to_b=a_to_b,
        b_to_a=b_to_a,
        seed=seed,
        statistics=bool(statistics),
        tolerance=tolerance,
        relative_tolerance=relative_tolerance,
    )


def _bounds_asked(
    bounds: bool, tolerance: Any, relative_tolerance: Any
) -> tuple[bool, float | None, float | None]:
    """``(bounds, tolerance, relative_tolerance)`` checked: at most one tolerance, and
    either implies the bounds."""
    tolerance = _check_tolerance(tolerance)
    relative_tolerance = _check_tolerance(relative_tolerance, "relative_tolerance")
    if tolerance is not None and relative_tolerance is not None:
        raise MeshbitsError("give tolerance (a length) or relative_tolerance, not both")
    wanted = bool(bounds) or tolerance is not None or relative_tolerance is not None
    return wanted, tolerance, relative_tolerance


def _check_tolerance(tolerance: Any, name: str = "tolerance") -> float | None:
    if tolerance is None:
        return None
    if isinstance(tolerance, bool) or not isinstance(tolerance, numbers.Real):
        raise TypeError(f"{name} must be a number or None, got {tolerance!r}")
    value = float(tolerance)
    if not (value > 0 and math.isfinite(value)):
        raise MeshbitsError(f"{name} must be positive and finite, got {tolerance}")
    return value


class Reference:
    """A mesh measured against many candidates (the original of ``compress``, each pass
    a new candidate): its BVH and its samples are built once, here.

    ``Reference(a, samples=n, seed=s).hausdorff(b, samples=n)`` is
    ``hausdorff(a, b, samples=n, seed=s)``: the same samples and the same exact
    distances (up to a rounding of order 1e-16 of the coordinates, from measuring the
    stored samples in each candidate's frame).

    Parameters
    ----------
    mesh
        ``trimesh.Trimesh`` or ``(vertices, faces)``.
    samples : int, optional
        Area samples of the reference (default :func:`default_samples` of its faces).
    seed : int
        Seed of every sample set, the reference's and the candidates'.
    """

    def __init__(self, mesh: MeshLike, *, samples: int | None = None, seed: int = 0) -> None:
        self.vertices, self.faces = as_mesh(mesh)
        self._tree = _core.build_tree(self.vertices, self.faces)
        refuse_overlap(self._tree.box_overlap, len(self.faces))
        self.seed = _check_seed(seed)
        self.samples = (
            default_samples(len(self.faces))
            if samples is None
            else _check_count(samples, "samples")
        )
        self._sampled = _core.sample_mesh(self.vertices, self.faces, self.samples, self.seed)
        self._quick: tuple[int, _core.SampledMesh] | None = None

    @property
    def n_samples(self) -> int:
        """The reference's samples: referenced vertices plus area samples."""
        return int(self._sampled.n_samples)

    def hausdorff(
        self,
        candidate: MeshLike,
        *,
        samples: int | None = None,
        statistics: bool = False,
        bounds: bool = False,
        tolerance: float | None = None,
        refine_budget: int = HAUSDORFF_REFINE_BUDGET,
        check: bool = True,
        threshold: float | None = None,
        relative_tolerance: float | None = None,
    ) -> Hausdorff:
        """Sampled Hausdorff distance from the reference (``a``) to ``candidate`` (``b``),
        as :func:`hausdorff` computes it; ``samples`` is the candidate's area sample count
        (default: the reference's). Only the candidate's BVH and samples are built.
        ``check=False`` skips the candidate's overlap check (:func:`check_overlap`), for
        one made from the reference by simplification or quantization (compress's
        search).

        ``threshold`` (length, with a ``tolerance``) asks only whether the distance is
        within it: the refinement settles a piece once its bound is within ``threshold``
        (instead of ``max + tolerance``) and stops once the maximum found exceeds it, so
        ``upper`` may be anywhere up to ``threshold`` (``converged`` is then true when
        the bounds decided the question, false when ``refine_budget`` ran out first).
        Once the direction from the reference exceeds ``threshold``, the other direction
        is not refined (its ``upper`` is its unrefined bound, ``converged`` false).
        ``relative_tolerance``, instead of ``tolerance``, as :func:`hausdorff`'s."""
        count = self.samples if samples is None else _check_count(samples, "samples")
        refine_budget = _check_count(refine_budget, "refine_budget")
        if threshold is not None:
            threshold = float(threshold)
            if not (math.isfinite(threshold) and threshold >= 0):
                raise MeshbitsError(f"threshold must be finite and >= 0, got {threshold}")
        bounds, tolerance, relative_tolerance = _bounds_asked(bounds, tolerance, relative_tolerance)
        vertices, faces = as_mesh(candidate)
        tree = _core.build_tree(vertices, faces)
        if check:
            refuse_overlap(tree.box_overlap, len(faces), "the candidate")
        # What both directions are asked, after their source and target.
        asked = (statistics, bounds, tolerance, refine_budget, False, threshold, relative_tolerance)
        a_to_b = _core.hausdorff_from_samples(self._sampled, tree, *asked)
        if threshold is not None and a_to_b["max"] > threshold:
            # The answer is already no: the other direction keeps its unrefined bound
            # (refining it to decide would take seconds on a large candidate).
            asked = (*asked[:3], 0, *asked[4:])
        b_to_a = _core.hausdorff_directed(vertices, faces, self._tree, count, self.seed, *asked)
        return _symmetric(
            _directed(a_to_b),
            _directed(b_to_a),
            self.seed,
            statistics,
            tolerance,
            relative_tolerance,
        )

    def quick_distance(
        self, candidate: MeshLike, samples: int | None = None, *, check: bool = True
    ) -> float:
        """A cheaper estimate of the sampled Hausdorff distance to ``candidate`` (length):
        the maximum only, over every referenced vertex of both meshes and ``samples``
        area samples of each (the reference's drawn once; default a tenth of the
        reference's, at least :data:`QUICK_SAMPLES`). A lower bound, like the full
        measurement, but from fewer points."""
        if samples is None:
            samples = max(QUICK_SAMPLES, self.samples // 10)
        samples = _check_count(samples, "samples")
        if self._quick is None or self._quick[0] != samples:
            self._quick = (
                samples,
                _core.sample_mesh(self.vertices, self.faces, samples, self.seed),
            )
        vertices, faces = as_mesh(candidate)
        tree = _core.build_tree(vertices, faces)
        if check:
            refuse_overlap(tree.box_overlap, len(faces), "the candidate")
        budget = HAUSDORFF_REFINE_BUDGET
        a_to_b = _core.hausdorff_from_samples(
            self._quick[1], tree, False, False, None, budget, False
        )
        b_to_a = _core.hausdorff_directed(
            vertices, faces, self._tree, samples, self.seed, False, False, None, budget, False
        )
        return float(max(a_to_b["max"], b_to_a["max"]))

    def __repr__(self) -> str:
        return f"Reference({len(self.faces)} faces, {self.n_samples} samples, seed {self.seed})"
