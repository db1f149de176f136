"""The paper's algorithm (Sec. 7) end to end: plan, simplify, quantize, encode, measure.

1. Take the constraint: a vertex count V, a file size F, or an error E.
2. Compute the shape complexity K (:func:`meshbits.shape_complexity`).
3. Solve for B and V (:mod:`meshbits.model`).
4. Pick the level of detail closest to V, or simplify to about V vertices.
5. Quantize to B bits on the bounding-box grid and encode (Draco by default).
6. Measure the real error (sampled Hausdorff distance to the *original*) and the real
   file size; when a budget is missed, rescale the constraint given to the solver by
   budget / measured and repeat.

The loop also steps the other way: a result that meets its budget with room to spare
(more than :data:`SLACK` of it unused) is retried with a looser constraint, and the best
result that meets the budget is kept. It stops when the budget is met tightly, after
``max_iterations``, or when a plan repeats; :attr:`CompressResult.met` says plainly
whether the budget was met.
"""

from __future__ import annotations

import math
import numbers
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from . import model
from .complexity import ShapeComplexity, shape_complexity
from .constants import (
    DRACO_ALPHA,
    DRACO_CONNECTIVITY_BITS,
    FORMAT_MAX_BITS,
    MODEL_MIN_BITS,
    MODEL_MIN_VERTICES,
)
from .encode import Encoded, encode
from .errors import MeshbitsError
from .hausdorff import default_samples, hausdorff
from .io import write_atomic
from .mesh import MeshLike, as_mesh
from .quantize import cube_grid, precision_bits
from .results import ArrayResult
from .simplify import (
    Simplifier,
    check_untangled,
    closest_level,
    referenced_vertex_count,
    simplify,
)

__all__ = ["SLACK", "CompressResult", "Iteration", "compress"]

#: A budget counts as met tightly when less than this fraction of it is left unused.
SLACK = 0.1

#: With ``certify=True``, the certified bound is refined to this fraction of the budget.
CERTIFY_TOLERANCE = 0.05


@dataclass(frozen=True)
class Iteration:
    """One pass of steps 3-6.

    Attributes
    ----------
    target : float
        The constraint handed to the solver in this pass (bits for size, mesh length units
        for error, a count for vertices); the first pass uses the budget itself.
    bits : int
        Whole bits per coordinate B used.
    planned_vertices : int
        V from the plan.
    vertices, faces : int
        Vertex and face counts of the encoded mesh.
    predicted_error : float
        The model's E at (B, planned V) (length).
    predicted_size_bits : float
        The model's F at (B, planned V) (bits).
    measured_error : float
        Sampled symmetric Hausdorff distance between the original and the decoded output
        (length).
    measured_size_bits : int
        Size of the encoded file (bits).
    measured_error_upper : float or None
        With ``certify=True``: a certified upper bound on the true Hausdorff distance
        (length); ``measured_error`` is then the refined sampled lower bound.
    met : bool
        Whether this pass met the budget.
    seconds : float
        Wall time of the pass.
    """

    target: float
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

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True, eq=False)
class CompressResult(ArrayResult):
    """Outcome of :func:`compress`.

    Attributes
    ----------
    constraint : str
        ``"size"``, ``"error"`` or ``"vertices"``.
    budget : float
        The budget: bits for size, mesh length units for error, a count for vertices.
    met : bool
        Whether the chosen output meets the budget (always true for a vertex count).
    message : str
        One sentence on the outcome.
    bits : int
        Bits per coordinate of the output.
    vertices, faces : ndarray
        The output as a decoder reads it back: ``(n, 3)`` float64 positions on the grid,
        ``(m, 3)`` int64 faces.
    codes : ndarray
        ``(n, 3)`` integer grid codes of the output vertices (origin :attr:`origin`,
        step :attr:`step`).
    origin : ndarray
        Grid origin, ``(3,)`` (length): the min corner of the original's bounding box
        (widened if the simplified mesh pokes out of it).
    step : float
        Grid step, ``S / (2**bits - 1)`` with S the cube grid's side (length).
    error : float
        Measured symmetric Hausdorff distance to the original (length): sampled, so a
        lower bound on the true one.
    error_upper : float or None
        With ``certify=True``, a certified upper bound on the true distance (length).
    size_bits : int
        Size of the encoded output (bits).
    data : bytes
        The encoded file.
    format : str
        ``"draco"`` or ``"ply"``.
    plan : model.Allocation or None
        The first plan, from the budget itself; None when the model has none (a size
        below a tetrahedron's, an error of S or more): the smallest output is tried.
    complexity : ShapeComplexity
        K of the original.
    iterations : tuple of Iteration
        Every pass, in order.
    level : int or None
        With ``lods``, the index of the level used.
    seconds : dict
        Wall time by phase: ``complexity``, ``simplify``, ``encode``, ``hausdorff``.
    """

    constraint: str
    budget: float
    met: bool
    message: str
    bits: int
    vertices: np.ndarray = field(repr=False)
    faces: np.ndarray = field(repr=False)
    codes: np.ndarray = field(repr=False)
    origin: np.ndarray = field(repr=False)
    step: float
    error: float
    error_upper: float | None
    size_bits: int
    data: bytes = field(repr=False)
    format: str
    plan: model.Allocation | None = field(repr=False)
    complexity: ShapeComplexity = field(repr=False)
    iterations: tuple[Iteration, ...] = field(repr=False)
    level: int | None
    seconds: dict[str, float] = field(repr=False)

    @property
    def size_bytes(self) -> int:
        return len(self.data)

    def write(self, path: str | Path) -> Path:
        """Write the encoded bytes atomically (see :func:`meshbits.io.write_atomic`)."""
        return write_atomic(Path(path), self.data)

    def to_dict(self, *, arrays: bool = False) -> dict[str, Any]:
        """JSON-ready summary, never the bytes (with ``arrays=True``, also the output's
        vertices, faces and codes as nested lists)."""
        return {
            "constraint": self.constraint,
            "budget": self.budget,
            "met": self.met,
            "message": self.message,
            "bits": self.bits,
            "vertices": len(self.vertices),
            "faces": len(self.faces),
            "error": self.error,
            "error_upper": self.error_upper,
            "size_bits": self.size_bits,
            "size_bytes": self.size_bytes,
            "format": self.format,
            "step": self.step,
            "grid_size": self.complexity.grid_size,
            "k": self.complexity.k,
            "level": self.level,
            "plan": None if self.plan is None else self.plan.to_dict(),
            "iterations": [it.to_dict() for it in self.iterations],
            "seconds": dict(self.seconds),
        } | (
            {
                "output_vertices": self.vertices.tolist(),
                "output_faces": self.faces.tolist(),
                "codes": self.codes.tolist(),
            }
            if arrays
            else {}
        )


