"""A scene's primitives made ready to compress: read from the document, grouped into jobs
(primitives reading the same accessors are one geometry, encoded once), each with the bits
of its attributes and its largest world scale, and placed in frames (clusters of meshes
that share node transforms; far from the origin, moved to their centre)."""

from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..codecs.attributes import AttributeBits, normal_bits, uv_bits
from ..errors import MeshbitsError, MeshFileError
from ..formats.gltf.document import Document, PrimitiveData, largest_scale
from ..formats.gltf.validate import finite_or_fail
from ..formats.gltf.write import frame_centre
from ..formats.sniff import image_size
from ..hausdorff import Reference
from .skins import ibm_rounding_reserve, mesh_skins, node_worlds, rest_joint_scale

__all__ = [
    "KEPT",
    "Job",
    "Outcome",
    "choose_attribute_bits",
    "decoded_primitives",
    "distinct_vertices",
    "place_in_frames",
    "plan_jobs",
    "world_box",
]

#: What a primitive's search gives: its measurement, its encoding and its level; all None
#: for a primitive written as it was.
Outcome = tuple[Any, Any, Any]
KEPT: Outcome = (None, None, None)


@dataclass
class Job:
    """One geometry to compress: a primitive, with every other primitive whose attributes
    and indices are the same accessors (``targets``, its own first), encoded once and
    shared by all of them."""

    data: PrimitiveData
    name: str | None
    instances: int
    scale: float
    bits: AttributeBits
    targets: list[tuple[int, int]] = field(default_factory=list)
    reference: Reference | None = None
    k: float = 0.0
    grid_size: float = 0.0
    results: dict[tuple[str, float, bool], Outcome] = field(default_factory=dict)
    #: Its positions are encoded in a frame of their own, which the nodes showing its
    #: meshes carry: ``offset`` (mesh units) subtracted from them, and with meshopt the
    #: grid's origin and step. False for a skinned or instanced mesh (its node's transform
    #: is not its only one) and for a mesh of which some primitive is kept as it was.
    framed: bool = False
    offset: np.ndarray = field(default_factory=lambda: np.zeros(3))
    #: Jobs of one cluster share their meshes' frames (and with meshopt, one grid).
    cluster: int = -1
    #: Why its primitives are written as they were (None: compressed).
    kept: str | None = None
    #: Candidates its search skipped (the encoder refused them), each with why.
    skipped: tuple[str, ...] = ()
    #: The skins whose inverse bind matrices carry its frame (a skinned mesh's integer
    #: positions: its nodes' transforms do not apply); empty when its nodes carry it.
    skins: set[int] = field(default_factory=set)
    #: A bound (world units) on what rounding those matrices to float32 moves it by,
    #: added to its certified bound (:func:`meshbits.scene.skins.ibm_rounding`).
    skin_rounding: float = 0.0

    @property
    def meshes(self) -> set[int]:
        """The meshes whose primitives it is."""
        return {mesh for mesh, _ in self.targets}


def _material_textures(document: Document, material: int | None) -> dict[int, int]:
    """``texCoord index -> largest image side`` over the textures a material binds."""
    if material is None:
        return {}
    spec = document.json.get("materials", [])[material]
    infos: list[dict[str, Any]] = []

    def walk(value: Any) -> None:
        if isinstance(value, dict):
            if "index" in value and isinstance(value["index"], int):
                infos.append(value)
            for inner in value.values():
                walk(inner)
        elif isinstance(value, list):
            for inner in value:
                walk(inner)

    walk(spec)
    out: dict[int, int] = {}
    textures = document.json.get("textures", [])
    for info in infos:
        if not 0 <= info["index"] < len(textures):
            continue
        source = textures[info["index"]].get("source")
        if source is None:
            continue
        try:
            data, _ = document.image_bytes(source)
        except MeshbitsError:
            continue
        size = image_size(data)
        if size:
            channel = int(info.get("texCoord", 0))
            out[channel] = max(out.get(channel, 0), max(size))
    return out


def choose_attribute_bits(
    document: Document, primitive: PrimitiveData, normal_tolerance: float
) -> AttributeBits:
    """The bits of a primitive's attributes: its normals and tangents within
    ``normal_tolerance`` degrees, each UV set within half a texel of the largest texture
    its material binds to it."""
    texels = _material_textures(document, primitive.material)
    uv = {
        name: uv_bits(values, texels.get(int(name.split("_")[1])))
        for name, values in primitive.attributes.items()
        if name.startswith("TEXCOORD_")
    }
    normals = [primitive.attributes[n] for n in ("NORMAL", "TANGENT") if n in primitive.attributes]
    bits = max((normal_bits(n, normal_tolerance) for n in normals), default=8)
    return AttributeBits(normal=bits, uv=uv)


