"""Levels of detail: the meshes the search can quantize (the original, a simplification, a
given LOD), the vertex attributes that travel with them, and simplification with the
original vertices a level strays from locked in place.

meshoptimizer's simplifier can leave a spike of the original (one vertex far from its
neighbours) far from the simplified surface: the error of a level is then far above its
target, flat over a range of vertex counts. A level whose original vertices lie farther
from it than the tessellation error it is meant to have is simplified again with those
vertices locked in place (:data:`LOCK_ROUNDS`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..codecs import Encoded
from ..hausdorff import ClosestPoints
from ..mesh import referenced
from ..simplify import simplify
from .error_model import COMBINE_DELTA, interaction, quantization_error

__all__ = [
    "BASE_FACES",
    "LOCK_MAX_FRACTION",
    "LOCK_ROUNDS",
    "LOCK_ROUNDS_LARGE",
    "Attributes",
    "Level",
    "simplify_locking",
    "used_box",
]

#: For an original of more faces than this, each simplification costs about a second:
#: ``"auto"`` takes meshoptimizer without comparing (fast-simplification takes twice as
#: long on the dragon), each B gets one level per pass and one B above the least is
#: tried.
BASE_FACES = 200_000

#: Rounds of locking the original vertices a meshopt level strays from, then
#: simplifying again.
LOCK_ROUNDS = 2

#: The same for an original of more than :data:`BASE_FACES` faces, where each round
#: simplifies the whole original again (about a second on the dragon's 871k faces). On
#: the dragon's 0.001 S budget a second round locked 4 more vertices beyond the 744 of
#: the first. (No round once strays are known cost more: the level without the 12 more
#: that later levels found failed its certification.)
LOCK_ROUNDS_LARGE = 1

#: Most original vertices a level locks, as a fraction of its own vertex count: when more
#: stray, it is too coarse for its aim, and only the farthest are locked (all of them
#: would bloat it). (The welded Stanford dragon at meshoptimizer's 5e-4 S error target
#: strays from 1,003 vertices at 20,071: locking them took its error from 1.35e-2 to
#: 1.25e-3 S. A size budget of 200,000 bits on it strayed from more than a tenth: locking
#: none kept 2.87e-3 mesh units, locking the farthest tenth gave 5.40e-4.)
LOCK_MAX_FRACTION = 0.1


@dataclass
class Level:
    """A mesh the search can quantize: the original, a simplified one, or a given LOD.

    Attributes
    ----------
    source : str
        ``"original"``, ``"meshopt"`` (an error target), ``"vertices"`` (a vertex target)
        or ``"lod"``.
    vertices, faces : ndarray
    target_error : float or None
        meshoptimizer's error target (length).
    target_vertices : int or None
    simplifier_error : float or None
        The simplifier's own estimate (length).
    locked : int
        Original vertices locked in place.
    lod : int or None
        Index among the given levels of detail.
    origin, grid_size
        The level's cube grid.
    encodings : dict
        ``B -> Encoded``.
    errors : dict
        ``B -> measured error`` (length; the certified bound when certifying).
    quick : float or None
        :meth:`Reference.quick_distance` of the unquantized level (length).
    aliases : list
        Other simplifier parameters that gave this same mesh.
    referenced_vertices : int or None
        The vertices its faces use, when some of ``vertices`` are not (the original, whose
        duplicate positions the weld left unused); None when all are.
    """

    source: str
    vertices: np.ndarray = field(repr=False)
    faces: np.ndarray = field(repr=False)
    target_error: float | None = None
    target_vertices: int | None = None
    simplifier_error: float | None = None
    locked: int = 0
    lod: int | None = None
    method: str | None = None
    attributes: dict[str, np.ndarray] | None = field(default=None, repr=False)
    origin: np.ndarray = field(default_factory=lambda: np.zeros(3), repr=False)
    grid_size: float = 0.0
    encodings: dict[int, Encoded] = field(default_factory=dict, repr=False)
    errors: dict[int, float] = field(default_factory=dict)
    quick: float | None = None
    aliases: list[float] = field(default_factory=list)
    referenced_vertices: int | None = None

    @property
    def vertex_count(self) -> int:
        """The vertices its faces use (the welded original keeps its duplicates unused)."""
        if self.referenced_vertices is not None:
            return self.referenced_vertices
        return len(self.vertices)

    @property
    def parameter(self) -> float:
        """What the simplifier was driven by: the error target, else the vertex count."""
        if self.target_error is not None:
            return self.target_error
        return float(self.target_vertices or self.vertex_count)

    def interactions(self, ratio: float, bits: int | None = None) -> list[float]:
        """:func:`interaction` of each measurement of the level (at ``bits`` only, when
        given), its tessellation error taken as ``ratio`` times its quick estimate."""
        if self.quick is None and self.source != "original":
            return []
        t = 0.0 if self.source == "original" else ratio * float(self.quick or 0.0)
        return [
            interaction(error, t, quantization_error(measured_bits, self.grid_size))
            for measured_bits, error in self.errors.items()
            if bits is None or measured_bits == bits
        ]

    def ratio(self) -> float | None:
        """Measured over quick-estimated tessellation error, from the measurements where
        tessellation dominates (quantization below half the error); None without one."""
        if not self.quick:
            return None
        ratios = [
            (error - COMBINE_DELTA * q) / self.quick
            for bits, error in self.errors.items()
            for q in [quantization_error(bits, self.grid_size)]
            if q < 0.5 * error
        ]
        return max(ratios) if ratios else None


@dataclass(frozen=True)
class Attributes:
    """Per-vertex attributes that travel with the positions through simplification.

    Attributes
    ----------
    values : dict
        ``name -> (n, k)`` arrays, one row per vertex of the original.
    weights : dict
        ``name -> weight`` for meshoptimizer's attribute-aware collapse cost (0: carried
        but not weighed).
    interpolate : bool
        Whether attribute values may move with the vertices (meshoptimizer's updated
        positions); False keeps every kept vertex as it was, attributes included (skins:
        joint indices do not interpolate).
    """

    values: dict[str, np.ndarray]
    weights: dict[str, float]
    interpolate: bool = True

    def stacked(self) -> tuple[np.ndarray, np.ndarray, list[tuple[str, int]]]:
        """The values side by side ``(n, K)`` (float32), a weight per column, and each
        attribute's name and width."""
        columns, weights, layout = [], [], []
        for name, array in self.values.items():
            block = np.asarray(array, dtype=np.float64).reshape(len(array), -1)
            columns.append(block)
            weights += [float(self.weights.get(name, 0.0))] * block.shape[1]
            layout.append((name, block.shape[1]))
        return np.hstack(columns), np.asarray(weights), layout

    def split(self, stacked: np.ndarray, layout: list[tuple[str, int]]) -> dict[str, np.ndarray]:
        out, start = {}, 0
        for name, width in layout:
            block = stacked[:, start : start + width]
            source = self.values[name]
            out[name] = block.astype(source.dtype) if source.dtype.kind in "iu" else block
            start += width
        return out