def _weld(mesh: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Merge vertices with identical coordinates (STL files are triangle soups: without
    this the simplifier sees no shared edge)."""
    vertices, faces = mesh
    unique, inverse = np.unique(vertices, axis=0, return_inverse=True)
    if len(unique) == len(vertices):
        return mesh
    return as_mesh(unique, inverse.reshape(-1)[faces])


def _box(mesh: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Bounding box of the vertices some face references."""
    used = mesh[0][np.unique(mesh[1])]
    return used.min(axis=0), used.max(axis=0)


def _grid(
    original_box: tuple[np.ndarray, np.ndarray], level: tuple[np.ndarray, np.ndarray]
) -> tuple[np.ndarray, float]:
    """Cube grid (origin, side) over the original's box, widened to hold the level: a
    simplifier may move a vertex slightly outside the original's box."""
    level_lo, level_hi = _box(level)
    return cube_grid(np.minimum(original_box[0], level_lo), np.maximum(original_box[1], level_hi))


def _plan(
    constraint: str, target: float, k: float, grid_size: float, alpha: float, t: float
) -> model.Allocation | None:
    """The model's plan for the constraint; None where it has none because the smallest
    mesh it knows already meets the target (an error of S or more) or exceeds it (a size
    below a tetrahedron's)."""
    options = {"grid_size": grid_size, "alpha": alpha, "connectivity_bits": t}
    if constraint == "size":
        smallest = MODEL_MIN_VERTICES * (3.0 * alpha * MODEL_MIN_BITS + t)
        return model.plan_for_size(target, k, **options) if target >= smallest else None
    if constraint == "error":
        return model.plan_for_error(target, k, **options) if target < grid_size else None
    return model.plan_for_vertices(target, k, **options)


def _meets(constraint: str, budget: float, error: float, size_bits: int) -> bool:
    if constraint == "size":
        return size_bits <= budget
    if constraint == "error":
        return error <= budget
    return True


def _slack(constraint: str, budget: float, error: float, size_bits: int) -> float:
    """Unused fraction of the budget (0 for a vertex count)."""
    if constraint == "size":
        return 1.0 - size_bits / budget
    if constraint == "error":
        return 1.0 - error / budget
    return 0.0


def compress(
    mesh: MeshLike,
    *,
    size: float | None = None,
    error: float | None = None,
    vertices: int | None = None,
    relative: bool = False,
    lods: Sequence[MeshLike] | None = None,
    simplifier: Simplifier | None = None,
    format: str = "draco",
    alpha: float = DRACO_ALPHA,
    connectivity_bits: float = DRACO_CONNECTIVITY_BITS,
    max_iterations: int = 6,
    samples: int | None = None,
    seed: int = 0,
    estimator: str = "circumsphere",
    certify: bool = False,
    progress: Callable[[Iteration], None] | None = None,
) -> CompressResult:
    """Compress a mesh to meet one budget, choosing B and V by the paper's model (Sec. 7).

    Parameters
    ----------
    mesh
        ``trimesh.Trimesh`` or ``(vertices, faces)``; vertices with identical coordinates
        are welded first.
    size
        File-size budget in **bits** (the CLI parses "100KB").
    error
        Error budget: the symmetric Hausdorff distance to the original, in the mesh's
        length unit, or relative to the grid size S (largest bounding-box side) with
        ``relative=True``.
    vertices
        Vertex count: B is the model's optimum for it (Eq. 12); nothing to iterate.
    lods
        Precomputed levels of detail: step 4 picks the one closest to the plan's V
        instead of simplifying.
    simplifier
        ``simplifier(vertices, faces, target_vertices) -> (vertices, faces)``; default
        :func:`meshbits.simplify.simplify` (fast-simplification).
    format
        ``"draco"`` (default; DracoPy, ``quantization_bits=B`` on the paper's grid),
        ``"glb"`` (glTF with integer positions, KHR_mesh_quantization, B <= 16) or
        ``"ply"`` (positions quantized, stored as float32). The size model's defaults are
        fitted to Draco: pass ``alpha`` and ``connectivity_bits`` for the others, or let
        the loop correct the size.
    alpha, connectivity_bits
        The size model's alpha and T (Eq. 1). The defaults are fitted to Draco at
        compression level 7 (see :func:`meshbits.encode.fit_size_model` and
        ``meshbits calibrate``); the loop corrects for any misfit.
    max_iterations
        Passes of steps 3-6 at most.
    samples, seed
        Sampling of the Hausdorff measurement (:func:`meshbits.hausdorff`), seeded. By
        default both meshes get the area samples that the finer one would get alone
        (10 per face of the finer mesh, within [1e4, 1e6]): the distance to the fine
        original varies at the scale of its own triangles, so the coarse output must be
        sampled that densely too (on Spot at 370 vertices, sampling the output by its own
        face count found 71% of the error that 1e6 samples find).
    estimator
        Estimator of K.
    certify
        Measure with a certified upper bound (:func:`meshbits.hausdorff` with
        ``bounds=True``, refined to a tolerance of :data:`CERTIFY_TOLERANCE` times the
        budget) and count an error budget as met only when that *upper bound* is within
        it. Slower; without it the sampled distance (a lower bound) decides.
    progress
        Called with each :class:`Iteration` as it completes.
    """
    given = [
        name
        for name, value in (("size", size), ("error", error), ("vertices", vertices))
        if value is not None
    ]
    if len(given) != 1:
        raise MeshbitsError(f"give exactly one of size, error, vertices (got {given or 'none'})")
    constraint = given[0]
    if isinstance(max_iterations, bool) or not isinstance(max_iterations, numbers.Integral):
        raise TypeError(f"max_iterations must be an integer, got {max_iterations!r}")
    if max_iterations < 1:
        raise MeshbitsError(f"max_iterations must be at least 1, got {max_iterations}")
    if format not in ("draco", "glb", "ply"):
        raise MeshbitsError(f"format must be 'draco', 'glb' or 'ply', got {format!r}")
    value = {"size": size, "error": error, "vertices": vertices}[constraint]
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"the {constraint} budget must be a real number, got {value!r}")
    try:
        budget = float(value)
    except OverflowError:  # an int beyond the float range
        budget = math.inf
    if not math.isfinite(budget) or budget <= 0:
        raise MeshbitsError(
            f"the {constraint} budget must be a positive finite number, got {value}"
        )
    alpha = model._scalar(model._alpha(alpha), "alpha")
    connectivity_bits = model._scalar(
        model._nonnegative("connectivity_bits", connectivity_bits), "connectivity_bits"
    )
    original = _weld(as_mesh(mesh))
    available = referenced_vertex_count(original[1])
    # A tangle (fan-triangulated polygons of hundreds of corners) takes fast-simplification
    # and the Hausdorff BVH minutes to hours: one of 245k faces on 507 vertices, 3 minutes.
    check_untangled(len(original[1]), available, "compressed")
    seconds = {"complexity": 0.0, "simplify": 0.0, "encode": 0.0, "hausdorff": 0.0}

    start = time.perf_counter()
    complexity = shape_complexity(original, estimator=estimator)
    seconds["complexity"] = time.perf_counter() - start
    grid_size = complexity.grid_size
    if complexity.k <= 0:
        raise MeshbitsError(
            "the mesh has K = 0 (flat or all edges skipped): the model has no answer"
        )

    if constraint == "error" and relative:
        budget *= grid_size
    original_box = _box(original)
    max_bits = min(FORMAT_MAX_BITS[format], precision_bits(original[0], grid_size))
    simplify_to = simplifier or (lambda v, f, n: simplify((v, f), n))

    simplified_cache: dict[int, tuple[tuple[np.ndarray, np.ndarray], int | None]] = {}

    def level_for(target_vertices: int) -> tuple[tuple[np.ndarray, np.ndarray], int | None]:
        key = int(target_vertices)
        if lods is not None:
            index = closest_level(lods, key)
            return as_mesh(lods[index]), index
        if key not in simplified_cache:
            begin = time.perf_counter()
            if key >= available:
                simplified_cache[key] = (original, None)
            else:
                # Start from the coarsest level made so far that still has enough
                # vertices: later passes then reduce a small mesh, not the original.
                finer = [
                    mesh
                    for mesh, _ in simplified_cache.values()
                    if mesh is not original and len(mesh[0]) >= key
                ]
                source = min(finer, key=lambda mesh: len(mesh[0])) if finer else original
                v, f = simplify_to(source[0], source[1], key)
                simplified_cache[key] = (as_mesh(v, f), None)
            seconds["simplify"] += time.perf_counter() - begin
        return simplified_cache[key]

    first_plan: model.Allocation | None = None
    target = budget
    iterations: list[Iteration] = []
    best: tuple[Encoded, int | None, Iteration, np.ndarray, float] | None = None
    fallback: tuple[Encoded, int | None, Iteration, np.ndarray, float] | None = None
    tried: set[tuple[int, int]] = set()
    passing: float | None = None
    failing: float | None = None
    for _ in range(max_iterations):
        begin = time.perf_counter()
        plan = _plan(constraint, target, complexity.k, grid_size, alpha, connectivity_bits)
        if not iterations:
            first_plan = plan
        if plan is None:
            # Below the model's smallest mesh (a size) or above its largest error: the
            # smallest output there is.
            bits, planned = int(MODEL_MIN_BITS), int(min(MODEL_MIN_VERTICES, available))
        else:
            bits = int(np.clip(plan.whole_bits, 1, max_bits))
            planned = int(np.clip(round(plan.whole_vertices), 4, available))
        if constraint == "vertices":
            planned = int(min(budget, available))
        if (bits, planned) in tried:
            break
        tried.add((bits, planned))
        level_mesh, level = level_for(planned)

        t0 = time.perf_counter()
        origin, size_of_grid = _grid(original_box, level_mesh)
        encoded = encode(level_mesh, bits, format=format, origin=origin, grid_size=size_of_grid)
        seconds["encode"] += time.perf_counter() - t0
        t0 = time.perf_counter()
        measurement = hausdorff(
            original,
            (encoded.vertices, encoded.faces),
            samples=samples or default_samples(max(len(original[1]), len(encoded.faces))),
            seed=seed,
            statistics=False,
            bounds=certify,
            tolerance=CERTIFY_TOLERANCE * budget if certify and constraint == "error" else None,
        )
        measured = measurement.distance
        upper = measurement.upper if certify else None
        seconds["hausdorff"] += time.perf_counter() - t0

        decisive = measured if upper is None else upper
        met = _meets(constraint, budget, decisive, encoded.size_bits)
        record = Iteration(
            target=float(target),
            bits=bits,
            planned_vertices=planned,
            vertices=len(encoded.vertices),
            faces=len(encoded.faces),
            predicted_error=float(model.error(bits, planned, complexity.k, grid_size)),
            predicted_size_bits=float(
                model.file_size(bits, planned, alpha=alpha, connectivity_bits=connectivity_bits)
            ),
            measured_error=float(measured),
            measured_size_bits=encoded.size_bits,
            measured_error_upper=upper,
            met=met,
            seconds=time.perf_counter() - begin,
        )
        iterations.append(record)
        if progress is not None:
            progress(record)
        if met and (best is None or _better(constraint, record, best[2])):
            best = (encoded, level, record, origin, size_of_grid)
        if fallback is None or _closer(constraint, budget, record, fallback[2]):
            fallback = (encoded, level, record, origin, size_of_grid)
        if constraint == "vertices" or (lods is not None and met):
            break
        if met:
            passing = target if passing is None else max(passing, target)
            if _slack(constraint, budget, decisive, encoded.size_bits) < SLACK:
                break
        else:
            failing = target if failing is None else min(failing, target)
        measured_amount = decisive if constraint == "error" else encoded.size_bits
        # An exact reproduction measures 0: any coarser output is worth a try.
        ratio = budget / measured_amount if measured_amount > 0 else math.inf
        next_target = _next_target(target, ratio, passing, failing)
        if next_target is None or (constraint == "error" and next_target >= grid_size):
            break
        target = next_target

    chosen = best or fallback
    assert chosen is not None
    encoded, level, record, origin, size_of_grid = chosen
    met = best is not None
    step = size_of_grid / (2**encoded.bits - 1)
    codes = np.rint((encoded.vertices - origin) / step).astype(
        np.uint16 if encoded.bits <= 16 else np.uint32
    )
    message = _message(constraint, budget, met, record, len(iterations))
    return CompressResult(
        constraint=constraint,
        budget=budget,
        met=met,
        message=message,
        bits=encoded.bits,
        vertices=encoded.vertices,
        faces=encoded.faces,
        codes=codes,
        origin=origin,
        step=step,
        error=record.measured_error,
        error_upper=record.measured_error_upper,
        size_bits=encoded.size_bits,
        data=encoded.data,
        format=encoded.format,
        plan=first_plan,
        complexity=complexity,
        iterations=tuple(iterations),
        level=level,
        seconds=seconds,
    )


