"""A scene compressed whole (:func:`compress_scene`): every triangle primitive of a glTF
document (or of an OBJ, PLY... read as one) to one world-space error budget, or a size
budget split across them, and the document written around them with everything else
kept. The error budget is a world-space length: a primitive's error is its mesh's error
times the largest scale of the nodes that instance it."""

from __future__ import annotations

import copy
import json
import os
import tempfile
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..budget import Budget
from ..codecs.attributes import NORMAL_TOLERANCE_DEGREES
from ..codecs.primitive import PrimitiveEncoding
from ..errors import MeshbitsError, MeshFileError, UnreachableBudgetError
from ..files import asset_bytes, check_not_an_input
from ..formats.gltf.document import Document, PrimitiveData
from ..formats.gltf.write import (
    CompressedGeometry,
    EncodedAnimations,
    document_size,
    image_key,
    rebuild_document,
    write_document,
)
from ..formats.open import load_document
from ..results import Progress, ProgressCallback
from ..units import length_unit_of
from .animation import AnimationReport, compress_animations
from .primitive_search import search_primitive
from .primitives import (
    Job,
    Outcome,
    decoded_primitives,
    place_in_frames,
    plan_jobs,
    world_box,
)
from .report import PrimitiveReport, SceneResult, job_report, kept_report, scene_result
from .shared_grid import Encodings, final_encodings
from .skins import settle_skin_rounding
from .split import RunAt, size_one, split_size

__all__ = ["CODECS", "WORLD_ROUNDING", "better_codec", "compress_scene", "scene_document"]

#: Codecs of :func:`compress_scene`; ``"auto"`` tries both and keeps the better file.
CODECS = ("draco", "meshopt", "auto")

#: Relative float64 rounding of a world position a reader composes from the file (node
#: transforms applied to float32 or integer positions), bounded generously: every
#: certified world-space bound is raised by this times the largest world coordinate.
WORLD_ROUNDING = 16 * 2.0**-52


def compress_scene(
    source: str | Path | Document,
    *,
    error: float | None = None,
    size: float | None = None,
    relative: bool = False,
    codec: str = "auto",
    normal_tolerance: float = NORMAL_TOLERANCE_DEGREES,
    output: str | Path | None = None,
    seed: int = 0,
    certify: bool = True,
    progress: ProgressCallback | None = None,
    animation_tolerance: float | None = None,
) -> SceneResult:
    """Compress every triangle primitive of a scene to one world-space budget and write
    the scene with everything else kept.

    Primitives whose attributes and indices are the same accessors are compressed once
    and keep sharing their data. A primitive (with every primitive sharing its meshes'
    frame) whose compressed data would not be smaller than its input's is written as it
    was; a glTF input whose compressed file would be larger than itself is written as it
    was (byte for byte, ``.glb`` to ``.glb``).

    Parameters
    ----------
    source
        A ``.glb`` / ``.gltf`` file, an OBJ (with MTL and textures), a PLY (with colours),
        or any mesh trimesh reads; or a :class:`meshbits.formats.Document`.
    error
        World-space error budget: the Hausdorff distance of every primitive, scaled by the
        largest scale of the nodes that instance it, in world units (or with ``relative``, as
        a fraction of the largest side of the scene's world bounding box).
    size
        Size budget of the whole file, in **bits** (the CLI parses "100KB").
    codec
        ``"draco"`` (``KHR_draco_mesh_compression``), ``"meshopt"``
        (``EXT_meshopt_compression`` with ``KHR_mesh_quantization``), or ``"auto"``: the
        scene compressed with each, and the better file kept (:func:`better_codec`): the
        result's ``codec`` names it and ``alternatives`` what the other gave.
    normal_tolerance
        Largest angle (degrees) between a normal or tangent and its quantized value.
    output
        ``.glb`` or ``.gltf`` to write (atomically; a ``.gltf``'s buffer goes beside it,
        named after it). None: nothing written.
    seed
        Seed of every measurement.
    certify
        Judge each primitive's budget by a certified upper bound of its error (default),
        not by the sampled distance, which only bounds it from below.
    progress
        Called with a :class:`meshbits.Progress` per primitive searched (``str(event)``
        is its line).
    animation_tolerance
        How far any node, and what it carries, may move off its animated path (world
        units, docs/scenes.md). None: the world error (budget, or found); 0: copied.

    Returns
    -------
    SceneResult
    """
    start = time.perf_counter()
    given = _check_scene_arguments(error, size, relative, codec, normal_tolerance, output)
    _check_animation_tolerance(animation_tolerance)
    if codec == "auto":
        options = dict(error=error, size=size, relative=relative, seed=seed)
        options.update(normal_tolerance=normal_tolerance, certify=certify, progress=progress)
        options.update(animation_tolerance=animation_tolerance)
        return _compress_with_either(source, output, options)
    constraint = given.kind
    scene = _plan(source, output, normal_tolerance, codec)
    budget = given.resolve(scene.world_size)
    jobs = scene.jobs
    outcomes, target_error = _search(scene, constraint, budget, codec, seed, certify, progress)
    encodings = final_encodings(jobs, outcomes, codec, certify, target_error, scene.margin, seed)
    tolerance = target_error if animation_tolerance is None else animation_tolerance
    animations, animation_report = compress_animations(
        scene.document, tolerance, codec == "meshopt"
    )
    settle_skin_rounding(scene.document, jobs, encodings[0])
    files, size_bytes, verbatim = _write(
        scene.document, jobs, encodings[0], codec, source, output, scene.input_bytes, animations
    )
    if verbatim:
        animation_report = AnimationReport.input_kept(animation_report)
    return scene_result(
        constraint,
        budget,
        certify,
        codec,
        _reports(scene, outcomes, encodings, target_error, certify, constraint),
        size_bytes,
        scene.input_bytes,
        files,
        scene.unit,
        start,
        scene.document.notes,
        given.describe(),
        [(job.data.positions, job.data.faces) for job in jobs] + [None] * len(scene.kept),
        animation_report,
    )


