"""The paper's algorithm (Sec. 7) end to end: plan, simplify, quantize, encode, measure,
adjust, until the budget is met at the fewest bytes (or the least error) found.

1. Take the constraint: an error E, a file size F, or a vertex count V.
2. Compute the shape complexity K (:func:`meshbits.shape_complexity`) and the first plan
   (:mod:`meshbits.model`).
3. Search (:mod:`meshbits.search`): each pass plans a candidate (a mesh: the original, a
   simplification, or a given level of detail; and B) from the measurements so far,
   simplifies (meshoptimizer, driven by an error target), quantizes to B bits on the
   cube grid, encodes (Draco by default), and measures the real size and the Hausdorff
   distance to the original (sampled; its BVH and samples are built once).
4. Keep the best result that meets the budget; :attr:`CompressResult.met` says plainly
   whether one did.

One concept: compressing one mesh to one budget, :func:`compress` and the
:class:`CompressResult` it returns with the notes its message is made of.
"""

from __future__ import annotations

import math
import numbers
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from . import model
from .budget import Budget
from .codecs.draco import draco_max_bits
from .complexity import ShapeComplexity, shape_complexity
from .constants import (
    ANSWER_RELATIVE_TOLERANCE,
    CERTIFY_TOLERANCE,
    DRACO_ALPHA,
    DRACO_CONNECTIVITY_BITS,
    FLAT_K,
    FORMAT_MAX_BITS,
)
from .errors import MeshbitsError
from .files import write_atomic
from .formats.gltf.write import frame_centre
from .hausdorff import Reference, default_samples
from .mesh import (
    MeshLike,
    as_mesh,
    distinct_positions,
    draco_drops_note,
    kept_shape,
    lost_geometry_note,
    referenced,
    weld,
)
from .quantize import precision_bits
from .results import SAMPLED_ONLY, ArrayResult, ProgressCallback
from .search import Iteration, Refused, Search
from .simplify import METHODS, Simplifier, check_untangled, referenced_vertex_count

__all__ = ["CERTIFY_TOLERANCE", "CompressResult", "Iteration", "compress", "compress_in_frame"]


#: Fewest area samples per mesh of compress's measurements: a "met" should hold under an
#: independent measurement, and Open3D's reference pipeline in the benchmarks samples
#: 300,000 points per mesh besides the vertices.
MIN_SAMPLES = 300_000


