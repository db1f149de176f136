"""What :func:`meshbits.scene.compress_scene` reports: a line per primitive
(:class:`PrimitiveReport`: bits, vertices, bytes, the measured error and its certified
bound, in its mesh's units and in world units) and the scene's result
(:class:`SceneResult`), with the message that sums them up."""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from ..codecs.primitive import PrimitiveEncoding
from ..formats.gltf.document import Document, PrimitiveData
from ..mesh import distinct_positions, draco_drops_note, kept_shape, lost_geometry_note
from ..results import SAMPLED_ONLY
from .animation import AnimationReport
from .primitive_search import job_reference
from .primitives import Job, Outcome, distinct_vertices

__all__ = [
    "PrimitiveReport",
    "SceneResult",
    "job_report",
    "kept_report",
    "scene_result",
]


@dataclass(frozen=True)
class PrimitiveReport:
    """What compress_scene did to one primitive.

    Attributes
    ----------
    mesh, primitive : int
        Its indices in the document.
    name : str or None
        The mesh's name.
    instances : int
        Nodes that show it.
    scale : float
        The largest scale of those nodes (world units per mesh unit).
    budget : float
        Its error budget in its mesh's units (``world budget / scale``), or None.
    bits : int
        Bits per coordinate of its positions.
    normal_bits, uv_bits : int or None
        Bits of its normals (octahedral) and of its first UV set.
    input_vertices, vertices, faces : int
        Vertices in, and vertices and faces of the decoded output.
        ``input_distinct_vertices`` counts the input's vertices once per distinct position
        and attributes (an STL's corners welded). Draco's encoder splits
        the vertices of non-manifold edges, so an output of every input vertex can have
        more (Suzanne, with one edge of four faces: 507 in, 512 out of Draco at any B).
    bytes : int
        Its compressed geometry.
    error : float
        Measured Hausdorff distance to the input primitive (its mesh's units): the sampled
        maximum, raised by any larger distance the certification found (a lower bound).
    world_error : float
        ``error * scale``.
    error_upper, world_error_upper : float or None
        The certified upper bound on that distance (mesh units, and times ``scale``),
        refined until it decides the primitive's budget; None with ``certify=False``.
    met : bool
        Within its budget: by the certified bound, or with ``certify=False`` by ``error``.
    kept : str or None
        Why it was copied as it was, when it was (morph targets, no faces, compression
        that would not make it smaller, a codec that refused it).
    shared_with : tuple of (mesh, primitive)
        Other primitives reading the same accessors: one compressed geometry serves all.
    skipped : int
        Candidates of its search the codec refused (each skipped, the search went on).
    kept_area, kept_extent : float
        The fractions of its surface area and of its largest box side the output keeps;
        below 0.1 or 0.5 the scene's message warns that the geometry is lost.
    """

    mesh: int
    primitive: int
    name: str | None
    instances: int
    scale: float
    budget: float | None
    bits: int
    normal_bits: int | None
    uv_bits: int | None
    input_vertices: int
    vertices: int
    faces: int
    bytes: int
    error: float
    world_error: float
    met: bool
    kept: str | None = None
    error_upper: float | None = None
    world_error_upper: float | None = None
    input_distinct_vertices: int | None = None
    shared_with: tuple[tuple[int, int], ...] = ()
    skipped: int = 0
    kept_area: float = 1.0
    kept_extent: float = 1.0

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class SceneResult:
    """Outcome of :func:`compress_scene`.

    Attributes
    ----------
    constraint : str
        ``"error"`` or ``"size"``.
    budget : float
        World units for an error budget, bits for a size budget (as given).
    met : bool
    message : str
    codec : str
    world_error : float
        The largest world-space error of any primitive (world units).
    world_error_upper : float or None
        The largest certified bound of any primitive (world units); None with
        ``certify=False``.
    length_unit : str
        The unit of the lengths: ``"m"`` for a glTF input (its unit is the meter), else
        ``"mesh units"`` (the file's own coordinates).
    notes : tuple of str
        What reading the input left out (an OBJ's missing material library).
    budget_text, budget_unit : str
        The budget as it was given (``"0.01 x S"``, ``"0.002"``, ``"20000 bytes"``), and the
        unit of ``budget``: ``"bits"`` for a size budget, else ``length_unit``.
    animations : AnimationReport or None
        What was done to the animations: samplers compressed and copied (by why), bytes
        before and after, and the stated tolerance of every node's path (world units,
        measured, apart from the certified geometry bound).
    size_bytes : int
        The written file (GLB; for ``.gltf``, the JSON plus its buffer).
    alternatives : dict or None
        With ``codec="auto"``: each codec's ``size_bytes``, ``met``, ``world_error``,
        ``world_error_upper`` and ``seconds``; ``codec`` is the one kept.
    input_bytes : int
    primitives : tuple of PrimitiveReport
    seconds : float
    """

    constraint: str
    budget: float
    met: bool
    message: str
    codec: str
    world_error: float
    size_bytes: int
    input_bytes: int
    primitives: tuple[PrimitiveReport, ...]
    seconds: float
    files: tuple[str, ...] = ()
    world_error_upper: float | None = None
    length_unit: str = "mesh units"
    notes: tuple[str, ...] = ()
    budget_text: str = ""
    budget_unit: str = ""
    alternatives: dict[str, dict[str, Any]] | None = None
    animations: AnimationReport | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready; a size budget is also given in bytes (``budget_bytes``), as
        :class:`meshbits.CompressResult` does."""
        out = {k: v for k, v in asdict(self).items() if k != "primitives"}
        out["budget_bytes"] = self.budget / 8 if self.constraint == "size" else None
        out["primitives"] = [p.to_dict() for p in self.primitives]
        return out


def _kept_error(document: Document, job: Job, certify: bool) -> tuple[float, float | None]:
    """The error of a job written as it was (its mesh's units, and the certified bound):
    none for a glTF's own positions; for another file's, what their float32 copy in the
    document moved them by."""
    prim = document.json["meshes"][job.data.mesh]["primitives"][job.data.index]
    index = (prim.get("attributes") or {}).get("POSITION")
    if index not in document.exact_positions:
        return 0.0, 0.0 if certify else None
    stored = document.accessor(index) - job.offset
    if np.array_equal(stored, job.data.positions):
        return 0.0, 0.0 if certify else None
    reference = job_reference(job, 0)
    h = reference.hausdorff((stored, job.data.faces), bounds=certify)
    return h.distance, None if h.upper is None else float(h.upper)


def job_report(
    document: Document,
    job: Job,
    outcome: Outcome,
    encoding: PrimitiveEncoding | None,
    error: float,
    upper: float | None,
    target_error: float,
    margin: float,
    certify: bool,
    constraint: str,
) -> PrimitiveReport:
    """One job's line of the report (its first primitive's indices, the others in
    ``shared_with``)."""
    compressed = job.kept is None and encoding is not None
    if not compressed:
        error, upper = _kept_error(document, job, certify)
    world_upper = None if upper is None else upper * job.scale + margin + job.skin_rounding
    limit = target_error * (1 + 1e-12)
    if not compressed and error == 0.0:
        met = True
    elif world_upper is not None:
        met = world_upper <= limit
    else:
        # Without a bound an error budget is met only when nothing was to be certified;
        # a size budget's answer can lack one (its refinement is capped).
        met = error * job.scale <= limit and (not certify or constraint == "size")
    kept_area, kept_extent = (
        kept_shape((job.data.positions, job.data.faces), (encoding.vertices, encoding.faces))
        if compressed
        else (1.0, 1.0)
    )
    return PrimitiveReport(
        kept_area=kept_area,
        kept_extent=kept_extent,
        mesh=job.data.mesh,
        primitive=job.data.index,
        name=job.name,
        instances=job.instances,
        scale=job.scale,
        budget=target_error / job.scale,
        bits=(encoding.bits or outcome[0].bits) if compressed else 0,  # type: ignore[union-attr]
        normal_bits=job.bits.normal
        if compressed and any(n in job.data.attributes for n in ("NORMAL", "TANGENT"))
        else None,
        uv_bits=job.bits.uv.get("TEXCOORD_0") if compressed else None,
        input_vertices=len(job.data.positions),
        input_distinct_vertices=distinct_vertices(job.data.positions, job.data.attributes),
        vertices=distinct_positions(encoding.vertices)  # type: ignore[union-attr]
        if compressed
        else len(job.data.positions),
        faces=len(encoding.faces) if compressed else len(job.data.faces),  # type: ignore[union-attr]
        bytes=encoding.size_bits // 8 if compressed else 0,  # type: ignore[union-attr]
        error=error,
        world_error=error * job.scale,
        met=met,
        kept=job.kept,
        error_upper=upper,
        world_error_upper=world_upper,
        shared_with=tuple(job.targets[1:]),
        skipped=len(job.skipped) if compressed else 0,
    )


def kept_report(
    document: Document,
    data: PrimitiveData,
    instances: dict[int, list[tuple[int, np.ndarray]]],
    certify: bool,
    margin: float,
    codec: str = "meshopt",
) -> PrimitiveReport:
    """The report of a primitive with morph targets or no faces, copied as it was (its
    bound the world rounding ``margin``)."""
    if not data.morph:
        why = "no faces"
    elif codec == "draco":
        why = "morph targets (KHR_draco_mesh_compression does not compress them)"
    else:
        why = "morph targets of a Draco primitive (its decoded vertex order need not be theirs)"
    return PrimitiveReport(
        mesh=data.mesh,
        primitive=data.index,
        name=document.json["meshes"][data.mesh].get("name"),
        instances=len(instances.get(data.mesh, [])),
        scale=1.0,
        budget=None,
        bits=0,
        normal_bits=None,
        uv_bits=None,
        input_vertices=len(data.positions),
        input_distinct_vertices=distinct_vertices(data.positions, data.attributes),
        vertices=len(data.positions),
        faces=len(data.faces),
        bytes=0,
        error=0.0,
        world_error=0.0,
        met=True,
        kept=why,
        error_upper=0.0 if certify else None,
        world_error_upper=margin if certify else None,
    )


def scene_result(
    constraint: str,
    budget: float,
    certify: bool,
    codec: str,
    reports: list[PrimitiveReport],
    size_bytes: int,
    input_bytes: int,
    files: list[str],
    unit: str,
    start: float,
    notes: list[str],
    budget_text: str,
    meshes: list[tuple[np.ndarray, np.ndarray] | None],
    animations: AnimationReport | None = None,
) -> SceneResult:
    world_error = max(r.world_error for r in reports)
    bounds = [r.world_error_upper for r in reports if r.world_error_upper is not None]
    world_error_upper = max(bounds) if len(bounds) == len(reports) else None
    bound = "" if world_error_upper is None else f" (certified <= {world_error_upper:.4g})"
    if constraint == "error":
        met = all(r.met for r in reports)
        sampled = "" if certify or not met else SAMPLED_ONLY
        message = (
            f"{'met' if met else 'could not meet'} the world-space error budget of "
            f"{budget:.6g} ({unit}): largest error {world_error:.4g}{bound} ({unit}), "
            f"{size_bytes} bytes{sampled}"
        )
    else:
        met = size_bytes <= budget / 8
        message = (
            f"{'met' if met else 'could not meet'} the size budget of {budget / 8:.6g} bytes: "
            f"{size_bytes} bytes, largest world-space error {world_error:.4g}{bound} "
            f"({unit})"
        )
    message += _kept_note(reports) + _skipped_note(reports) + "".join(f"; {n}" for n in notes)
    message += animations.note() if animations is not None else ""
    message += lost_geometry_note(
        min(r.kept_area for r in reports), min(r.kept_extent for r in reports)
    )
    if not met and codec == "draco":
        message += "".join(
            draco_drops_note(*mesh, f"mesh {r.mesh} primitive {r.primitive}")
            for r, mesh in zip(reports, meshes, strict=True)
            if not r.met and mesh is not None
        )
    return SceneResult(
        constraint=constraint,
        budget=budget,
        met=met,
        message=message,
        codec=codec,
        world_error=world_error,
        size_bytes=size_bytes,
        input_bytes=input_bytes,
        primitives=tuple(reports),
        seconds=time.perf_counter() - start,
        files=tuple(files),
        world_error_upper=world_error_upper,
        length_unit=unit,
        notes=tuple(notes),
        budget_text=budget_text,
        budget_unit="bits" if constraint == "size" else unit,
        animations=animations,
    )


def _kept_note(reports: list[PrimitiveReport]) -> str:
    """The primitives written as they were, counted by why."""
    reasons: dict[str, int] = {}
    for report in reports:
        if report.kept is not None:
            count = 1 + len(report.shared_with)
            reasons[report.kept] = reasons.get(report.kept, 0) + count
    if not reasons:
        return ""
    parts = [f"{n} primitive{'s' if n > 1 else ''}: {why}" for why, n in reasons.items()]
    return f"; kept as they were: {'; '.join(parts)}"


def _skipped_note(reports: list[PrimitiveReport]) -> str:
    skipped = sum(r.skipped for r in reports)
    if not skipped:
        return ""
    return f"; {skipped} candidate{'s' if skipped > 1 else ''} the codec refused skipped"