def _search(
    scene: _Planned,
    constraint: str,
    budget: float,
    codec: str,
    seed: int,
    certify: bool,
    progress: ProgressCallback | None,
) -> tuple[list[Any], float]:
    """Every primitive's outcome and the world error they were searched at: the budget
    itself for an error budget, the largest error that fits for a size budget."""
    jobs = scene.jobs
    run_at = _run_at(jobs, codec, seed, certify, scene.margin, scene.unit, progress)
    if not jobs:
        return [], budget if constraint == "error" else 0.0
    if constraint == "error":
        return run_at(budget), budget
    return _size_search(
        scene.document, jobs, budget, codec, seed, certify, run_at, scene.world_size
    )


def better_codec(results: dict[str, SceneResult]) -> str:
    """The codec whose file is better: one that meets the budget over one that does not;
    then, for an error budget, the fewer bytes; for a size budget, the smaller certified
    world error (the sampled one without certification). Ties go to the first given."""

    def rank(name: str) -> tuple[bool, float]:
        result = results[name]
        if result.constraint == "size":
            error = result.world_error_upper
            return (not result.met, result.world_error if error is None else error)
        return (not result.met, result.size_bytes)

    return min(results, key=rank)


def _compress_with_either(
    source: str | Path | Document, output: str | Path | None, options: dict[str, Any]
) -> SceneResult:
    """``codec="auto"``: the scene compressed with Draco and with meshopt, each written
    into a folder of its own beside ``output``, and the better file moved into place
    (its ``.bin`` with it). The result is the chosen codec's, with ``alternatives``
    saying what each gave and its message which was chosen."""
    if output is not None and not isinstance(source, Document):
        check_not_an_input(output, source)
    results: dict[str, SceneResult] = {}
    folder = None if output is None else Path(output).resolve().parent
    with tempfile.TemporaryDirectory(dir=folder, prefix=".meshbits-") as scratch:
        for codec in ("draco", "meshopt"):
            target = None if output is None else Path(scratch) / codec / Path(output).name
            if target is not None:
                target.parent.mkdir()
            own = copy.deepcopy(source) if isinstance(source, Document) else source
            results[codec] = compress_scene(own, codec=codec, output=target, **options)
        chosen = better_codec(results)
        files = []
        for name in results[chosen].files:
            destination = Path(output).with_name(Path(name).name) if output else Path(name)
            os.replace(name, destination)
            files.append(str(destination))
    other = next(c for c in results if c != chosen)
    note = (
        f"; codec auto: {chosen} ({results[chosen].size_bytes} bytes) over {other} "
        f"({results[other].size_bytes} bytes{'' if results[other].met else ', unmet'})"
    )
    return replace(
        results[chosen],
        message=results[chosen].message + note,
        files=tuple(files),
        seconds=sum(r.seconds for r in results.values()),
        alternatives={codec: _alternative(result) for codec, result in results.items()},
    )