@dataclass(frozen=True, eq=False)
class CompressResult(ArrayResult):
    """Outcome of :func:`compress`.

    Attributes
    ----------
    constraint : str
        ``"size"``, ``"error"`` or ``"vertices"``.
    budget : float
        The budget: bits for size, mesh length units for error, a count for vertices
        (``to_dict()`` also gives a size budget in bytes, ``budget_bytes``, as the batch
        report and the command line state it).
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
        step :attr:`step`) as the file stores them, not recomputed from float positions
        (see :func:`meshbits.codecs.draco_codes` for Draco's).
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
        With ``lods``, the index of the level used; None for a mesh compress made.
    source : str
        What the output's mesh is: ``"original"`` (not simplified), ``"meshopt"``,
        ``"vertices"`` (a vertex-count simplification) or ``"lod"``.
    max_bits : int
        The largest B the search could use: the output format's limit, or the input's
        precision (:func:`meshbits.precision_bits`), whichever is smaller.
    kept_area, kept_extent : float
        The fractions of the original's surface area and of its largest box side the
        output keeps; below 0.1 or 0.5 the message warns that the geometry is lost.
    skipped : tuple of str
        Candidates the encoder could not encode (each with why), skipped by the search.
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
    source: str = "original"
    max_bits: int = 30
    kept_area: float = 1.0
    kept_extent: float = 1.0
    skipped: tuple[str, ...] = ()
    frame: np.ndarray = field(default_factory=lambda: np.zeros(3), repr=False)

    @property
    def size_bytes(self) -> int:
        return len(self.data)

    @property
    def vertex_count(self) -> int:
        """The output's vertices counted once per position (V), though a decoder may get
        them split into more (:func:`meshbits.mesh.distinct_positions`)."""
        return distinct_positions(self.vertices)

    def write(self, path: str | Path) -> Path:
        """Write the encoded bytes atomically (see :func:`meshbits.files.write_atomic`).

        Raises
        ------
        MeshbitsError
            For a result of :func:`compress_in_frame` whose bytes encode the mesh moved by
            ``-frame``: a .drc or .ply of them would be elsewhere than the input.
        """
        if self.frame.any():
            raise MeshbitsError(
                f"this result's encoding is relative to a centre at {self.frame.tolist()} "
                "(mesh units) that a .drc or .ply cannot carry: write its vertices and "
                "faces (meshbits.save_mesh to .obj or .off), or compress with compress()"
            )
        return write_atomic(Path(path), self.data)

    def to_dict(self, *, arrays: bool = False) -> dict[str, Any]:
        """JSON-ready summary, never the bytes (with ``arrays=True``, also the output's
        vertices, faces and codes as nested lists)."""
        return {
            "constraint": self.constraint,
            "budget": self.budget,
            "budget_bytes": self.budget / 8 if self.constraint == "size" else None,
            "met": self.met,
            "message": self.message,
            "bits": self.bits,
            "vertices": self.vertex_count,
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
            "source": self.source,
            "max_bits": self.max_bits,
            "kept_area": self.kept_area,
            "kept_extent": self.kept_extent,
            "skipped": list(self.skipped),
            "frame": self.frame.tolist(),
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


def welded_vertex_count(mesh: MeshLike) -> int:
    """The vertices a mesh's faces use once identical positions are welded (an STL file
    repeats every shared corner): the ``V`` of the paper's model."""
    return referenced_vertex_count(weld(as_mesh(mesh))[1])


