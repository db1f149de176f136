"""The search behind :func:`meshbits.compress`: the (B, V) of fewest bytes within an error
budget, or of least error within a size budget, found from measurements.

Each pass plans from what is known, builds candidates (simplify, quantize, encode: cheap
next to measuring), measures the one it ranks best, and updates:

- **Quantization error** in closed form: a mesh quantized to ``B`` bits on the cube grid
  of side ``S`` measures ``E_Q(B) = c_Q S / (2^B - 1)`` from itself, ``c_Q`` =
  :data:`QUANTIZATION_FACTOR` (0.68-0.86 on the full-resolution bunny, horse, hand and
  fandisk at every ``B`` from 6 to 20; the bound is ``sqrt(3)/2 = 0.87``).
- **Combined error** of a level with tessellation error ``t`` quantized with ``E_Q = q``:
  ``max(t, q) (1 + delta min(t, q) / max(t, q))``, ``delta`` = :data:`COMBINE_DELTA`.
  The paper adds the two (``delta = 1``); measured, the larger one dominates (over 2,500
  (level, B) pairs of those four meshes, the measured error over this form has median
  0.98-1.00 and 90th percentile 1.02-1.06 with ``delta = 0.15``).
- **Tessellation error** of a level: inverted from its measurements once measured;
  before, meshoptimizer's own estimate times ``kappa``, the measured ratio of the nearest
  measured meshopt levels (:data:`KAPPA_PRIOR` before any: the ratio is 1.8-3 on the
  bunny, hand and horse, 2.6-6 on the CAD part fandisk).
- **Size** from real encodings of the candidates.

For an error budget ``E``, each ``B`` from the least one whose quantization alone fits
(``E_Q(B) < E``) up to :data:`BITS_ABOVE` more leaves room ``t*(B)`` for tessellation;
meshoptimizer is asked for a level at the error target ``tau`` expected to give
``t*(B)`` (interpolated between the measured levels, in log-log), and the original
itself is a candidate at the least ``B``. The candidate of fewest bytes predicted to meet
``E`` is measured. A measured level that met ``E`` at some ``B`` is not tried at more
bits, one that missed it not at fewer: at a fixed level the least passing ``B`` is
sought. For a size budget ``F``, each ``B`` near the model's optimum gets the finest
level whose encoding fits ``F``, and the one of least predicted error is measured. The
search stops when no candidate promises :data:`STOP_GAIN` more than the best result so
far.

meshoptimizer's simplifier can leave a spike of the original (one vertex far from its
neighbours) far from the simplified surface: the error of a level is then far above its
target, flat over a range of vertex counts. A level whose original vertices lie farther
from it than the tessellation error it is meant to have is simplified again with those
vertices locked in place (:data:`LOCK_ROUNDS`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np

from . import model
from .codecs import Encoded, encode
from .constants import MODEL_MIN_BITS, MODEL_MIN_VERTICES
from .errors import MeshbitsError
from .hausdorff import ClosestPoints, Hausdorff, Reference
from .mesh import all_faces_degenerate, as_mesh, distinct_positions, referenced
from .quantize import cube_grid
from .results import Progress, ProgressCallback
from .simplify import Simplifier, closest_level, simplify

__all__ = [
    "BITS_ABOVE",
    "COMBINE_DELTA",
    "KAPPA_PRIOR",
    "QUANTIZATION_FACTOR",
    "STOP_GAIN",
    "Iteration",
    "Level",
    "Search",
    "allowed_tessellation",
    "combined_error",
    "interaction",
    "quantization_error",
    "run_search",
]

#: ``c_Q``: measured Hausdorff distance of a mesh to its own ``B``-bit quantization, in
#: steps ``S / (2^B - 1)`` (dimensionless).
QUANTIZATION_FACTOR = 0.81

#: ``delta`` of :func:`combined_error` (dimensionless).
COMBINE_DELTA = 0.15

#: Measured tessellation error over meshoptimizer's own estimate, before a level of the
#: mesh at hand is measured (dimensionless).
KAPPA_PRIOR = 2.5

#: Until a result meets an error budget, candidates are aimed at this fraction of it:
#: the combined-error model is within 3-6% at its 90th percentile.
AIM = 0.96

#: Once one does, candidates predicted up to this fraction of it are tried: measured
#: errors scatter around the prediction (quantization can lower a level's error), and
#: a miss costs a pass, not the result.
EXPLORE_AIM = 1.06

#: When no candidate is left after an error budget is met, a level already built that is
#: predicted up to this fraction of it is still tried, if it would be smaller (one pass
#: each, within :data:`PASSES_AFTER_MET`). On the fandisk (a CAD part, where a vertex
#: target's error jumps between nearby counts) at 0.001 S, a 455-vertex level predicted at
#: 1.175 times the budget measured 0.97 times it at B = 11: 1,787 bytes instead of 1,989
#: (the brute-force oracle's best: 1,718). Wider searches that also built levels for the
#: wider aim gave the nefertiti 14-16% bigger files (their passes after the first met
#: result went to misses).
EXPLORE_WIDE = 1.2

#: A result within an error budget is preferred when it meets it with this fraction to
#: spare: sampled distances are lower bounds, and an independent measurement with other
#: samples can find up to about 2% more (Open3D, in benches/frontier.py).
CLEAR_MARGIN = 0.015

#: The search stops when no candidate promises this relative gain (fewer bytes, or less
#: error) over the best result so far.
STOP_GAIN = 0.03

#: Passes spent looking for a better result once one meets the budget (for an original
#: of more than :data:`BASE_FACES` faces, :data:`PASSES_AFTER_MET_LARGE`).
PASSES_AFTER_MET = 2

#: Passes after a met one for a large original, where a pass costs seconds: none. (On
#: the dragon's 0.001 S budget the one pass after its first met result, 4.8 s, tried
#: B = 10 with fewer vertices and missed the budget, as every B = 10 level does there.)
PASSES_AFTER_MET_LARGE = 0

#: Bits tried above the least ``B`` whose quantization alone fits an error budget.
BITS_ABOVE = 2

#: Bits tried on each side of the model's optimum for a size budget.
BITS_AROUND = 2

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

#: Simplifications tried to reach a vertex budget (a simplifier's vertex target is
#: approximate).
VERTEX_TRIES = 3

#: Simplifications tried to fit a size budget at one B.
FIT_TRIES = 3

#: A level for a size budget is aimed at this fraction of it (Draco's bytes per vertex
#: vary by a few percent between levels)...
FIT_AIM = 0.98

#: ...and is fine once its file uses this fraction of it.
FIT_USED = 0.94

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

#: For an original of more faces than this, each simplification costs about a second:
#: ``"auto"`` takes meshoptimizer without comparing (fast-simplification takes twice as
#: long on the dragon), each B gets one level per pass and one B above the least is
#: tried.
BASE_FACES = 200_000

#: ``"auto"`` takes fast-simplification only when its quick estimate is below this
#: fraction of meshoptimizer's (with its strays locked).
AUTO_MARGIN = 0.97

#: The level a vertex-driven simplifier builds first when the model asks for every
#: vertex (as a fraction of them): fandisk at 1.26e-4 S, where the paper's model wants
#: 34,600 vertices of 6,475, has fast-simplification at 3,239 vertices measuring 4.3e-5
#: (mesh units of 5.24 S) against a budget of 6.6e-4.
PROBE_FRACTION = 0.5

#: Meshes of at most this many vertices are cheap to encode whole.
CHEAP_VERTICES = 100_000

#: Largest number of refinement points a size or vertex budget's answer spends on its
#: error bound, per direction (:func:`bound_answer`).
ANSWER_REFINE_BUDGET = 1_000_000


def quantization_error(bits: int, grid_size: float) -> float:
    """``E_Q(B) = c_Q S / (2^B - 1)`` (length): see the module docs."""
    return QUANTIZATION_FACTOR * grid_size / (2.0**bits - 1.0)


def combined_error(tessellation: float, quantization: float, delta: float = COMBINE_DELTA) -> float:
    """Predicted Hausdorff error of a level with tessellation error ``t`` quantized with
    error ``q``: ``max(t, q) (1 + delta min/max)`` (length)."""
    high, low = max(tessellation, quantization), min(tessellation, quantization)
    return high if high <= 0 else high * (1.0 + delta * low / high)


def interaction(measured: float, tessellation: float, quantization: float) -> float:
    """The ``delta`` for which :func:`combined_error` gives ``measured``, within [0, 1]
    (0 when there is no smaller part to interact with)."""
    high, low = max(tessellation, quantization), min(tessellation, quantization)
    if low <= 0:
        return 0.0
    return float(min(max((measured - high) / low, 0.0), 1.0))


def allowed_tessellation(budget: float, quantization: float, delta: float = COMBINE_DELTA) -> float:
    """The largest ``t`` whose :func:`combined_error` with ``q`` stays within ``budget``;
    negative when quantization alone exceeds it."""
    if quantization >= budget:
        return -1.0
    if quantization * (1.0 + delta) >= budget:
        return (budget - quantization) / delta
    return budget - delta * quantization


@dataclass(frozen=True)
class Iteration:
    """One pass of the search: the candidate it measured.

    Attributes
    ----------
    level : int
        Index of the mesh in :attr:`Search.levels` (0: the original).
    source : str
        What the mesh is: ``"original"``, ``"meshopt"`` (simplified to an error target),
        ``"vertices"`` (simplified to a vertex count) or ``"lod"``.
    bits : int
        Bits per coordinate B.
    planned_vertices : int
        The vertex count of the planned candidate (the plan's, for a vertex budget).
    vertices, faces : int
        Of the encoded mesh.
    predicted_error : float
        The plan's error (length).
    predicted_size_bits : float
        The size the plan chose it by (bits): candidates are encoded before one is
        chosen, so this is its encoded size, ``measured_size_bits``.
    measured_error : float
        Sampled symmetric Hausdorff distance between the original and the decoded output
        (length).
    measured_size_bits : int
        Size of the encoded file (bits).
    measured_error_upper : float or None
        With ``certify``: a certified upper bound on the true distance (length).
    met : bool
        Whether this pass met the budget.
    seconds : float
        Wall time of the pass, planning and building included.
    """

    level: int
    source: str
    bits: int
    planned_vertices: int
    vertices: int
    faces: int
    predicted_error: float
    predicted_size_bits: float
    measured_error: float
    measured_size_bits: int
    measured_error_upper: float | None
    met: bool
    seconds: float

    @property
    def decisive_error(self) -> float:
        """The error a budget is judged by: the certified bound when there is one."""
        upper = self.measured_error_upper
        return self.measured_error if upper is None else upper

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    def __str__(self) -> str:
        upper = self.measured_error_upper
        # A pass that missed its budget by a point beyond it stops refining there: its
        # bound can be far above the error and says nothing (the line says it missed).
        shown = upper is not None and (self.met or upper <= 2 * self.measured_error)
        return (
            f"pass: {self.source} mesh, B = {self.bits}, V = {self.vertices}; "
            f"error {self.measured_error:.4g}"
            + (f" (certified <= {upper:.4g})" if shown else "")
            + f" (model {self.predicted_error:.4g}) (mesh units), "
            f"{self.measured_size_bits // 8} bytes" + ("" if self.met else ": misses the budget")
        )


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

    def interactions(self, ratio: float) -> list[float]:
        """:func:`interaction` of each measurement of the level, its tessellation error
        taken as ``ratio`` times its quick estimate."""
        if self.quick is None and self.source != "original":
            return []
        t = 0.0 if self.source == "original" else ratio * float(self.quick or 0.0)
        return [
            interaction(error, t, quantization_error(bits, self.grid_size))
            for bits, error in self.errors.items()
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


#: A codec for the search: ``codec(vertices, faces, attributes, bits, origin, grid_size)``
#: returns an object with ``size_bits`` and the decoded ``vertices`` and ``faces``.
Codec = Callable[..., Any]


class Refused(MeshbitsError):
    """The encoder cannot encode a candidate (Draco refusing a mesh, say)."""


@dataclass(frozen=True)
class _Candidate:
    level: int
    bits: int
    size_bits: float
    error: float


class Search:
    """The state and steps of the search: :meth:`propose` plans (and builds) candidates
    and returns the one to measure, :meth:`measure` measures it; :func:`run_search`
    repeats them.

    Parameters
    ----------
    original : (vertices, faces)
        The welded original.
    reference : Reference
        Its BVH and samples, built once.
    constraint : {"error", "size", "vertices"}
    budget : float
        Length, bits or a vertex count.
    k : float
        The original's grid-normalised K.
    grid_size : float
        ``S`` of the original (length).
    max_bits : int
        Largest ``B`` (format and input precision).
    format : str
        Encoder.
    alpha, connectivity_bits : float
        The paper's size model, for the first plan.
    method : str or None
        ``"meshopt"``, ``"fast-simplification"``, or ``"auto"`` (both compete, see
        :meth:`simplifier_methods`); None with ``simplifier`` or ``lods``.
    simplifier : callable, optional
        ``simplifier(vertices, faces, target_vertices) -> (vertices, faces)``.
    lods : sequence of meshes, optional
        The levels to choose from, with the original.
    samples : int
        Area samples of each candidate.
    certify : bool
        Judge an error budget by a certified upper bound.
    tolerance : float or None
        Refinement tolerance of that bound (length).
    attributes : Attributes, optional
        Vertex attributes to simplify with (meshoptimizer only: they keep their seams)
        and to encode.
    codec : callable, optional
        What encodes a candidate (see :data:`Codec`); default :func:`meshbits.encode`
        in ``format``.
    """

    def __init__(
        self,
        original: tuple[np.ndarray, np.ndarray],
        reference: Reference,
        *,
        constraint: str,
        budget: float,
        k: float,
        grid_size: float,
        max_bits: int,
        format: str,
        alpha: float,
        connectivity_bits: float,
        method: str | None = "auto",
        simplifier: Simplifier | None = None,
        lods: Sequence[Any] | None = None,
        samples: int,
        certify: bool = False,
        tolerance: float | None = None,
        attributes: Attributes | None = None,
        codec: Codec | None = None,
    ) -> None:
        self.original = original
        self.attributes = attributes
        self.codec = codec
        self.reference = reference
        self.constraint = constraint
        self.budget = float(budget)
        self.k = float(k)
        self.grid_size = float(grid_size)
        self.max_bits = int(max_bits)
        self.format = format
        self.alpha = float(alpha)
        self.connectivity_bits = float(connectivity_bits)
        self.method = method
        self.simplifier = simplifier
        self.compete = (
            method == "auto"
            and simplifier is None
            and lods is None
            and attributes is None
            and len(original[1]) <= BASE_FACES
        )
        self.samples = int(samples)
        self.certify = certify
        self.tolerance = tolerance
        self.original_box = _box(original)
        self.used = referenced(original[1], len(original[0]))
        self.available = len(self.used)
        self.levels: list[Level] = []
        self.measurements: list[Iteration] = []
        #: ``(level, bits) -> why`` of each candidate the encoder refused (skipped).
        self.refused: dict[tuple[int, int], str] = {}
        self.seconds = {"simplify": 0.0, "encode": 0.0, "hausdorff": 0.0, "estimate": 0.0}
        self.plan = self._first_plan()
        #: Quick estimate of each simplifier tried by ``"auto"`` (length).
        self.simplifier_estimates: dict[str, float] = {}
        self._add(
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
                self._add(Level("lod", vertices, faces.astype(np.int64), lod=index))

    # --- models -------------------------------------------------------------------------

    def _first_plan(self) -> model.Allocation | None:
        options = {
            "grid_size": self.grid_size,
            "alpha": self.alpha,
            "connectivity_bits": self.connectivity_bits,
        }
        if self.constraint == "size":
            smallest = MODEL_MIN_VERTICES * (
                3.0 * self.alpha * MODEL_MIN_BITS + self.connectivity_bits
            )
            if self.budget < smallest:
                return None
            return model.plan_for_size(self.budget, self.k, **options)
        if self.constraint == "error":
            if self.budget >= self.grid_size:
                return None
            return model.plan_for_error(self.budget, self.k, **options)
        return model.plan_for_vertices(max(self.budget, MODEL_MIN_VERTICES), self.k, **options)

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

    def delta(self, level: Level | None = None) -> float:
        """The interaction ``delta`` to predict with: the level's own (the largest
        measured), else the mean over the measured levels with :data:`COMBINE_DELTA` as
        one more observation."""
        if level is not None and level.interactions(self.ratio(level)):
            return max(level.interactions(self.ratio(level)))
        seen = [
            max(lv.interactions(self.ratio(lv)))
            for lv in self.levels
            if lv.interactions(self.ratio(lv))
        ]
        return (COMBINE_DELTA + sum(seen)) / (1 + len(seen))

    def tessellation(self, level: Level) -> float:
        """The level's tessellation error (length): 0 for the original, else the quick
        estimate of the unquantized level times :meth:`ratio`."""
        return self.ratio(level) * self._estimate(level)

    def _estimate(self, level: Level) -> float:
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

    # --- levels -------------------------------------------------------------------------

    def _add(self, level: Level) -> int:
        """Keep a level, with the cube grid over the original's box widened to hold it (a
        simplifier may move a vertex slightly outside)."""
        low, high = _box((level.vertices, level.faces))
        level.origin, level.grid_size = cube_grid(
            np.minimum(self.original_box[0], low), np.maximum(self.original_box[1], high)
        )
        self.levels.append(level)
        return len(self.levels) - 1

    def _can_simplify(self) -> bool:
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
        if target < MODEL_MIN_VERTICES or len(self.original[1]) > BASE_FACES:
            self.method = "meshopt"
            return self.method
        fast_level = self._simplified("fast-simplification", vertices=target)
        if fast_level is None:
            self.method = "meshopt"
            return self.method
        fast = self._estimate(self.levels[fast_level])
        # meshoptimizer with the vertices it strays from beyond fast-simplification's error
        # locked: what its levels will be.
        meshopt_level = self._simplified("meshopt", vertices=target, aim=fast)
        if meshopt_level is None:
            self.method = "fast-simplification"
            return self.method
        meshopt = self._estimate(self.levels[meshopt_level])
        self.simplifier_estimates = {"meshopt": meshopt, "fast-simplification": fast}
        self.method = "fast-simplification" if fast < AUTO_MARGIN * meshopt else "meshopt"
        return self.method

    def _simplified(
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
            result, locked, attributes = _simplify_locking(
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
        return self._add(level)

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

    def _level_for(
        self, tessellation: float, aim_locks: float | None, method: str | None
    ) -> int | None:
        """A level whose tessellation error is at most ``tessellation`` and as close to
        it as a few simplifications find: the simplifier's parameter (meshopt's error
        target, or a vertex count) is interpolated in log-log between the levels built so
        far, which are judged by their measured or quick-estimated error."""
        if not self._can_simplify() or tessellation <= 0:
            return None
        by_error = method == "meshopt"
        if tessellation < 0.99 * self.floor.get(method or "", 0.0):
            return None
        best: int | None = None
        tries = LEVEL_TRIES if len(self.original[1]) <= BASE_FACES else 1
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
                tau = _interpolate(sorted(known), tessellation, 1.0 / KAPPA_PRIOR)
                tau = _stepped(tau, known, tessellation, finer_is_smaller=True)
                index = self._simplified(method, tau=tau, aim=aim_locks)
            else:
                # More vertices, less error: interpolate the vertex count against 1/t.
                inverse = sorted((1.0 / t, v) for t, v in known if t > 0)
                guess = self._paper_vertices(tessellation)
                vertices = _interpolate(inverse, 1.0 / tessellation, guess * tessellation)
                vertices = _stepped(vertices, known, tessellation, finer_is_smaller=False)
                if not known and vertices >= self.available:
                    # The model asks for the whole mesh, and nothing of this simplifier
                    # was measured yet: it can be far off (on a CAD part, flat faces meet
                    # at creases whose spheres are small), so a level of half the
                    # vertices is measured first, and later tries interpolate from it.
                    vertices = PROBE_FRACTION * self.available
                index = self._simplified(method, vertices=vertices)
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

    def _paper_vertices(self, tessellation: float) -> float:
        """The paper's ``V = K S / (3 sqrt(3) E_T)`` (Eq. 18) at half the error (what
        meshoptimizer's levels measure on the bunny)."""
        return 0.5 * self.k * self.grid_size / (3.0 * math.sqrt(3.0) * tessellation)

    def _encoded(self, index: int, bits: int) -> Encoded:
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

    def _size_of(self, index: int, bits: int) -> float:
        """Bits of level ``index`` encoded at ``bits``; infinite when it cannot be."""
        try:
            return float(self._encoded(index, bits).size_bits)
        except Refused:
            return math.inf

    def _candidate(self, index: int, bits: int) -> _Candidate | None:
        """Level ``index`` at ``bits``, encoded, with its predicted error; None when the
        encoder cannot encode it."""
        level = self.levels[index]
        error = level.errors.get(bits)
        if error is None:
            q = quantization_error(bits, level.grid_size)
            error = combined_error(self.tessellation(level), q, self.delta(level))
        size = self._size_of(index, bits)
        if not math.isfinite(size):
            return None
        return _Candidate(index, bits, size, error)

    def _tried(self, index: int, bits: int) -> bool:
        return bits in self.levels[index].errors or (index, bits) in self.refused

    # --- planning -----------------------------------------------------------------------

    def propose(self) -> _Candidate | None:
        """The next candidate to measure (built and encoded), or None when none promises
        :data:`STOP_GAIN` over the best result so far. Raises :class:`Refused` when the
        encoder refuses every candidate of the first pass."""
        candidate = self._propose()
        if candidate is None and not self.measurements:
            reasons = sorted(set(self.refused.values()))
            raise Refused(
                f"the encoder refused every candidate ({len(self.refused)} tried): "
                + "; ".join(reasons[:3])
            )
        return candidate

    def _propose(self) -> _Candidate | None:
        if self.constraint == "vertices":
            return None if self.measurements else self._vertices_candidate()
        first_met = next(
            (
                i
                for i, m in enumerate(self.measurements)
                if m.met and (self.constraint != "error" or self._clear(m))
            ),
            None,
        )
        after = PASSES_AFTER_MET_LARGE if len(self.original[1]) > BASE_FACES else PASSES_AFTER_MET
        if first_met is not None and len(self.measurements) - 1 - first_met >= after:
            return None
        best = self.best()
        if self.constraint == "error":
            ranked = sorted(self._error_candidates(), key=lambda c: (c.size_bits, c.error))
            if best is not None:
                limit = (1 - STOP_GAIN) * best.measured_size_bits
                ranked = [c for c in ranked if c.size_bits < limit]
        else:
            ranked = sorted(self._size_candidates(), key=lambda c: (c.error, c.size_bits))
            if best is not None:
                ranked = [c for c in ranked if c.error < (1 - STOP_GAIN) * best.decisive_error]
        if ranked:
            return ranked[0]
        if not self.measurements:
            return self._fallback()
        if best is None and self.constraint == "error":
            return self._last_resort()
        return self._clearing(best) or self._exploring(best)

    def _exploring(self, best: Iteration | None) -> _Candidate | None:
        """Once an error budget is met with room to spare and no candidate is left, the
        built level at a B of :meth:`_error_bits` with the fewest predicted bytes, at
        least :data:`STOP_GAIN` fewer than the best, that is predicted within
        :data:`EXPLORE_WIDE` of the budget; None when there is none. No level is built
        for it: this is a pass spent on the scatter of the predictions."""
        if self.constraint != "error" or best is None:
            return None
        limit = (1 - STOP_GAIN) * best.measured_size_bits
        wide = []
        for index, level in enumerate(self.levels):
            for bits in self._error_bits():
                if self._tried(index, bits) or not self._may_meet(level, bits):
                    continue
                if level.source == "original" and not self._original_worth_encoding(bits):
                    continue
                candidate = self._candidate(index, bits)
                if candidate is None:
                    continue
                if candidate.error <= EXPLORE_WIDE * self.budget and candidate.size_bits < limit:
                    wide.append(candidate)
        return min(wide, key=lambda c: (c.size_bits, c.error), default=None)

    def _last_resort(self) -> _Candidate | None:
        """Nothing measured meets an error budget and no level is expected to (a level
        that missed it by its certified bound, say, and the lesson scaled every level's
        estimate up): the finest level built and never measured, finer than every level
        measured, then the original, each at the least B expected to meet the budget that
        it was not measured at; None when every B was."""
        fitting = self._error_bits()
        first = fitting[0] if len(fitting) else self.max_bits
        finest_missed = max(
            (self.levels[m.level].vertex_count for m in self.measurements), default=0
        )
        finest = max(
            (
                i
                for i, level in enumerate(self.levels)
                if i > 0 and level.vertex_count > finest_missed and not level.errors
            ),
            key=lambda i: self.levels[i].vertex_count,
            default=None,
        )
        for index in [finest, 0] if finest is not None else [0]:
            for bits in range(first, self.max_bits + 1):
                if not self._tried(index, bits) and self._may_meet(self.levels[index], bits):
                    candidate = self._candidate(index, bits)
                    if candidate is not None:
                        return candidate
        return None

    def _clearing(self, best: Iteration | None) -> _Candidate | None:
        """When the best result meets an error budget without :data:`CLEAR_MARGIN` to
        spare, its level at one more bit (a last pass); else None."""
        if self.constraint != "error" or best is None or self._clear(best):
            return None
        bits = best.bits + 1
        if bits > self.max_bits or self._tried(best.level, bits):
            return None
        return self._candidate(best.level, bits)

    def _aim(self) -> float:
        """What error candidates are aimed at (length): see :data:`AIM`."""
        return (EXPLORE_AIM if self.best() is not None else AIM) * self.budget

    def _stored_bits(self, bits: int) -> int:
        """The most bits stored in the same bytes as ``bits``: a fixed-width format keeps
        each coordinate in whole bytes (float32 in PLY; 8 or 16 bits in a quantized GLB),
        so at the same size those give the least error. ``bits`` itself for Draco and a
        caller's codec."""
        if self.codec is None and self.format == "ply":
            return self.max_bits
        if self.codec is None and self.format == "glb":
            return min(8 if bits <= 8 else 16, self.max_bits)
        return bits

    def _planning_bits(self) -> range:
        """The B whose quantization error leaves the room an error budget's levels are
        planned for: the least B whose quantization alone fits, and
        :data:`BITS_ABOVE` more."""
        aim = self._aim()
        first = next(
            (b for b in range(1, self.max_bits + 1) if quantization_error(b, self.grid_size) < aim),
            None,
        )
        if first is None:
            return range(0)
        above = BITS_ABOVE if len(self.original[1]) <= BASE_FACES else 1
        return range(first, min(first + above, self.max_bits) + 1)

    def _error_bits(self) -> list[int]:
        """The B an error budget's candidates are encoded at: :meth:`_planning_bits`,
        each raised to the most bits stored in the same bytes (:meth:`_stored_bits`)."""
        return sorted({self._stored_bits(b) for b in self._planning_bits()})

    def _error_candidates(self) -> list[_Candidate]:
        """Candidates expected to meet the error budget: for each B, a level whose
        tessellation error fills the room quantization leaves; and every level built so
        far, at each B where it is expected to meet the budget."""
        aim = self._aim()
        bits_range = self._error_bits()
        for bits in self._planning_bits():
            room = allowed_tessellation(aim, quantization_error(bits, self.grid_size), self.delta())
            for method in self.simplifier_methods():
                self._level_for(room, room, method)
        out = []
        for index, level in enumerate(self.levels):
            for bits in bits_range:
                if self._tried(index, bits) or not self._may_meet(level, bits):
                    continue
                if level.source == "original" and not self._original_worth_encoding(bits):
                    continue
                candidate = self._candidate(index, bits)
                if candidate is not None and candidate.error <= aim:
                    out.append(candidate)
        return out

    def _original_worth_encoding(self, bits: int) -> bool:
        """Whether the original at ``bits`` may be the smallest candidate: always when
        encoding it is cheap or done; else unless the simplified levels' bits per vertex
        at ``bits``, halved, times its vertex count exceed the smallest of them."""
        if bits in self.levels[0].encodings or self.available <= CHEAP_VERTICES:
            return True
        sizes = [
            (lv.encodings[bits].size_bits, lv.vertex_count)
            for lv in self.levels[1:]
            if bits in lv.encodings
        ]
        if not sizes:
            return False
        rate = min(size / count for size, count in sizes)
        return 0.5 * rate * self.available < min(size for size, _ in sizes)

    def _may_meet(self, level: Level, bits: int) -> bool:
        """Whether ``bits`` is still worth trying on a level for an error budget: not
        when the level missed the budget at as many bits or more (fewer cannot do
        better), nor when it met it with fewer (more only cost bytes)."""
        for measured_bits, error in level.errors.items():
            if measured_bits >= bits and error > self.budget:
                return False
            if measured_bits < bits and error <= self.budget:
                return False
        return True

    def _size_bits(self) -> list[int]:
        centre = [round(self.plan.bits)] if self.plan is not None else [8]
        best = self.best()
        if best is not None:
            centre.append(best.bits)
        wanted = {
            b
            for c in centre
            for b in range(c - BITS_AROUND, c + BITS_AROUND + 1)
            if 1 <= b <= self.max_bits
        }
        return sorted(wanted)

    def _size_candidates(self) -> list[_Candidate]:
        """For each B near the optimum, the finest level whose encoding fits the size;
        the original at the most bits that fit; and every encoding built so far that
        fits, with each level at the most bits stored in the same bytes
        (:meth:`_stored_bits`) where that fits too."""
        for bits in self._size_bits():
            for method in self.simplifier_methods():
                self._fitting_level(bits, method)
        self._original_most_bits()
        for index, level in enumerate(self.levels):
            for bits in [b for b, e in level.encodings.items() if e.size_bits <= self.budget]:
                self._size_of(index, self._stored_bits(bits))
        out = []
        for index, level in enumerate(self.levels):
            for bits, encoded in list(level.encodings.items()):
                if encoded.size_bits <= self.budget and not self._tried(index, bits):
                    candidate = self._candidate(index, bits)
                    if candidate is not None:
                        out.append(candidate)
        return out

    def _original_most_bits(self) -> None:
        """Encode the original at the most bits whose file fits the size budget (a
        bisection on B: sizes grow with B), when that is cheap or may fit."""
        if not self._original_fits(1):
            return
        lo, hi = 1, self.max_bits
        while lo < hi:
            mid = (lo + hi + 1) // 2
            lo, hi = (mid, hi) if self._original_fits(mid) else (lo, mid - 1)

    def _fitting_level(self, bits: int, method: str | None) -> int | None:
        """The finest level whose encoding at ``bits`` fits the size budget: the original
        if it fits, else a simplification sized by the bits per vertex seen."""
        if not self._can_simplify():
            fitting = [
                i
                for i, level in enumerate(self.levels)
                if level.vertex_count <= CHEAP_VERTICES or bits in level.encodings
                if self._size_of(i, bits) <= self.budget
            ]
            return max(fitting, key=lambda i: self.levels[i].vertex_count, default=None)
        if self._original_fits(bits):
            return 0
        vertices = FIT_AIM * self.budget / self._rate(bits)
        fitting: int | None = None
        aim = FIT_AIM
        for _ in range(FIT_TRIES):
            if vertices < MODEL_MIN_VERTICES:
                break
            index = self._simplified(method, vertices=vertices, aim=self._fit_aim(vertices))
            if index is None or index == 0:
                break
            size = self._size_of(index, bits)
            count = self.levels[index].vertex_count
            if size <= self.budget:
                if fitting is None or count > self.levels[fitting].vertex_count:
                    fitting = index
                if size >= FIT_USED * self.budget:
                    break
            if size > self.budget:
                aim *= FIT_AIM  # bytes per vertex grow as levels coarsen: aim lower
            vertices = count * aim * self.budget / size
        return fitting

    def _fit_aim(self, vertices: float) -> float:
        """Where a size budget's meshopt level locks the original vertices it strays from
        (length): the tessellation error the built levels show at ``vertices`` (before
        any, the paper's Eq. 18 at half the error, which gives E_T from V as it gives V
        from E_T: :meth:`_paper_vertices`)."""
        inverse = sorted(
            (float(lv.vertex_count), 1.0 / t)
            for lv in self.levels[1:]
            if lv.method == "meshopt" and lv.quick is not None
            for t in [self.tessellation(lv)]
            if t > 0
        )
        if not inverse:
            return self._paper_vertices(vertices)
        return 1.0 / _interpolate(inverse, vertices, inverse[0][1] / inverse[0][0])

    def _original_fits(self, bits: int) -> bool:
        original = self.levels[0]
        if bits not in original.encodings and self.available > CHEAP_VERTICES:
            # Encoding a large original is worth it only when it can fit.
            rates = [
                lv.encodings[b].size_bits / lv.vertex_count
                for lv in self.levels[1:]
                for b in lv.encodings
                if b <= bits
            ]
            if not rates or 0.5 * min(rates) * self.available > self.budget:
                return False
        return self._size_of(0, bits) <= self.budget

    def _rate(self, bits: int) -> float:
        """Bits per vertex of a simplified level at ``bits``: the encodings seen at that
        B, else the paper's ``3 alpha B + T`` scaled by what was seen."""
        seen = [
            (level.encodings[b].size_bits / level.vertex_count, b)
            for level in self.levels[1:]
            for b in level.encodings
        ]
        same = [rate for rate, b in seen if b == bits]
        if same:
            return float(np.median(same))
        paper = 3.0 * self.alpha * bits + self.connectivity_bits
        if seen:
            model_rates = [3.0 * self.alpha * b + self.connectivity_bits for _, b in seen]
            scale = np.median([r / m for (r, _), m in zip(seen, model_rates, strict=True)])
            return float(scale * paper)
        return paper

    def _vertices_candidate(self) -> _Candidate | None:
        assert self.plan is not None
        bits = int(np.clip(self.plan.whole_bits, 1, self.max_bits))
        target = min(self.budget, self.available)
        if self.lods:
            index = 1 + closest_level([(lv.vertices, lv.faces) for lv in self.levels[1:]], target)
        elif target >= self.available:
            index = 0
        else:
            # A simplifier's vertex target is approximate (meshoptimizer's is a face
            # count), and the encoder may split vertices: aim lower while the encoded
            # level holds more vertices than the budget.
            method = self.simplifier_method()
            aim = target
            index = 0
            for _ in range(VERTEX_TRIES):
                index = self._simplified(method, vertices=aim) or 0
                try:
                    count = distinct_positions(self._encoded(index, bits).vertices)
                except Refused:
                    break
                if index == 0 or count <= self.budget:
                    break
                # At least 4% lower: a level within 3% of the target is reused.
                aim *= min(0.96, 0.99 * self.budget / count)
        return self._candidate(index, bits)

    def _fallback(self) -> _Candidate | None:
        """Nothing is expected to meet the budget: the most accurate output for an error
        budget, the smallest for a size budget (at the next B where the encoder refuses
        one); None when the encoder refuses every B."""
        if self.constraint == "error":
            fitting = self._error_bits()
            first = fitting[0] if len(fitting) else self.max_bits
            order = [*range(first, self.max_bits + 1), *range(first - 1, 0, -1)]
            return next(filter(None, (self._candidate(0, b) for b in order)), None)
        index = None
        if self._can_simplify():
            index = self._simplified(self.simplifier_method(), vertices=MODEL_MIN_VERTICES)
        if index is None:
            index = min(range(len(self.levels)), key=lambda i: self.levels[i].vertex_count)
        order = range(int(MODEL_MIN_BITS), self.max_bits + 1)
        return next(filter(None, (self._candidate(index, b) for b in order)), None)

    # --- measuring ----------------------------------------------------------------------

    def measure(self, candidate: _Candidate, began: float) -> Iteration:
        """Measure one candidate (its encoding is built) and record it."""
        level = self.levels[candidate.level]
        encoded = self._encoded(candidate.level, candidate.bits)
        start = time.perf_counter()
        deciding = self.certify and self.constraint == "error" and self.tolerance is not None
        h = self.reference.hausdorff(
            (encoded.vertices, encoded.faces),
            samples=self.samples,
            bounds=self.certify,
            tolerance=self.tolerance,
            check=level.source == "lod",
            threshold=self.budget if deciding else None,
        )
        self.seconds["hausdorff"] += time.perf_counter() - start
        decisive = h.distance if h.upper is None else h.upper
        level.errors[candidate.bits] = _learned(h.distance, h.upper, self.budget, deciding)
        if self.constraint == "error":
            met = decisive <= self.budget
        elif self.constraint == "size":
            met = encoded.size_bits <= self.budget
        else:
            met = distinct_positions(encoded.vertices) <= self.budget
        record = Iteration(
            level=candidate.level,
            source=level.source,
            bits=candidate.bits,
            planned_vertices=(
                round(self.plan.whole_vertices)
                if self.constraint == "vertices" and self.plan is not None
                else level.vertex_count
            ),
            vertices=distinct_positions(encoded.vertices),
            faces=len(encoded.faces),
            predicted_error=candidate.error,
            predicted_size_bits=candidate.size_bits,
            measured_error=h.distance,
            measured_size_bits=encoded.size_bits,
            measured_error_upper=h.upper,
            met=met,
            seconds=time.perf_counter() - began,
        )
        self.measurements.append(record)
        return record

    # --- results ------------------------------------------------------------------------

    def best(self) -> Iteration | None:
        """The best measurement that meets the budget: fewest bytes for an error budget,
        least error for a size budget."""
        met = [m for m in self.measurements if m.met]
        if not met:
            return None
        if self.constraint == "size":
            return min(met, key=lambda m: (m.decisive_error, m.measured_size_bits))
        return min(met, key=lambda m: (not self._clear(m), m.measured_size_bits, m.decisive_error))

    def _clear(self, measurement: Iteration) -> bool:
        """Whether a result meets an error budget with :data:`CLEAR_MARGIN` to spare (a
        sampled distance), or at all (a certified bound: the margin is for samples)."""
        if measurement.measured_error_upper is not None:
            return measurement.measured_error_upper <= self.budget
        return measurement.decisive_error <= (1 - CLEAR_MARGIN) * self.budget

    def closest(self) -> Iteration:
        """The measurement that misses the budget least: the smallest file, the fewest
        vertices, or the least sampled error (a lower bound on every measurement, where
        a certified bound refined only to decide the budget can be loose)."""
        if self.constraint == "size":
            return min(self.measurements, key=lambda m: m.measured_size_bits)
        if self.constraint == "vertices":
            return min(self.measurements, key=lambda m: m.vertices)
        return min(self.measurements, key=lambda m: m.measured_error)

    def encoded(self, measurement: Iteration) -> Encoded:
        return self.levels[measurement.level].encodings[measurement.bits]