def _alternative(result: SceneResult) -> dict[str, Any]:
    """What one codec gave, for ``SceneResult.alternatives``."""
    return {
        "size_bytes": result.size_bytes,
        "met": result.met,
        "world_error": result.world_error,
        "world_error_upper": result.world_error_upper,
        "seconds": result.seconds,
    }


@dataclass
class _Planned:
    """A scene read and planned: its document, the input's bytes (0 for a document given
    in memory), the unit of its lengths, its meshes' instances, the jobs to compress and
    the primitives kept as they are, the largest side of its world box and the world
    rounding margin (world units)."""

    document: Document
    input_bytes: int
    unit: str
    instances: dict[int, list[tuple[int, np.ndarray]]]
    jobs: list[Job]
    kept: list[PrimitiveData]
    world_size: float
    margin: float
    codec: str


def _plan(source: Any, output: str | Path | None, normal_tolerance: float, codec: str) -> _Planned:
    """Read the scene, group its primitives into jobs and place them in frames."""
    document, input_bytes = _read_source(source, output)
    # A glTF's lengths are meters; another file's are its own coordinates, as its JSON
    # report says (``length_unit``).
    unit = "m" if isinstance(source, Document) else length_unit_of(source)
    instances = document.mesh_instances()
    where = "" if isinstance(source, Document) else f"{source}: "
    primitives = decoded_primitives(document, where)
    jobs, kept = plan_jobs(document, primitives, instances, normal_tolerance, where, codec)
    if not jobs and not kept:
        raise MeshFileError("the scene has no triangle primitive")
    place_in_frames(jobs, kept, document)
    world_size, reach = world_box(primitives, instances)
    # The world positions a reader computes (float32 values through float64 node
    # transforms) carry float64 rounding that the measurement in each mesh's frame does
    # not: every bound is raised by it.
    margin = WORLD_ROUNDING * reach
    return _Planned(document, input_bytes, unit, instances, jobs, kept, world_size, margin, codec)


def _reports(
    scene: _Planned,
    outcomes: list[Outcome],
    encodings: Encodings,
    target_error: float,
    certify: bool,
    constraint: str,
) -> list[PrimitiveReport]:
    """A report per job (its first primitive's), then one per primitive kept."""
    reports = [
        job_report(
            scene.document,
            job,
            outcome,
            encoding,
            error,
            upper,
            target_error,
            scene.margin,
            certify,
            constraint,
        )
        for job, outcome, encoding, error, upper in zip(
            scene.jobs, outcomes, *encodings, strict=True
        )
    ]
    return reports + [
        kept_report(scene.document, data, scene.instances, certify, scene.margin, scene.codec)
        for data in scene.kept
    ]


def _read_source(source: Any, output: str | Path | None) -> tuple[Document, int]:
    """The scene's document and the input's bytes (0 for a document given in memory);
    an output that is the input, or a source that is no file nor document, refused."""
    if output is not None and not isinstance(source, Document):
        check_not_an_input(output, source)
    if not isinstance(source, (str, Path, Document)):
        raise TypeError(
            f"compress_scene takes a file path or a meshbits.formats.Document, got "
            f"{type(source).__name__}: for a mesh in memory use meshbits.compress, or export "
            "the scene to a .glb first"
        )
    if isinstance(source, Document):
        return source, 0
    return load_document(source), asset_bytes(source)


def _run_at(
    jobs: list[Job],
    codec: str,
    seed: int,
    certify: bool,
    margin: float,
    unit: str,
    progress: ProgressCallback | None,
) -> RunAt:
    """Every job searched within one common world error (its local budget that error,
    less the world rounding ``margin``, over its scale), each answer told to
    ``progress``."""

    def run_at(world_error: float) -> list[Outcome]:
        outcomes = []
        for job in jobs:
            local = max(world_error - margin - job.skin_rounding, world_error / 2) / job.scale
            outcome = search_primitive(job, local, codec, seed, certify)
            outcomes.append(outcome)
            if outcome[0] is not None and progress is not None:
                progress(
                    Progress(
                        "compress_scene",
                        f"mesh {job.data.mesh} primitive {job.data.index} within "
                        f"{world_error:.4g}: B = {outcome[0].bits}, V = {outcome[0].vertices}, "
                        f"{outcome[1].size_bits // 8} bytes, error "
                        f"{outcome[0].measured_error * job.scale:.4g} ({unit})",
                    )
                )
        return outcomes

    return run_at