def compress(
    mesh: MeshLike,
    *,
    size: float | None = None,
    error: float | None = None,
    vertices: int | None = None,
    relative: bool = False,
    lods: Sequence[MeshLike] | None = None,
    simplifier: Simplifier | None = None,
    method: str = "auto",
    format: str = "draco",
    alpha: float = DRACO_ALPHA,
    connectivity_bits: float = DRACO_CONNECTIVITY_BITS,
    max_iterations: int = 6,
    samples: int | None = None,
    seed: int = 0,
    estimator: str = "circumsphere",
    certify: bool = True,
    progress: ProgressCallback | None = None,
) -> CompressResult:
    """Compress a mesh to meet one budget: the fewest bytes within an error budget, the
    least error within a size budget (paper Sec. 7, with the search of
    :mod:`meshbits.search`).

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
        Vertex count: B is the model's optimum for it (Eq. 12); one pass.
    lods
        Precomputed levels of detail to choose from (with the original) instead of
        simplifying.
    simplifier
        ``simplifier(vertices, faces, target_vertices) -> (vertices, faces)``, driven by
        vertex counts, instead of ``method``.
    method
        ``"auto"`` (default): on a mesh of at most 200,000 faces, levels of both below
        compete and the measurements decide (above, meshoptimizer); ``"meshopt"``
        (meshoptimizer, driven by error targets, vertices moved to their quadric optimum)
        or ``"fast-simplification"`` (vertex counts). docs/frontier.md compares them.
    format
        ``"draco"`` (default; DracoPy, ``quantization_bits=B`` on the paper's grid),
        ``"glb"`` (glTF with integer positions, KHR_mesh_quantization, B <= 16) or
        ``"ply"`` (positions quantized, stored as float32, B <= 24).
    alpha, connectivity_bits
        The size model's alpha and T (Eq. 1) for the first plan; the search then predicts
        sizes from real encodings.
    max_iterations
        Passes (candidates measured) at most; when certifying, as many more again after
        an answer whose certified bound exceeds the budget.
    samples, seed
        Sampling of the Hausdorff measurement (:func:`meshbits.hausdorff`), seeded: both
        meshes get ``samples`` area samples (default: the original's
        :func:`meshbits.hausdorff.default_samples`, at least :data:`MIN_SAMPLES`, so a
        coarse output is sampled as densely as the fine original; on Spot at 370
        vertices, sampling the output by its own face count found 71% of the error that
        1e6 samples find).
    estimator
        Estimator of K.
    certify
        Count an error budget as met only when a certified upper bound of the error
        (refined until it decides the budget) is within it (default). For a size or
        vertex budget, bound the answer's error (``error_upper``) within 5% of its
        sampled value, or leave it unbounded when a million refinement points do not get
        there (:meth:`meshbits.search.Search.bound_answer`). The search explores
        with sampled distances and certifies its answer, trying the next best when the
        bound exceeds the budget (:meth:`meshbits.search.Search.certify_answer`).
        ``False`` lets the sampled distance decide: faster, but a sample only bounds the error from
        below, and at the default density it fell short of the true distance by up to 17%
        (the cow at 0.002 S: reported 0.0194, at least 0.0236 in truth), so "met" could
        be over budget.
    progress
        Called with a :class:`meshbits.Progress` as each pass completes: ``str(event)``
        is its line, ``event.detail`` the pass's :class:`Iteration`.

    Raises
    ------
    MeshbitsError
        Bad mesh or arguments, a budget that is not a positive finite number. (A mesh
        with K = 0, a flat one, is planned with :data:`meshbits.constants.FLAT_K`.)
    """
    given = Budget.from_options(size=size, error=error, vertices=vertices, relative=relative)
    _check_options(max_iterations, format, method)
    alpha, connectivity_bits = model.size_model_parameters(alpha, connectivity_bits)
    original = weld(as_mesh(mesh))
    # A tangle (fan-triangulated polygons of hundreds of corners) takes fast-simplification
    # and the Hausdorff BVH minutes to hours: one of 245k faces on 507 vertices, 3 minutes.
    check_untangled(len(original[1]), referenced_vertex_count(original[1]), "compressed")
    start = time.perf_counter()
    complexity = shape_complexity(original, estimator=estimator)
    seconds = {"complexity": time.perf_counter() - start}
    grid_size = complexity.grid_size
    budget = given.resolve(grid_size)
    max_bits = _max_bits(original[0], grid_size, format)

    start = time.perf_counter()
    count = max(default_samples(len(original[1])), MIN_SAMPLES) if samples is None else int(samples)
    reference = Reference(original, samples=count, seed=seed)
    seconds["reference"] = time.perf_counter() - start
    search = Search(
        original,
        reference,
        constraint=given.kind,
        budget=budget,
        k=max(complexity.k, FLAT_K),
        grid_size=grid_size,
        max_bits=max_bits,
        format=format,
        alpha=alpha,
        connectivity_bits=connectivity_bits,
        method=None if (simplifier is not None or lods is not None) else method,
        simplifier=simplifier,
        lods=lods,
        samples=count,
    )
    try:
        search.run(max_iterations, progress)
    except Refused as err:
        raise MeshbitsError(
            f"no {format} output of this mesh could be encoded: {err}"
            + _unrepresentable(format, original[0], grid_size)
        ) from None
    if certify and given.kind == "error":
        search.certify_answer(CERTIFY_TOLERANCE * budget, max(2, max_iterations), progress)
    elif certify:
        search.bound_answer(ANSWER_RELATIVE_TOLERANCE, progress)
    return _result(search, original, complexity, budget, format, max_bits, seconds)


def _check_options(max_iterations: Any, format: str, method: str) -> None:
    """compress's options besides the budget and the size model, checked."""
    if isinstance(max_iterations, bool) or not isinstance(max_iterations, numbers.Integral):
        raise TypeError(f"max_iterations must be an integer, got {max_iterations!r}")
    if max_iterations < 1:
        raise MeshbitsError(f"max_iterations must be at least 1, got {max_iterations}")
    if format not in FORMAT_MAX_BITS:
        raise MeshbitsError(f"format must be one of {tuple(FORMAT_MAX_BITS)}, got {format!r}")
    if method not in (*METHODS, "auto"):
        raise MeshbitsError(f"method must be 'auto' or one of {METHODS}, got {method!r}")