#: Largest factor by which one pass may change the solver's constraint.
MAX_STEP = 4.0


def _next_target(
    target: float, ratio: float, passing: float | None, failing: float | None
) -> float | None:
    """The constraint for the next pass, or None when the bracket has closed.

    ``ratio`` is budget / measured. Raising the constraint (a larger size or error) uses
    more of the budget; ``passing`` is the largest constraint that met the budget so far
    and ``failing`` the smallest that missed it. Until both exist, step by the ratio
    (aiming a little inside the budget, at most :data:`MAX_STEP` per pass); then bisect
    on a log scale.
    """
    step = float(np.clip(ratio * (1 - SLACK / 2), 1 / MAX_STEP, MAX_STEP))
    proposal = target * step
    if passing is not None and failing is not None:
        if failing / passing < 1 + SLACK / 4:
            return None
        if not passing < proposal < failing:
            proposal = float(np.sqrt(passing * failing))
    return proposal


def _describe(constraint: str, amount: float) -> str:
    """A budget or measurement in the user's units: bytes for a size."""
    if constraint == "size":
        return f"{amount / 8:.6g} bytes"
    if constraint == "error":
        return f"{amount:.6g} (mesh units)"
    return f"{amount:.6g} vertices"


def _message(constraint: str, budget: float, met: bool, record: Iteration, passes: int) -> str:
    outcome = (
        f"B = {record.bits}, V = {record.vertices}: error {record.measured_error:.4g} "
        f"(mesh units), {record.measured_size_bits // 8} bytes"
    )
    if met:
        return f"met the {constraint} budget of {_describe(constraint, budget)} with {outcome}"
    closest = {"size": "smallest output", "error": "most accurate output"}[constraint]
    return (
        f"could not meet the {constraint} budget of {_describe(constraint, budget)} in "
        f"{passes} passes; the {closest} reached: {outcome}"
    )


def _better(constraint: str, a: Iteration, b: Iteration) -> bool:
    """Among results that meet the budget: smaller error for size, smaller file otherwise."""
    if constraint == "size":
        return a.measured_error < b.measured_error
    return a.measured_size_bits < b.measured_size_bits


def _closer(constraint: str, budget: float, a: Iteration, b: Iteration) -> bool:
    """Among results that miss the budget: the one that misses it least."""
    if constraint == "size":
        return a.measured_size_bits < b.measured_size_bits
    return a.measured_error < b.measured_error