def scene_document(
    document: Document,
    jobs: list[Job],
    encodings: list[PrimitiveEncoding | None],
    codec: str,
    animations: EncodedAnimations | None = None,
) -> tuple[dict[str, Any], bytes]:
    """The output document (JSON) and its buffer: the jobs compressed (not kept, with an
    encoding) written by :func:`meshbits.formats.gltf.write.rebuild_document`, each once
    for every primitive of its ``targets``, and the compressed ``animations``."""
    geometries = [
        CompressedGeometry(job.targets, encoding, job.offset)
        for job, encoding in zip(jobs, encodings, strict=True)
        if job.kept is None and encoding is not None
    ]
    return rebuild_document(document, geometries, codec, animations)


def _write(
    document: Document,
    jobs: list[Job],
    encodings: list[PrimitiveEncoding | None],
    codec: str,
    source: Any,
    output: str | Path | None,
    input_bytes: int,
    animations: EncodedAnimations | None,
) -> tuple[list[str], int, bool]:
    """Write the output (when asked): clusters whose data would grow kept as they were,
    every primitive kept when the file would be larger than a glTF input (and a .glb
    input itself written when even that is larger; a larger file than any other input
    noted). Returns the files, the size and whether the input itself was written."""
    _keep_what_grows(document, jobs, encodings)
    out, data = scene_document(document, jobs, encodings, codec, animations)
    written: bytes | None = None
    grew = _larger_than_input(source, output, input_bytes, out, data)
    if grew is not None:
        for job in jobs:
            job.kept = job.kept or grew
        out, data = scene_document(document, jobs, encodings, codec, animations)
        if _larger_than_input(source, output, input_bytes, out, data) and _verbatim(source, output):
            written = Path(source).read_bytes()
    files, size = write_document(out, data, output, written)
    if input_bytes and size > input_bytes:
        document.notes.append(
            f"the file is larger than its input ({size:,} > {input_bytes:,} bytes): "
            "a glTF's container, JSON and accessors outweigh what compression saved"
        )
    return files, size, written is not None


def _check_animation_tolerance(tolerance: float | None) -> None:
    """Refuse an animation tolerance that is not a finite length >= 0."""
    if tolerance is not None and not 0 <= tolerance < float("inf"):
        raise MeshbitsError(f"animation_tolerance must be a finite length >= 0, got {tolerance}")


def _check_scene_arguments(
    error: float | None,
    size: float | None,
    relative: bool,
    codec: str,
    normal_tolerance: float,
    output: str | Path | None,
) -> Budget:
    """The budget (as given), every argument checked."""
    given = Budget.from_options(error=error, size=size, relative=relative, kinds=("error", "size"))
    if codec not in CODECS:
        raise MeshbitsError(f"codec must be one of {CODECS}, got {codec!r}")
    if not (0 < normal_tolerance < 90):
        raise MeshbitsError(f"normal_tolerance must be in (0, 90) degrees, got {normal_tolerance}")
    if output is not None and Path(output).suffix.lower() not in (".glb", ".gltf"):
        raise MeshbitsError(f"a scene is written as .glb or .gltf, not {Path(output).suffix}")
    return given


def _size_search(
    document: Document,
    jobs: list[Job],
    budget: float,
    codec: str,
    seed: int,
    certify: bool,
    run_at: RunAt,
    world_size: float,
) -> tuple[list[Outcome], float]:
    """A size budget (bits): one primitive's own size search, or the common world error
    that fills the file (:func:`meshbits.scene.split.split_size`). Returns the outcomes
    and that error."""

    def file_bytes(outcomes: list[Outcome]) -> int:
        encodings, _, _ = final_encodings(jobs, outcomes, codec, False, 0.0, 0.0, measure=False)
        return document_size(*scene_document(document, jobs, encodings, codec), ".glb")

    fixed = _fixed_bytes(document, jobs)
    if budget / 8 - fixed <= 0:
        images = len(document.json.get("images", []))
        parts = (
            f"{images} image{'' if images == 1 else 's'}, its JSON and other data"
            if images
            else "its JSON and other data"
        )
        raise UnreachableBudgetError(
            f"the size budget ({budget / 8:.6g} bytes) is less than what the output keeps "
            f"whatever its geometry: {parts} ({fixed} bytes)"
        )
    if len(jobs) == 1:
        return size_one(jobs[0], budget, fixed, codec, seed, certify, file_bytes)
    return split_size(jobs, budget, run_at, world_size, file_bytes)