def _max_bits(vertices: np.ndarray, grid_size: float, format: str) -> int:
    """The most bits B worth searching: the format's most, and no finer than the
    coordinates' precision over the grid size (float32's for the formats whose decoded
    positions are float32, Draco's quantization range)."""
    max_bits = min(FORMAT_MAX_BITS[format], precision_bits(vertices, grid_size))
    if format in ("draco", "ply"):
        # Their decoded positions are float32: bits beyond float32's spacing at the
        # coordinates' magnitude move no vertex.
        max_bits = min(max_bits, precision_bits(_as_float32(vertices), grid_size))
    if format == "draco":
        max_bits = min(max_bits, draco_max_bits(grid_size))
    return max_bits


def _result(
    search: Search,
    original: tuple[np.ndarray, np.ndarray],
    complexity: ShapeComplexity,
    budget: float,
    format: str,
    max_bits: int,
    seconds: dict[str, float],
) -> CompressResult:
    """The search's answer (the best result within the budget, else the closest) as a
    :class:`CompressResult`, its message saying why where the budget was not met."""
    constraint = search.constraint
    best = search.best()
    chosen = best or search.closest()
    met = best is not None
    encoded = search.encoded(chosen)
    level = search.levels[chosen.level]
    kept_area, kept_extent = kept_shape(original, (encoded.vertices, encoded.faces))
    skipped = tuple(
        f"level {index} ({search.levels[index].vertex_count} vertices) at {bits} bits: {why}"
        for (index, bits), why in search.refused.items()
    )
    return CompressResult(
        constraint=constraint,
        budget=budget,
        met=met,
        message=_message(constraint, budget, met, chosen, len(search.measurements))
        + _precision_note(constraint, met, chosen, max_bits, FORMAT_MAX_BITS[format])
        + _float32_note(constraint, met, budget, format, original[0])
        + skipped_note(skipped)
        + lost_geometry_note(kept_area, kept_extent)
        + (draco_drops_note(*original) if not met and format == "draco" else ""),
        kept_area=kept_area,
        kept_extent=kept_extent,
        skipped=skipped,
        bits=encoded.bits,
        vertices=encoded.vertices,
        faces=encoded.faces,
        codes=encoded.codes.astype(np.uint16 if encoded.bits <= 16 else np.uint32),
        origin=level.origin,
        step=level.grid_size / (2**encoded.bits - 1),
        error=chosen.measured_error,
        error_upper=chosen.measured_error_upper,
        size_bits=encoded.size_bits,
        data=encoded.data,
        format=encoded.format,
        plan=search.plan,
        complexity=complexity,
        iterations=tuple(search.measurements),
        level=level.lod,
        seconds=seconds | search.seconds,
        source=level.source,
        max_bits=max_bits,
    )