def simplify_locking(
    source: tuple[np.ndarray, np.ndarray],
    method: str,
    target: dict[str, Any],
    aim: float | None,
    known_strays: np.ndarray,
    attributes: Attributes | None = None,
) -> tuple[Any, int, dict[str, np.ndarray] | None]:
    """Simplify ``source``; for meshopt with an ``aim``, lock the source vertices the
    result leaves farther than ``aim`` (the farthest :data:`LOCK_MAX_FRACTION` of the
    result's vertex count, when more stray) and simplify again (:data:`LOCK_ROUNDS` times
    at most).
    ``known_strays`` (one flag per source vertex) starts locked, and gains every vertex
    locked here: a vertex left far from one level tends to be from the next. With
    ``attributes``, they are simplified with the positions (their seams kept). Returns
    the result, how many vertices were locked, and the result's attributes by name."""
    options: dict[str, Any] = {"update_positions": True} if method == "meshopt" else {}
    layout: list[tuple[str, int]] = []
    if attributes is not None:
        stacked, weights, layout = attributes.stacked()
        options = {
            "attributes": stacked,
            "attribute_weights": weights,
            "update_positions": attributes.interpolate,
        }
    use_locks = method == "meshopt" and aim is not None and aim > 0
    locked = known_strays.copy() if use_locks else np.zeros(len(source[0]), dtype=bool)
    rounds = LOCK_ROUNDS
    if len(source[1]) > BASE_FACES:
        rounds = LOCK_ROUNDS_LARGE
    if locked.any():
        result = simplify(source, method=method, locked=locked, **target, **options)
    else:
        result = simplify(source, method=method, **target, **options)

    def named(result: Any) -> dict[str, np.ndarray] | None:
        return None if attributes is None else attributes.split(result.attributes, layout)

    if not use_locks or len(result.faces) == 0:
        return result, 0, named(result)
    assert aim is not None  # use_locks
    used = referenced(source[1], len(source[0]))
    for _ in range(rounds):
        level = ClosestPoints(result.mesh, check=False)
        strays = used[level.farther_than(source[0][used], aim)]
        cap = int(LOCK_MAX_FRACTION * result.vertex_count)
        if len(strays) == 0 or cap == 0:
            break
        if len(strays) > cap:
            # Too many for this level to keep: the farthest, which set its error.
            distances = level.query(source[0][strays]).distances
            strays = strays[np.argsort(-distances, kind="stable")[:cap]]
        locked[strays] = True
        result = simplify(source, method=method, locked=locked, **target, **options)
    known_strays |= locked
    return result, int(locked.sum()), named(result)


def used_box(mesh: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Bounding box of the vertices some face references."""
    used = mesh[0][referenced(mesh[1], len(mesh[0]))]
    return used.min(axis=0), used.max(axis=0)