def _learned(lower: float, upper: float | None, budget: float, deciding: bool) -> float:
    """The error the plans learn from a measurement (length). A bound refined only until
    it decides the budget says little about the error itself (it stops anywhere up to
    the budget, or at a loose value once a point beyond it is found): then the measured
    maximum (a lower bound), unless the bound exceeds the budget while that maximum does
    not (the refinement ran out of budget): the bound."""
    if upper is None:
        return lower
    if not deciding:
        return upper
    return upper if lower <= budget < upper else lower


def _simplify_locking(
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


def _interpolate(points: list[tuple[float, float]], x: float, slope: float) -> float:
    """``y(x)`` through ``(x_i, y_i)`` (increasing together), linear in log-log between
    the two around ``x``, proportional to the nearest one beyond them, ``slope * x``
    without any."""
    below = [(xi, yi) for xi, yi in points if xi <= x]
    above = [(xi, yi) for xi, yi in points if xi > x]
    if below and above:
        (x0, y0), (x1, y1) = max(below), min(above)
        if y1 > y0 > 0 and x0 > 0:
            w = math.log(x / x0) / math.log(x1 / x0)
            return y0 * (y1 / y0) ** w
        return math.sqrt(y0 * y1) if y0 > 0 else y1
    if above:
        x1, y1 = min(above)
        return y1 * x / x1
    if below:
        x0, y0 = max(below)
        return y0 * x / x0 if x0 > 0 else y0
    return slope * x


def _box(mesh: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Bounding box of the vertices some face references."""
    used = mesh[0][referenced(mesh[1], len(mesh[0]))]
    return used.min(axis=0), used.max(axis=0)


def _measure_again(search: Search, record: Iteration, **asked: Any) -> Hausdorff:
    """A result's encoded mesh measured against the original again, with ``asked`` (the
    bounds :meth:`Reference.hausdorff` takes); timed with the search's measurements."""
    encoded = search.encoded(record)
    begin = time.perf_counter()
    h = search.reference.hausdorff(
        (encoded.vertices, encoded.faces),
        samples=search.samples,
        check=search.levels[record.level].source == "lod",
        **asked,
    )
    search.seconds["hausdorff"] += time.perf_counter() - begin
    return h


def certify_answer(
    search: Search,
    tolerance: float,
    extra_passes: int,
    progress: ProgressCallback | None = None,
) -> None:
    """Certify the answer of an error-budget search that measured sampled distances.

    The best result that met the budget by its sampled distance (a lower bound) is
    measured again with a certified upper bound refined until it is within the budget or
    within ``tolerance`` of the sampled maximum (the refinement stops as soon as a point
    beyond the budget is found): within the budget, it stands; beyond, it no longer
    counts as met (its record now carries the bound) and the next best is tried. When
    none is left, the search goes on for up to ``extra_passes`` passes measuring every
    candidate certified, and their best is certified the same way. Exploring with
    samples and certifying only the answer keeps the search's plans on the sampled
    errors it was tuned on, at the price of one certified measurement per answer tried.
    """
    for round_ in range(2):
        while True:
            best = search.best()
            if best is None or best.measured_error_upper is not None:
                break
            h = _measure_again(
                search, best, bounds=True, tolerance=tolerance, threshold=search.budget
            )
            upper = float(h.upper if h.upper is not None else h.distance)
            checked = replace(
                best,
                measured_error=max(best.measured_error, h.distance),
                measured_error_upper=upper,
                met=upper <= search.budget,
            )
            search.measurements[search.measurements.index(best)] = checked
            search.levels[best.level].errors[best.bits] = _learned(
                max(best.measured_error, h.distance), upper, search.budget, True
            )
            if progress is not None:
                more = (round_ == 0 and extra_passes >= 1) or any(
                    m.met and m.measured_error_upper is None for m in search.measurements
                )
                verdict = "holds" if checked.met else "misses the budget: not met"
                if not checked.met and more:
                    verdict += ", the search goes on"
                if checked.measured_error > search.budget:
                    # The refinement stopped at a point beyond the budget: its bound then
                    # is whatever it had reached, not a measure of the error.
                    found = f"a point {checked.measured_error:.4g} away"
                else:
                    found = f"error {checked.measured_error:.4g}, certified <= {upper:.4g}"
                progress(
                    Progress(
                        "compress",
                        f"certify: B = {best.bits}, V = {best.vertices}; {found} "
                        f"(budget {search.budget:.4g}) (mesh units): {verdict}",
                        checked,
                    )
                )
            if checked.met:
                return
        if best is not None or round_ == 1 or extra_passes < 1:
            return
        search.certify, search.tolerance = True, tolerance
        run_search(search, extra_passes, progress)


def bound_answer(
    search: Search, relative_tolerance: float, progress: ProgressCallback | None = None
) -> Iteration:
    """The answer of a size or vertex budget with a certified upper bound on its error,
    refined until within ``relative_tolerance`` of each direction's sampled maximum. A
    size budget's answer is the least error: when bounding it raises its error above
    another result's sampled one, that result is bounded too, until the answer has its
    bound (bounds are compared with bounds, not with samples, which only bound below).
    A bound that does not converge within :data:`ANSWER_REFINE_BUDGET` points is not
    kept (a result whose error is spread evenly, as quantization's is on a CAD part at
    many bits, would refine nearly everywhere): the sampled error stands, as before."""
    tried: set[int] = set()
    while True:
        best = search.best() or search.closest()
        index = search.measurements.index(best)
        if best.measured_error_upper is not None or index in tried:
            return best
        tried.add(index)
        h = _measure_again(
            search, best, relative_tolerance=relative_tolerance, refine_budget=ANSWER_REFINE_BUDGET
        )
        converged = bool(h.a_to_b.converged and h.b_to_a.converged)
        bounded = replace(
            best,
            measured_error=max(best.measured_error, h.distance),
            measured_error_upper=float(h.upper) if converged and h.upper is not None else None,
        )
        search.measurements[index] = bounded
        if progress is not None:
            outcome = (
                f"certified <= {bounded.measured_error_upper:.4g}"
                if bounded.measured_error_upper is not None
                else f"no bound within {ANSWER_REFINE_BUDGET:,} refinement points"
            )
            progress(
                Progress(
                    "compress",
                    f"bound: B = {best.bits}, V = {best.vertices}; error "
                    f"{bounded.measured_error:.4g}, {outcome} (mesh units)",
                    bounded,
                )
            )


def run_search(search: Search, max_passes: int, progress: ProgressCallback | None = None) -> None:
    """Plan, build and measure until the search stops or ``max_passes`` are spent."""
    for _ in range(max_passes):
        began = time.perf_counter()
        candidate = search.propose()
        if candidate is None:
            break
        record = search.measure(candidate, began)
        if progress is not None:
            progress(Progress("compress", str(record), record))