def compress_in_frame(mesh: MeshLike, **options: Any) -> CompressResult:
    """:func:`compress` for outputs that store float64 coordinates (OBJ, OFF): far from
    the origin the mesh is compressed relative to its centre
    (:func:`meshbits.formats.gltf.write.frame_centre`), where Draco's float32 positions
    keep their precision, and the result's vertices are moved back in float64.

    The move there is exact: the centre is a float32 within half a power of two at or
    above the mesh's size of its box's centre, so each coordinate minus it is a multiple
    of the coordinate's own spacing and no larger than it. The move back rounds each
    coordinate by at most half a float64 spacing at the output's largest coordinate
    (``sqrt(3)/2`` spacings in all): an error budget is searched with that set aside
    (the spacing at the input's largest coordinate plus the budget, which the output's
    coordinates cannot pass), and the certified bound grows by what the move rounds. The
    result's ``frame`` is the centre; its bytes are the encoding of the moved mesh that
    the search sized, so :meth:`CompressResult.write` refuses them. Options are
    :func:`compress`'s.
    """
    vertices, faces = as_mesh(mesh)
    centre = frame_centre(vertices)
    if not centre.any():
        return compress((vertices, faces), **options)
    lods = options.pop("lods", None)
    if lods is not None:
        moved_lods = []
        for lod in lods:
            lod_vertices, lod_faces = as_mesh(lod)
            moved_lods.append((lod_vertices - centre, lod_faces))
        options["lods"] = moved_lods
    moved = (vertices - centre, faces)
    given = options.get("error")
    budget = reserved = None
    if given is not None and not isinstance(given, bool) and float(given) > 0:
        # S as shape_complexity takes it: the largest side of the referenced vertices' box.
        used = moved[0][referenced(faces, len(vertices))] if options.get("relative") else None
        scale = float(np.ptp(used, axis=0).max()) if used is not None and len(used) else 1.0
        budget = float(given) * scale
        reach = float(np.abs(vertices).max(initial=0.0)) + budget
        reserve = 0.5 * math.sqrt(3) * float(np.spacing(reach))
        if 0 < reserve < budget and scale > 0:
            reserved = budget - reserve
            options["error"] = reserved / scale
    result = compress(moved, **options)
    placed = result.vertices.astype(np.float64) + centre
    rounding = 0.5 * math.sqrt(3) * float(np.spacing(np.abs(placed).max(initial=0.0)))
    upper = None if result.error_upper is None else result.error_upper + rounding
    met, message = result.met, result.message
    if reserved is not None and budget is not None:
        message = message.replace(_describe("error", result.budget), _describe("error", budget), 1)
        result = replace(result, budget=budget)
    if met and result.constraint == "error" and upper is not None and upper > result.budget:
        met = False
        message = message.replace("met the error budget", "did not meet the error budget", 1)
        message += (
            f" (moving the output back from its centre rounds it by up to "
            f"{rounding:.4g} (mesh units), which takes the certified bound to {upper:.6g})"
        )
    return replace(
        result,
        vertices=placed,
        origin=result.origin + centre,
        error_upper=upper,
        met=met,
        message=message,
        frame=centre,
    )


def _describe(constraint: str, amount: float) -> str:
    """A budget or measurement in the user's units: bytes for a size."""
    if constraint == "size":
        return f"{amount / 8:.6g} bytes"
    if constraint == "error":
        return f"{amount:.6g} (mesh units)"
    return f"{amount:.6g} vertices"


def _precision_note(
    constraint: str, met: bool, record: Iteration, max_bits: int, format_bits: int
) -> str:
    """Why B stopped below the format's most, when an error budget was missed there."""
    if met or constraint != "error" or record.bits < max_bits or max_bits >= format_bits:
        return ""
    return (
        f" (B stops at {max_bits}: over the grid size, the coordinates' floating-point "
        "precision resolves no finer, and the decoded positions are float32 too)"
    )


def skipped_note(skipped: Sequence[str]) -> str:
    """The candidates the encoder refused, counted, with the first reason."""
    if not skipped:
        return ""
    count = len(skipped)
    return f" ({count} candidate{'s' if count > 1 else ''} skipped, e.g. {skipped[0]})"


def _unrepresentable(format: str, vertices: np.ndarray, grid_size: float) -> str:
    """Why a format of float32 positions cannot hold a mesh far from the origin, when it
    cannot: float32's spacing there is coarser than a 64th of the mesh's size."""
    if format not in ("draco", "ply"):
        return ""
    largest = float(np.abs(vertices).max())
    spacing = 2 * float32_rounding(vertices) / math.sqrt(3)
    if spacing <= grid_size / 64:
        return ""
    suffix = ".drc" if format == "draco" else ".ply"
    return (
        f" ({suffix} stores float32 positions: at coordinates up to {largest:.4g} (mesh units) "
        f"float32 is spaced {spacing:.4g} apart, against a mesh of size {grid_size:.4g}; a "
        ".glb or .gltf output stores them relative to a centre its node carries)"
    )


