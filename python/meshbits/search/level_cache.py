"""The level cache of a search: every level built (simplified once, encoded once per
``B``), the simplifiers that build them, and each level's predicted tessellation error.

A level's tessellation error is its quick estimate (:meth:`Reference.quick_distance` of
the unquantized level) times :meth:`LevelCache.ratio`, the full over quick error measured
on it or on the other levels; the interaction ``delta`` of :func:`combined_error` is
learned the same way (:meth:`LevelCache.delta`). A level for a tessellation error is
found by interpolating the simplifier's parameter (meshoptimizer's error target, or a
vertex count) in log-log between the levels built so far (:meth:`LevelCache.level_for`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from .. import model
from ..codecs import Encoded, encode
from ..constants import MODEL_MIN_VERTICES
from ..errors import MeshbitsError
from ..hausdorff import Reference
from ..mesh import all_faces_degenerate, as_mesh, referenced
from ..quantize import cube_grid
from ..simplify import Simplifier
from .error_model import COMBINE_DELTA, KAPPA_PRIOR, interpolate, paper_vertices
from .levels import BASE_FACES, Attributes, Level, simplify_locking, used_box

__all__ = [
    "AUTO_MARGIN",
    "LEVEL_CLOSE",
    "LEVEL_TRIES",
    "MIN_STEP",
    "PLATEAU_SPAN",
    "PROBE_FRACTION",
    "Codec",
    "LevelCache",
    "Refused",
]

#: ``"auto"`` takes fast-simplification only when its quick estimate is below this
#: fraction of meshoptimizer's (with its strays locked).
AUTO_MARGIN = 0.97

#: The level a vertex-driven simplifier builds first when the model asks for every
#: vertex (as a fraction of them): fandisk at 1.26e-4 S, where the paper's model wants
#: 34,600 vertices of 6,475, has fast-simplification at 3,239 vertices measuring 4.3e-5
#: (mesh units of 5.24 S) against a budget of 6.6e-4.
PROBE_FRACTION = 0.5

#: Simplifications tried to find a level of a given tessellation error.
LEVEL_TRIES = 3

#: Smallest step (a ratio) of a simplifier's parameter past a level that was too coarse.
MIN_STEP = 1.15

#: Two levels whose simplifier parameters differ by more than this (in log) and whose
#: errors agree within 1% mark a plateau: finer levels of that simplifier are not sought
#: below it.
PLATEAU_SPAN = 0.25

#: A level found for a tessellation error ``t*`` is close enough from ``LEVEL_CLOSE t*``
#: to ``t*``.
LEVEL_CLOSE = 0.8


#: A codec for the search: ``codec(vertices, faces, attributes, bits, origin, grid_size)``
#: returns an object with ``size_bits`` and the decoded ``vertices`` and ``faces``.
Codec = Callable[..., Any]


class Refused(MeshbitsError):
    """The encoder cannot encode a candidate (Draco refusing a mesh, say)."""


def _stepped(
    parameter: float,
    known: list[tuple[float, float]],
    tessellation: float,
    *,
    finer_is_smaller: bool,
) -> float:
    """``parameter``, moved at least :data:`MIN_STEP` (a ratio) past the nearest level
    built on the side it has to improve on: where the error plateaus, interpolation
    creeps, and a plateau is only left by a step."""
    if finer_is_smaller:  # meshopt's error target: a finer level has a smaller one
        too_coarse = [p for t, p in known if t > tessellation]
        if too_coarse:
            parameter = min(parameter, min(too_coarse) / MIN_STEP)
    else:  # a vertex count: a finer level has more
        too_coarse = [p for t, p in known if t > tessellation]
        if too_coarse:
            parameter = max(parameter, max(too_coarse) * MIN_STEP)
    return parameter


class LevelCache:
    """The levels a search has built, from the original (index 0) on, and how to build,
    encode and predict them.

    Parameters
    ----------
    original : (vertices, faces)
        The welded original.
    reference : Reference
        Its BVH and samples, built once (for the quick estimates).
    k : float
        The original's grid-normalised K.
    grid_size : float
        ``S`` of the original (length).
    format : str
        Encoder, when ``codec`` is None.
    method : str or None
        ``"meshopt"``, ``"fast-simplification"``, or ``"auto"`` (see
        :meth:`simplifier_methods`); None with ``simplifier`` or ``lods``.
    simplifier : callable, optional
        ``simplifier(vertices, faces, target_vertices) -> (vertices, faces)``.
    lods : sequence of meshes, optional
        The levels to choose from, with the original.
    attributes : Attributes, optional
        Vertex attributes to simplify with (meshoptimizer only: they keep their seams)
        and to encode.
    codec : callable, optional
        What encodes a level (see :data:`Codec`); default :func:`meshbits.encode` in
        ``format``.
    plan : Allocation or None
        The model's first plan (its vertex count is where ``"auto"`` compares the
        simplifiers).
    """

    def __init__(
        self,
        original: tuple[np.ndarray, np.ndarray],
        reference: Reference,
        *,
        k: float,
        grid_size: float,
        format: str,
        method: str | None,
        simplifier: Simplifier | None,
        lods: Sequence[Any] | None,
        attributes: Attributes | None,
        codec: Codec | None,
        plan: model.Allocation | None,
    ) -> None:
        self.original = original
        self.reference = reference
        self.k = float(k)
        self.grid_size = float(grid_size)
        self.format = format
        self.method = method
        self.simplifier = simplifier
        self.attributes = attributes
        self.codec = codec
        self.plan = plan
        self.compete = (
            method == "auto"
            and simplifier is None
            and lods is None
            and attributes is None
            and len(original[1]) <= BASE_FACES
        )
        self.original_box = used_box(original)
        self.used = referenced(original[1], len(original[0]))
        self.available = len(self.used)
        self.levels: list[Level] = []
        #: ``(level, bits) -> why`` of each candidate the encoder refused (skipped).
        self.refused: dict[tuple[int, int], str] = {}
        #: Wall time spent by kind of work (seconds).
        self.seconds = {"simplify": 0.0, "encode": 0.0, "hausdorff": 0.0, "estimate": 0.0}
        #: Quick estimate of each simplifier tried by ``"auto"`` (length).
        self.simplifier_estimates: dict[str, float] = {}
        self.add(
            Level(
                "original",
                *original,
                attributes=None if attributes is None else attributes.values,
                referenced_vertices=self.available,
            )
        )
        self.lods = lods is not None
        #: Tessellation error below which a simplifier's levels stopped improving.
        self.floor: dict[str, float] = {}
        #: Original vertices some meshopt level left too far: locked in every later one.
        self.strays = np.zeros(len(original[0]), dtype=bool)
        if lods is not None:
            for index, lod in enumerate(lods):
                vertices, faces = as_mesh(lod)
                self.add(Level("lod", vertices, faces.astype(np.int64), lod=index))

    @property
    def large(self) -> bool:
        """Whether the original has more than :data:`BASE_FACES` faces (each
        simplification then costs about a second)."""
        return len(self.original[1]) > BASE_FACES

    # --- predictions --------------------------------------------------------------------

    def ratio(self, level: Level | None = None) -> float:
        """Full over quick tessellation error: the level's own when measured, else the
        median over the measured levels (1 before any: the quick estimate is within 10%
        of the full measurement on the bunny, horse and fandisk; on the dragon's thin
        parts it finds half)."""
        own = None if level is None else level.ratio()
        if own is not None:
            return max(own, 1.0)
        seen = [r for lv in self.levels for r in [lv.ratio()] if r is not None]
        return max(float(np.median(seen)), 1.0) if seen else 1.0

    def delta(self, level: Level | None = None, bits: int | None = None) -> float:
        """The interaction ``delta`` to predict with: the larger of the level's own (the
        largest measured) and, at ``bits``, the mean of the interactions measured at the
        same ``bits`` on the other levels; without either, the mean over the measured
        levels with :data:`COMBINE_DELTA` as one more observation.

        The interaction depends on ``B``: where quantization takes most of the budget (the
        SMPL hand at 0.001 S and B = 10, ``E_Q = 0.79 E``), levels measured 1.00-1.22 E
        against 0.94-0.96 E predicted with the mean over every ``B`` (0.15-0.27), and
        four passes went to misses at that ``B``; the first miss measured 0.5 there."""
        own = [] if level is None else level.interactions(self.ratio(level))
        same = [
            value
            for lv in self.levels
            if bits is not None and lv is not level and lv.source != "original"
            for value in lv.interactions(self.ratio(lv), bits)
        ]
        if own or same:
            return max(max(own, default=0.0), float(np.mean(same)) if same else 0.0)
        seen = [
            max(lv.interactions(self.ratio(lv)))
            for lv in self.levels
            if lv.interactions(self.ratio(lv))
        ]
        return (COMBINE_DELTA + sum(seen)) / (1 + len(seen))

    def tessellation(self, level: Level) -> float:
        """The level's tessellation error (length): 0 for the original, else the quick
        estimate of the unquantized level times :meth:`ratio`."""
        return self.ratio(level) * self.estimate(level)

    def estimate(self, level: Level) -> float:
        """The quick estimate of a level's tessellation error, computed once (length)."""
        if level.source == "original":
            level.quick = 0.0
            return 0.0
        if level.quick is None:
            begin = time.perf_counter()
            level.quick = self.reference.quick_distance(
                (level.vertices, level.faces), check=level.source == "lod"
            )
            self.seconds["estimate"] += time.perf_counter() - begin
        return level.quick

    def add(self, level: Level) -> int:
        """Keep a level, with the cube grid over the original's box widened to hold it (a
        simplifier may move a vertex slightly outside)."""
        low, high = used_box((level.vertices, level.faces))
        level.origin, level.grid_size = cube_grid(
            np.minimum(self.original_box[0], low), np.maximum(self.original_box[1], high)
        )
        self.levels.append(level)
        return len(self.levels) - 1

    def can_simplify(self) -> bool:
        """Whether new levels can be built (a simplifier, and no given LODs)."""
        return not self.lods and (self.method is not None or self.simplifier is not None)

    def simplifier_methods(self) -> list[str | None]:
        """The simplifiers whose levels compete in the search: for ``"auto"`` on a mesh
        of at most :data:`BASE_FACES` faces without attributes, both (a level of each is
        planned, and the measurements decide); else :meth:`simplifier_method`'s."""
        if self.compete:
            return ["meshopt", "fast-simplification"]
        return [self.simplifier_method()]

    def simplifier_method(self) -> str | None:
        """The simplifier of this search: the one asked for, or for ``"auto"`` the one
        whose simplification to the first plan's vertex count lies closer to the original
        by the quick estimate; None for a caller's simplifier."""
        if self.simplifier is not None or self.method is None:
            return None
        if self.attributes is not None:
            # fast-simplification carries no attributes.
            self.method = "meshopt"
        if self.method != "auto":
            return self.method
        planned = self.plan.whole_vertices if self.plan is not None else 1000.0
        target = int(min(max(planned, 100.0), 0.5 * self.available))
        if target < MODEL_MIN_VERTICES or self.large:
            self.method = "meshopt"
            return self.method
        fast_level = self.simplified("fast-simplification", vertices=target)
        if fast_level is None:
            self.method = "meshopt"
            return self.method
        fast = self.estimate(self.levels[fast_level])
        # meshoptimizer with the vertices it strays from beyond fast-simplification's error
        # locked: what its levels will be.
        meshopt_level = self.simplified("meshopt", vertices=target, aim=fast)
        if meshopt_level is None:
            self.method = "fast-simplification"
            return self.method
        meshopt = self.estimate(self.levels[meshopt_level])
        self.simplifier_estimates = {"meshopt": meshopt, "fast-simplification": fast}
        self.method = "fast-simplification" if fast < AUTO_MARGIN * meshopt else "meshopt"
        return self.method

    def simplified(
        self,
        method: str | None,
        *,
        vertices: float | None = None,
        tau: float | None = None,
        aim: float | None = None,
    ) -> int | None:
        """The level a simplifier makes for a vertex target or (meshopt) an error target
        ``tau``: a built one within 3%, or a new one; None when nothing of the mesh is left
        (an error target as large as the mesh). For meshopt, original vertices left
        farther than ``aim`` from the level are locked and it is simplified again."""
        if vertices is not None:
            vertices = int(max(MODEL_MIN_VERTICES, min(round(vertices), self.available)))
            if vertices >= self.available:
                return 0
        for index, level in enumerate(self.levels):
            same_method = level.source == ("meshopt" if tau is not None else "vertices") and (
                level.method == method
            )
            wanted = tau if tau is not None else vertices
            if same_method and wanted:
                if any(abs(p / wanted - 1) < 0.03 for p in [level.parameter, *level.aliases]):
                    return index
        begin = time.perf_counter()
        if method is None:
            assert self.simplifier is not None and vertices is not None
            v, f = self.simplifier(self.original[0], self.original[1], vertices)
            v, f = as_mesh(v, f)
            level = Level("vertices", v, f.astype(np.int64), target_vertices=vertices)
        else:
            target = {"error": tau} if tau is not None else {"vertices": vertices}
            locks_at = aim if method == "meshopt" else None
            result, locked, attributes = simplify_locking(
                self.original, method, target, locks_at, self.strays, self.attributes
            )
            if len(result.faces) == 0:
                self.seconds["simplify"] += time.perf_counter() - begin
                return None
            level = Level(
                "meshopt" if tau is not None else "vertices",
                result.vertices,
                result.faces,
                target_error=tau,
                target_vertices=vertices,
                simplifier_error=result.error,
                locked=locked,
                attributes=attributes,
            )
        level.method = method
        self.seconds["simplify"] += time.perf_counter() - begin
        if all_faces_degenerate(level.vertices, level.faces):
            # Nothing of the surface is left (a single triangle collapsed to an edge).
            return None
        same = self._same_level(level)
        if same is not None:
            # Another parameter, the same mesh (a small mesh simplifies to the same level
            # over a range of targets): one level, so what was measured on it counts.
            self.levels[same].aliases.append(level.parameter)
            return same
        return self.add(level)

    def _same_level(self, level: Level) -> int | None:
        """The index of a built level of the same simplifier with the same mesh, if any."""
        for index, other in enumerate(self.levels):
            if (
                other.source == level.source
                and other.method == level.method
                and other.vertices.shape == level.vertices.shape
                and other.faces.shape == level.faces.shape
                and np.array_equal(other.faces, level.faces)
                and np.array_equal(other.vertices, level.vertices)
            ):
                return index
        return None

    def level_for(
        self, tessellation: float, aim_locks: float | None, method: str | None
    ) -> int | None:
        """A level whose tessellation error is at most ``tessellation`` and as close to
        it as a few simplifications find: the simplifier's parameter (meshopt's error
        target, or a vertex count) is interpolated in log-log between the levels built so
        far, which are judged by their measured or quick-estimated error."""
        if not self.can_simplify() or tessellation <= 0:
            return None
        by_error = method == "meshopt"
        if tessellation < 0.99 * self.floor.get(method or "", 0.0):
            return None
        best: int | None = None
        tries = 1 if self.large else LEVEL_TRIES
        for _ in range(tries):
            same = [
                i
                for i, level in enumerate(self.levels)
                if level.source == ("meshopt" if by_error else "vertices")
                and level.method == method
            ]
            known = [(self.tessellation(self.levels[i]), self.levels[i].parameter) for i in same]
            known_indices = [(self.tessellation(self.levels[i]), i) for i in same]
            if by_error:
                tau = interpolate(sorted(known), tessellation, 1.0 / KAPPA_PRIOR)
                tau = _stepped(tau, known, tessellation, finer_is_smaller=True)
                index = self.simplified(method, tau=tau, aim=aim_locks)
            else:
                # More vertices, less error: interpolate the vertex count against 1/t.
                inverse = sorted((1.0 / t, v) for t, v in known if t > 0)
                guess = paper_vertices(self.k, self.grid_size, tessellation)
                vertices = interpolate(inverse, 1.0 / tessellation, guess * tessellation)
                vertices = _stepped(vertices, known, tessellation, finer_is_smaller=False)
                if not known and vertices >= self.available:
                    # The model asks for the whole mesh, and nothing of this simplifier
                    # was measured yet: it can be far off (on a CAD part, flat faces meet
                    # at creases whose spheres are small), so a level of half the
                    # vertices is measured first, and later tries interpolate from it.
                    vertices = PROBE_FRACTION * self.available
                index = self.simplified(method, vertices=vertices)
            if index is None:
                break
            t = self.tessellation(self.levels[index])
            parameter = self.levels[index].parameter
            plateau = any(
                i != index
                and abs(t / t_i - 1) < 0.01
                and abs(math.log(self.levels[i].parameter / parameter)) > PLATEAU_SPAN
                for t_i, i in known_indices
                if t_i > 0
            )
            if t <= tessellation and (
                best is None or self.levels[index].vertex_count < self.levels[best].vertex_count
            ):
                best = index
            if plateau and t > tessellation:
                # Finer levels do not get closer: remember how low this simplifier gets.
                self.floor[method or ""] = min(self.floor.get(method or "", np.inf), t)
            if LEVEL_CLOSE * tessellation <= t <= tessellation or plateau:
                break
        return best

    # --- encoding -----------------------------------------------------------------------

    def encoded(self, index: int, bits: int) -> Encoded:
        """Level ``index`` encoded at ``bits`` (built once). Raises :class:`Refused` when
        the encoder cannot encode it (recorded in :attr:`refused`)."""
        level = self.levels[index]
        if (index, bits) in self.refused:
            raise Refused(self.refused[(index, bits)])
        if bits not in level.encodings:
            begin = time.perf_counter()
            try:
                if self.codec is not None:
                    level.encodings[bits] = self.codec(
                        level.vertices,
                        level.faces,
                        level.attributes,
                        bits,
                        level.origin,
                        level.grid_size,
                    )
                else:
                    level.encodings[bits] = encode(
                        (level.vertices, level.faces),
                        bits,
                        format=self.format,
                        origin=level.origin,
                        grid_size=level.grid_size,
                    )
            except MeshbitsError as err:
                self.refused[(index, bits)] = str(err)
                raise Refused(str(err)) from err
            finally:
                self.seconds["encode"] += time.perf_counter() - begin
            decoded = level.encodings[bits]
            if all_faces_degenerate(decoded.vertices, decoded.faces):
                # Nothing of the surface is left once decoded (a grid coarser than the
                # mesh): no measurement can make it an answer.
                del level.encodings[bits]
                why = "every decoded face is degenerate (no surface left)"
                self.refused[(index, bits)] = why
                raise Refused(why)
        return level.encodings[bits]

    def size_of(self, index: int, bits: int) -> float:
        """Bits of level ``index`` encoded at ``bits``; infinite when it cannot be."""
        try:
            return float(self.encoded(index, bits).size_bits)
        except Refused:
            return math.inf