def distinct_vertices(positions: np.ndarray, attributes: dict[str, Any] | None) -> int:
    """Vertices distinct in position or in some attribute: an STL's corners, stored once
    per face, count once (its welded count); a UV seam's copies count apart."""
    n = len(positions)
    if n == 0:
        return 0
    columns = [np.asarray(positions, dtype=np.float64).reshape(n, -1)] + [
        np.asarray(a, dtype=np.float64).reshape(n, -1)
        for a in (attributes or {}).values()
        if len(a) == n
    ]
    return len(np.unique(np.hstack(columns), axis=0))


def _geometry_key(document: Document, data: PrimitiveData) -> str:
    """What makes two primitives one geometry: the same accessors (or Draco data) for
    every attribute and the indices, in the same mode."""
    prim = document.json["meshes"][data.mesh]["primitives"][data.index]
    return json.dumps(
        [
            prim.get("attributes"),
            prim.get("indices"),
            prim.get("mode", 4),
            (prim.get("extensions") or {}).get("KHR_draco_mesh_compression"),
            prim.get("targets"),
        ],
        sort_keys=True,
    )


def plan_jobs(
    document: Document,
    primitives: list[PrimitiveData],
    instances: dict[int, list[tuple[int, np.ndarray]]],
    normal_tolerance: float,
    where: str,
    codec: str = "meshopt",
) -> tuple[list[Job], list[PrimitiveData]]:
    """The geometries to compress (primitives sharing accessors as one) and the
    primitives kept as they are (no faces; morph targets with Draco, which does not
    compress them, or of a Draco input, whose decoded vertex order need not be theirs).
    A skinned primitive's scale is also at least its skins' (:func:`rest_joint_scale`)."""
    jobs: dict[str, Job] = {}
    kept: list[PrimitiveData] = []
    skins, worlds = mesh_skins(document), node_worlds(document)
    for data in primitives:
        if len(data.faces) == 0 or (data.morph and (codec == "draco" or not data.targets)):
            kept.append(data)
            continue
        nodes = instances.get(data.mesh, [])
        scale = max((largest_scale(m) for _, m in nodes), default=1.0) or 1.0
        if data.skinned:
            posing = {s for s in skins.get(data.mesh, set()) if s is not None}
            scale = max(scale, rest_joint_scale(document, posing, worlds))
        mesh_name = document.json["meshes"][data.mesh].get("name")
        label = f"{where}mesh {data.mesh} ({mesh_name or 'unnamed'}), primitive {data.index}"
        finite_or_fail(f"{label}: POSITION", data.positions)
        for t, target in enumerate(data.targets):
            for name, values in target.items():
                finite_or_fail(f"{label}: targets[{t}].{name}", values)
        bits = choose_attribute_bits(document, data, normal_tolerance)
        key = _geometry_key(document, data)
        job = jobs.get(key)
        if job is None:
            jobs[key] = Job(data, mesh_name, len(nodes), scale, bits, [(data.mesh, data.index)])
            continue
        job.targets.append((data.mesh, data.index))
        job.scale = max(job.scale, scale)
        job.bits = job.bits.finer(bits)
    for job in jobs.values():
        job.instances = sum(len(instances.get(mesh, [])) for mesh in job.meshes)
    return list(jobs.values()), kept


def decoded_primitives(document: Document, where: str) -> list[PrimitiveData]:
    """``document.triangle_primitives()``, a file's errors prefixed with ``where`` (its
    path and a colon, or nothing)."""
    try:
        return document.triangle_primitives()
    except MeshFileError as error:
        if not where:
            raise
        raise MeshFileError(f"{where}{error}") from error


def world_box(
    primitives: list[PrimitiveData], instances: dict[int, list[tuple[int, np.ndarray]]]
) -> tuple[float, float]:
    """The largest side of the scene's world bounding box, and the largest absolute world
    coordinate (world units)."""
    lows, highs = [], []
    for data in primitives:
        for _, matrix in instances.get(data.mesh, [(-1, np.eye(4))]):
            world = data.positions @ matrix[:3, :3].T + matrix[:3, 3]
            if len(world):
                lows.append(world.min(axis=0))
                highs.append(world.max(axis=0))
    if not lows:
        raise MeshFileError("the scene has no vertices")
    lo, hi = np.min(lows, axis=0), np.max(highs, axis=0)
    return float((hi - lo).max()), float(np.maximum(np.abs(lo), np.abs(hi)).max())