def _as_float32(vertices: np.ndarray) -> np.ndarray:
    """The coordinates rounded to float32 (as float64), or as they are beyond its range
    (which the encoders refuse)."""
    with np.errstate(over="ignore"):
        rounded = vertices.astype(np.float32).astype(np.float64)
    return rounded if np.isfinite(rounded).all() else vertices


def float32_rounding(vertices: np.ndarray) -> float:
    """The largest distance float32 can move a vertex by rounding its coordinates (length):
    half the spacing of float32 at the largest coordinate, on each of three axes."""
    largest = float(np.abs(vertices).max(initial=0.0))
    if largest == 0 or not math.isfinite(largest):
        return 0.0
    spacing = math.ldexp(1.0, math.frexp(largest)[1] - 24)
    return 0.5 * spacing * math.sqrt(3)


#: A float32 output whose rounding alone, where the mesh lies, is more than this
#: fraction of the mesh's largest side holds no likeness of it.
FLOAT32_LIKENESS = 0.01


def _float32_note(
    constraint: str, met: bool, budget: float, format: str, vertices: np.ndarray
) -> str:
    """Why an error budget was missed by a format of float32 positions far from the
    origin; for a size budget, met or not, a warning when float32 alone rounds the mesh
    there by more than :data:`FLOAT32_LIKENESS` of its largest side (the output holds no
    likeness of it: the bunny 1.6e-7 in size at 5.4 to .ply at 30 kB was "met" as 4
    vertices 60% of its size away)."""
    if constraint == "vertices" or format not in ("draco", "ply"):
        return ""
    rounding = float32_rounding(vertices)
    largest = float(np.abs(vertices).max())
    suffix = ".drc" if format == "draco" else ".ply"
    if constraint == "size":
        side = float(np.ptp(vertices, axis=0).max()) if len(vertices) else 0.0
        if not rounding > FLOAT32_LIKENESS * side:
            return ""
        return (
            f"; warning: {suffix} stores float32 positions: at coordinates up to "
            f"{largest:.4g} (mesh units) float32 alone moves a vertex by up to "
            f"{rounding:.4g} (mesh units), {rounding / side:.3g} of the mesh's largest side: "
            "the output holds no likeness of the mesh; a .glb, .gltf, .obj or .off output "
            "keeps it"
        )
    if met or rounding <= 0.1 * budget:
        return ""
    return (
        f" ({suffix} stores float32 positions: at coordinates up to {largest:.4g} (mesh "
        f"units) float32 alone moves a vertex by up to {rounding:.4g} (mesh units), against "
        f"a budget of {budget:.4g}; a .glb or .gltf output stores them relative to a "
        "centre its node carries)"
    )


def _message(constraint: str, budget: float, met: bool, record: Iteration, passes: int) -> str:
    upper = record.measured_error_upper
    certified = "" if upper is None else f" (certified <= {upper:.4g})"
    outcome = (
        f"B = {record.bits}, V = {record.vertices}: error {record.measured_error:.4g}"
        f"{certified} (mesh units), {record.measured_size_bits // 8} bytes"
    )
    if met:
        uncertified = constraint == "error" and record.measured_error_upper is None
        sampled = SAMPLED_ONLY if uncertified else ""
        return (
            f"met the {constraint} budget of {_describe(constraint, budget)} with {outcome}"
            f"{sampled}"
        )
    closest = {
        "size": "smallest output",
        "error": "most accurate output",
        "vertices": "output with the fewest vertices",
    }[constraint]
    return (
        f"could not meet the {constraint} budget of {_describe(constraint, budget)} in "
        f"{passes} pass{'' if passes == 1 else 'es'}; the {closest} reached: {outcome}"
    )