def _input_views(document: Document, targets: list[tuple[int, int]]) -> set[int]:
    """The bufferViews a set of primitives read (attributes, indices, Draco data)."""
    views: set[int] = set()
    accessors = document.json.get("accessors", [])
    for mesh, index in targets:
        prim = document.json["meshes"][mesh]["primitives"][index]
        used = list((prim.get("attributes") or {}).values())
        used += [index for target in prim.get("targets") or [] for index in target.values()]
        if prim.get("indices") is not None:
            used.append(prim["indices"])
        for accessor in used:
            spec = accessors[accessor]
            if spec.get("bufferView") is not None:
                views.add(spec["bufferView"])
            for part in ("indices", "values"):
                view = ((spec.get("sparse") or {}).get(part) or {}).get("bufferView")
                if view is not None:
                    views.add(view)
        draco = (prim.get("extensions") or {}).get("KHR_draco_mesh_compression")
        if draco is not None:
            views.add(draco["bufferView"])
    return views


def _keep_what_grows(
    document: Document, jobs: list[Job], encodings: list[PrimitiveEncoding | None]
) -> None:
    """Keep as they were the jobs of every frame cluster whose compressed data is not
    smaller than the input data its primitives read (or of which one job is kept: its
    meshes' frames cannot change)."""
    clusters: dict[int, list[int]] = {}
    for i, job in enumerate(jobs):
        clusters.setdefault(job.cluster, []).append(i)
    for members in clusters.values():
        reason = next((jobs[i].kept for i in members if jobs[i].kept), None)
        if reason is None:
            views = _input_views(document, [t for i in members for t in jobs[i].targets])
            before = sum(int(document.json["bufferViews"][v]["byteLength"]) for v in views)
            after = sum(encodings[i].size_bits // 8 for i in members)  # type: ignore[union-attr]
            if after >= before:
                reason = (
                    f"compressed, it would not be smaller ({after:,} bytes against the "
                    f"{before:,} of its input)"
                )
        if reason is not None:
            for i in members:
                jobs[i].kept = jobs[i].kept or reason


def _larger_than_input(
    source: Any, output: Any, input_bytes: int, out: dict[str, Any], data: bytes
) -> str | None:
    """Why a glTF input is written as it was: its output would be larger than it."""
    if not input_bytes or Path(str(source)).suffix.lower() not in (".glb", ".gltf"):
        return None
    suffix = Path(output).suffix.lower() if output is not None else ".glb"
    size = document_size(out, data, suffix)
    if size <= input_bytes:
        return None
    return f"compressed, the file would be larger than its input ({size:,} > {input_bytes:,} bytes)"


def _verbatim(source: Any, output: Any) -> bool:
    """Whether the input file itself can be the output: a .glb written as .glb."""
    suffix = Path(output).suffix.lower() if output is not None else ".glb"
    return suffix == ".glb" and Path(str(source)).suffix.lower() == ".glb"


def _fixed_bytes(document: Document, jobs: list[Job]) -> int:
    """Bytes the output keeps whatever the geometry: every bufferView not read by a
    compressed primitive, plus the JSON (estimated at its input size)."""
    replaced = set()
    for job in jobs:
        for mesh, index in job.targets:
            prim = document.json["meshes"][mesh]["primitives"][index]
            replaced.update(prim.get("attributes", {}).values())
            if prim.get("indices") is not None:
                replaced.add(prim["indices"])
    views = set()
    for i, acc in enumerate(document.json.get("accessors", [])):
        if i not in replaced and acc.get("bufferView") is not None:
            views.add(acc["bufferView"])
    total = sum(int(document.json["bufferViews"][v]["byteLength"]) for v in views)
    images = {image_key(document, i): i for i in range(len(document.json.get("images", [])))}
    for i in images.values():
        total += len(document.image_bytes(i)[0])
    return total + len(json.dumps(document.json))