def place_in_frames(jobs: list[Job], kept: list[PrimitiveData], document: Document) -> None:
    """Group the jobs into clusters of meshes that must share frames (a job shared by
    several meshes joins them), mark the clusters whose meshes can take a frame of their
    own from the nodes that show them (``Job.framed``), and move those far from the
    origin to their centre (:func:`meshbits.formats.gltf.write.frame_centre`;
    ``Job.offset``), so that their float32 and quantized positions keep their precision."""
    parent: dict[int, int] = {}

    def root(mesh: int) -> int:
        while parent.setdefault(mesh, mesh) != mesh:
            mesh = parent[mesh]
        return mesh

    for job in jobs:
        first, *others = sorted(job.meshes)
        for mesh in others:
            parent[root(mesh)] = root(first)
    skins_of = mesh_skins(document)
    first_posed: dict[int, int] = {}
    for mesh, skins in skins_of.items():
        for skin in skins - {None}:
            parent[root(mesh)] = root(first_posed.setdefault(skin, mesh))
    clusters: dict[int, list[Job]] = {}
    for job in jobs:
        clusters.setdefault(root(min(job.meshes)), []).append(job)
    unframed = document.instanced_meshes() | {data.mesh for data in kept}
    for number, members in enumerate(clusters.values()):
        meshes = {mesh for job in members for mesh in job.meshes}
        skins = set().union(*(skins_of.get(mesh, set()) for mesh in meshes)) - {None}
        if skins or any(job.data.skinned for job in members):
            framed = _skin_frameable(members, meshes, skins, skins_of, unframed)
        else:
            framed = not (meshes & unframed) and _weights_stay(document, meshes)
        centre = np.zeros(3)
        if framed:
            centre = frame_centre(np.concatenate([job.data.positions for job in members]))
        for job in members:
            job.cluster, job.framed = number, framed
            job.skins = set(skins) if framed else set()
            if centre.any():
                job.offset = centre
                job.data = replace(job.data, positions=job.data.positions - centre)
        if framed and skins:
            _reserve_skin_rounding(document, members, skins)


def _reserve_skin_rounding(document: Document, members: list[Job], skins: set[int]) -> None:
    """Set aside in each job of a skin-framed cluster the most that rounding its skins'
    folded matrices can move it by (:func:`ibm_rounding_reserve`, over the cluster's box:
    its jobs share one grid)."""
    positions = np.concatenate([job.data.positions for job in members])
    spread = max(
        sum(
            float(np.linalg.norm(t["POSITION"], axis=1).max(initial=0.0))
            for t in job.data.targets
            if "POSITION" in t
        )
        for job in members
    )
    reserve = ibm_rounding_reserve(document, skins, node_worlds(document), positions, spread)
    for job in members:
        job.skin_rounding = reserve


def _skin_frameable(
    members: list[Job],
    meshes: set[int],
    skins: set[int],
    skins_of: dict[int, set[int | None]],
    unframed: set[int],
) -> bool:
    """Whether a cluster with skinned meshes can store integer positions, its frame in
    its skins' inverse bind matrices: every primitive skinned, every node showing its
    meshes with a skin, every mesh those skins pose in the cluster, none instanced or
    kept."""
    posed = {mesh for mesh, used in skins_of.items() if used & skins}
    every_node_skinned = all(None not in skins_of.get(mesh, {None}) for mesh in meshes)
    return (
        bool(skins)
        and all(job.data.skinned for job in members)
        and every_node_skinned
        and posed <= meshes
        and not (meshes & unframed)
    )


def _weights_stay(document: Document, meshes: set[int]) -> bool:
    """Whether the frame of ``meshes`` can go into the nodes showing them without moving
    a mesh whose morph weights an animation drives (an animation targets the node: the
    mesh must stay on it, so the frame must fold into the node itself)."""
    driven = {
        channel["target"]["node"]
        for animation in document.json.get("animations", [])
        for channel in animation.get("channels", [])
        if channel.get("target", {}).get("path") == "weights"
    }
    foldable = {"mesh", "name", "translation", "rotation", "scale", "matrix", "weights"}
    animated = document.animated_nodes()
    nodes = document.json.get("nodes", [])
    return all(
        set(nodes[i]) <= foldable and i not in animated
        for i in driven
        if 0 <= i < len(nodes) and nodes[i].get("mesh") in meshes
    )
