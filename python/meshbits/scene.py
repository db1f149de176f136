"""Scenes: a glTF document, or an OBJ / PLY with its attributes, compressed whole.

Every triangle primitive is simplified with its attributes (UV seams and hard normal edges
kept), its positions quantized at its own B found by the search of :mod:`meshbits.search`,
its other attributes at bits chosen from their own tolerance, and written with
``KHR_draco_mesh_compression`` (Draco, the default) or ``EXT_meshopt_compression`` with
``KHR_mesh_quantization`` (meshoptimizer's codecs). Nodes, materials, textures and images
(bytes unchanged), samplers, skins, animations, cameras, extras and the extensions meshbits
does not touch are copied as they were. See docs/scenes.md.

The error budget is a world-space length: a primitive's error is its mesh's error times the
largest scale of the nodes that instance it. An error budget is met by every primitive at
the fewest bytes each; a size budget is split across primitives by the common world-space
error that fills it (the split that minimises the scene's largest error).
"""

from __future__ import annotations

import copy
import json
import math
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from . import _core
from .budget import Budget
from .complexity import shape_complexity
from .constants import (
    ANSWER_RELATIVE_TOLERANCE,
    CERTIFY_TOLERANCE,
    DRACO_ALPHA,
    DRACO_CONNECTIVITY_BITS,
    FLAT_K,
)
from .encode import draco_encode, draco_max_bits, draco_quantization
from .errors import MeshbitsError, MeshFileError
from .files import asset_bytes, check_not_an_input, write_atomic
from .formats.gltf.document import Document, PrimitiveData, largest_scale
from .formats.gltf.spec import COMPONENT_DTYPES, COMPONENT_TYPES, MESHOPT_EXTENSIONS, WIDTH_TYPES
from .formats.gltf.validate import finite_or_fail
from .formats.gltf.write import frame_centre, json_number
from .formats.obj import missing_material_libraries
from .formats.open import load_document
from .formats.sniff import image_size
from .hausdorff import Reference, default_samples
from .mesh import distinct_positions, draco_drops_note, kept_shape, lost_geometry_note
from .quantize import cube_grid, precision_bits
from .results import SAMPLED_ONLY, Progress, ProgressCallback
from .search import (
    BASE_FACES,
    Attributes,
    Refused,
    Search,
    bound_answer,
    certify_answer,
    run_search,
)
from .units import length_unit_of

__all__ = [
    "CODECS",
    "NORMAL_TOLERANCE_DEGREES",
    "PrimitiveReport",
    "SceneResult",
    "compress_scene",
    "scene_info",
]

#: The most bits meshopt's integer positions hold (``KHR_mesh_quantization``'s shorts);
#: beyond, positions are float32 on the grid, up to :data:`MESHOPT_MAX_BITS`.
MESHOPT_INTEGER_BITS = 16
MESHOPT_MAX_BITS = 24
#: How many bits finer than the finest its jobs chose a cluster's shared meshopt grid
#: may go when one of them misses its budget on it (each halves the rounding).
SHARED_GRID_EXTRA_BITS = 3

#: Codecs of :func:`compress_scene`.
CODECS = ("draco", "meshopt")

#: Largest angle (degrees) between a normal or tangent and its quantized value.
NORMAL_TOLERANCE_DEGREES = 1.0

#: UV bits when no texture tells the texel size: gltfpack's default.
DEFAULT_UV_BITS = 12

#: Bits of colours and skin weights (one byte a component).
COLOR_BITS = WEIGHT_BITS = 8

#: Area samples per mesh of a primitive's measurements (fewer than a single mesh's: a
#: scene has many), for primitives of at most ``BASE_FACES`` faces; larger ones take
#: :func:`default_samples` (10 per face up to a million): with 100,000 the dragon's
#: sampled answer at 0.001 S failed certification.
SCENE_SAMPLES = 100_000

#: Passes per primitive, and certified passes after an answer that fails certification
#: (compress's defaults: with 4 and 2, the hand at 0.002 S and the dragon at 0.001 S
#: missed budgets that compress meets).
SCENE_PASSES = 6

#: Passes of the size split: common world errors tried.
SIZE_SPLIT_PASSES = 8

#: Searches of a lone primitive's size budget (each after the file was over) and the
#: bytes kept to spare when its share shrinks.
SIZE_ONE_TRIES = 3
SIZE_ONE_MARGIN = 16

#: The size split stops at a file of at least this fraction of the budget.
SIZE_SPLIT_FILL = 0.97

#: Relative float64 rounding of a world position a reader composes from the file (node
#: transforms applied to float32 or integer positions), bounded generously: every
#: certified world-space bound is raised by this times the largest world coordinate.
WORLD_ROUNDING = 16 * 2.0**-52

#: The size split aims at this fraction of the budget (measured sizes scatter around the
#: log-log line).
SIZE_SPLIT_AIM = 0.985


# --- attribute bits ---------------------------------------------------------------------


def _octahedral_round_trip(vectors: np.ndarray, bits: int) -> np.ndarray:
    """Unit vectors through the octahedral map quantized to signed ``bits``-bit
    components, and back."""
    v = vectors / np.maximum(np.abs(vectors).sum(axis=1, keepdims=True), 1e-30)
    x, y, z = v[:, 0], v[:, 1], v[:, 2]
    folded_x = np.where(z < 0, (1 - np.abs(y)) * np.sign(np.where(x == 0, 1, x)), x)
    folded_y = np.where(z < 0, (1 - np.abs(x)) * np.sign(np.where(y == 0, 1, y)), y)
    scale = float(2 ** (bits - 1) - 1)
    qx, qy = np.round(folded_x * scale) / scale, np.round(folded_y * scale) / scale
    qz = 1 - np.abs(qx) - np.abs(qy)
    t = np.maximum(-qz, 0)
    qx = qx - np.sign(qx) * t
    qy = qy - np.sign(qy) * t
    out = np.stack([qx, qy, qz], axis=1)
    return out / np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-30)


def normal_bits(vectors: np.ndarray, tolerance_degrees: float = NORMAL_TOLERANCE_DEGREES) -> int:
    """The fewest octahedral bits (4 to 16) that keep every unit vector within
    ``tolerance_degrees`` of itself."""
    v = np.asarray(vectors, dtype=np.float64)[:, :3]
    length = np.linalg.norm(v, axis=1)
    v = v[length > 1e-12] / length[length > 1e-12, None]
    if len(v) == 0:
        return 8
    limit = math.cos(math.radians(tolerance_degrees))
    for bits in range(4, 17):
        if np.min(np.sum(v * _octahedral_round_trip(v, bits), axis=1)) >= limit:
            return bits
    return 16


def uv_bits(uv: np.ndarray, texels: int | None) -> int:
    """Bits for texture coordinates: the fewest that keep them within half a texel of the
    largest texture bound to them (``texels`` its largest side), 8 to 16, over their range,
    or over [0, 1] when they lie in it (meshopt stores them there as normalized shorts);
    :data:`DEFAULT_UV_BITS` without a texture."""
    if not texels or len(uv) == 0:
        return DEFAULT_UV_BITS
    extent = 1.0 if _in_unit_square(uv) else float(np.ptp(uv, axis=0).max())
    if extent <= 0:
        return 8
    return int(min(max(math.ceil(math.log2(extent * texels + 1)), 8), 16))


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


@dataclass(frozen=True)
class AttributeBits:
    """Bits of a primitive's other attributes: ``normal`` (octahedral, normals and
    tangents), ``uv`` per texture-coordinate set, ``color``, ``weight``."""

    normal: int
    uv: dict[str, int]
    color: int = COLOR_BITS
    weight: int = WEIGHT_BITS


def choose_attribute_bits(
    document: Document, primitive: PrimitiveData, normal_tolerance: float
) -> AttributeBits:
    texels = _material_textures(document, primitive.material)
    uv = {
        name: uv_bits(values, texels.get(int(name.split("_")[1])))
        for name, values in primitive.attributes.items()
        if name.startswith("TEXCOORD_")
    }
    normals = [primitive.attributes[n] for n in ("NORMAL", "TANGENT") if n in primitive.attributes]
    bits = max((normal_bits(n, normal_tolerance) for n in normals), default=8)
    return AttributeBits(normal=bits, uv=uv)


# --- encoding one primitive --------------------------------------------------------------


@dataclass
class Encoding:
    """One primitive encoded: its bytes, what a decoder gets back, and what the writer
    needs.

    Attributes
    ----------
    size_bits : int
        Bits of the compressed data.
    vertices, faces : ndarray
        The decoded positions (float64) and triangles: what is measured.
    accessors : dict
        ``name -> accessor fields`` (count, componentType, type, normalized, min/max).
    draco : bytes or None
        The Draco buffer, with ``draco_ids`` (glTF name -> Draco attribute id).
    streams : list of dict
        meshopt: per stream (``name``, ``data`` compressed, ``raw`` length, ``stride``,
        ``count``, ``mode``, ``filter``).
    dequantize : tuple or None
        meshopt: ``(origin, step)`` mapping integer position codes to mesh units.
    """

    size_bits: int
    vertices: np.ndarray = field(repr=False)
    faces: np.ndarray = field(repr=False)
    accessors: dict[str, dict[str, Any]] = field(repr=False)
    draco: bytes | None = field(default=None, repr=False)
    draco_ids: dict[str, int] = field(default_factory=dict)
    streams: list[dict[str, Any]] = field(default_factory=list, repr=False)
    dequantize: tuple[np.ndarray, float] | None = None
    bits: int | None = None

    @property
    def data(self) -> bytes:
        return self.draco or b"".join(s["data"] for s in self.streams)


def _index_component(count: int) -> int:
    return 5123 if count < 65536 else 5125


def _float32_number(value: float) -> float:
    """A float32 value as the shortest decimal that reads back to it in float32 (at most
    9 digits, where its double expansion takes up to 17: an accessor's ``min`` and ``max``
    are float32 values)."""
    return float(str(np.float32(value)))


def _accessor_fields(
    values: np.ndarray, component: int, normalized: bool, bounds: bool
) -> dict[str, Any]:
    width = values.shape[1] if values.ndim == 2 else 1
    out: dict[str, Any] = {
        "count": len(values),
        "componentType": component,
        "type": WIDTH_TYPES[width],
    }
    if normalized:
        out["normalized"] = True
    if bounds and len(values):
        cast = _float32_number if component == 5126 else int
        out["min"] = [cast(x) for x in np.min(values, axis=0).reshape(-1)]
        out["max"] = [cast(x) for x in np.max(values, axis=0).reshape(-1)]
    return out


def _in_unit_square(uv: np.ndarray, slack: float = 0.0) -> bool:
    """Whether texture coordinates lie in [0, 1] (within ``slack``: simplification
    interpolates them)."""
    return len(uv) > 0 and uv.min() >= -slack and uv.max() <= 1.0 + slack


def _unit_u8(values: np.ndarray) -> np.ndarray:
    return np.clip(np.round(np.asarray(values) * 255.0), 0, 255).astype(np.uint8)


def _weights_u8(weights: np.ndarray) -> np.ndarray:
    """Skin weights as bytes summing to 255 (the largest takes the rounding)."""
    w = _unit_u8(weights).astype(np.int64)
    rows = np.arange(len(w))
    largest = np.argmax(w, axis=1)
    w[rows, largest] += 255 - w.sum(axis=1)
    return np.clip(w, 0, 255).astype(np.uint8)


def encode_draco_primitive(
    vertices: np.ndarray,
    faces: np.ndarray,
    attributes: dict[str, np.ndarray] | None,
    bits: int,
    origin: np.ndarray,
    grid_size: float,
    attribute_bits: AttributeBits,
) -> Encoding:
    """A primitive as a ``KHR_draco_mesh_compression`` buffer: positions on the cube grid
    at ``bits``, normals at ``attribute_bits.normal``, the first UV set at its bits,
    colours as bytes; other sets, tangents, joints and weights as Draco generic
    attributes."""
    import DracoPy

    attributes = attributes or {}
    uv_names = sorted(n for n in attributes if n.startswith("TEXCOORD_"))
    colors = sorted(n for n in attributes if n.startswith("COLOR_"))
    generic: dict[str, np.ndarray] = {}
    for name, values in attributes.items():
        if name in ("NORMAL", uv_names[0] if uv_names else None, colors[0] if colors else None):
            continue
        if name.startswith("JOINTS_"):
            generic[name] = np.asarray(values, dtype=np.uint16)
        elif name.startswith("COLOR_"):
            generic[name] = _unit_u8(values)
        else:
            generic[name] = np.asarray(values, dtype=np.float32)
    draco_bits, draco_range = draco_quantization(bits, grid_size)
    data = draco_encode(
        np.asarray(vertices, dtype=np.float64),
        np.asarray(faces, dtype=np.uint32),
        quantization_bits=draco_bits,
        compression_level=7,
        quantization_range=draco_range,
        quantization_origin=np.asarray(origin, dtype=np.float64),
        normals=np.asarray(attributes["NORMAL"], dtype=np.float64)
        if "NORMAL" in attributes
        else None,
        tex_coord=np.asarray(attributes[uv_names[0]], dtype=np.float64) if uv_names else None,
        colors=_unit_u8(attributes[colors[0]]) if colors else None,
        generic_attributes=generic or None,
        normal_quantization_bits=attribute_bits.normal if "NORMAL" in attributes else None,
        tex_coord_quantization_bits=attribute_bits.uv.get(uv_names[0]) if uv_names else None,
    )
    mesh = DracoPy.decode(data)
    ids: dict[str, int] = {}
    decoded: dict[str, np.ndarray] = {}
    for attribute in mesh.attributes:
        kind, name = attribute["attribute_type"], attribute["name"]
        glname = (
            {
                0: "POSITION",
                1: "NORMAL",
                2: colors[0] if colors else None,
                3: uv_names[0] if uv_names else None,
            }.get(kind)
            if kind != 4
            else name
        )
        if glname is None:
            continue
        ids[glname] = int(attribute["unique_id"])
        decoded[glname] = np.asarray(attribute["data"])
    positions = decoded["POSITION"].astype(np.float64)
    triangles = np.asarray(mesh.faces, dtype=np.int64).reshape(-1, 3)
    accessors = {"POSITION": _accessor_fields(positions, 5126, False, True)}
    for name, values in decoded.items():
        if name == "POSITION":
            continue
        if name.startswith("COLOR_"):
            accessors[name] = _accessor_fields(values, 5121, True, False)
        elif name.startswith("JOINTS_"):
            accessors[name] = _accessor_fields(values, 5123, False, False)
        else:
            accessors[name] = _accessor_fields(values, 5126, False, False)
    accessors["indices"] = {
        "count": int(triangles.size),
        "componentType": _index_component(len(positions)),
        "type": "SCALAR",
    }
    return Encoding(
        size_bits=8 * len(data),
        vertices=positions,
        faces=triangles,
        accessors=accessors,
        draco=data,
        draco_ids=ids,
    )


def _stream(name: str, rows: np.ndarray, filter: str = "NONE") -> dict[str, Any]:
    """A vertex stream through meshoptimizer's vertex codec, rows padded to 4 bytes."""
    rows = np.ascontiguousarray(rows)
    raw = rows.view(np.uint8).reshape(len(rows), -1)
    pad = (-raw.shape[1]) % 4
    if pad:
        raw = np.hstack([raw, np.zeros((len(raw), pad), dtype=np.uint8)])
    stride = raw.shape[1]
    flat = np.ascontiguousarray(raw).reshape(-1)
    return {
        "name": name,
        "data": _core.meshopt_encode_vertices(flat, stride),
        "raw": flat.tobytes(),
        "stride": stride,
        "count": len(rows),
        "mode": "ATTRIBUTES",
        "filter": filter,
    }


def encode_meshopt_primitive(
    vertices: np.ndarray,
    faces: np.ndarray,
    attributes: dict[str, np.ndarray] | None,
    bits: int,
    origin: np.ndarray,
    grid_size: float,
    attribute_bits: AttributeBits,
    *,
    integer_positions: bool = True,
) -> Encoding:
    """A primitive as ``EXT_meshopt_compression`` streams under ``KHR_mesh_quantization``,
    triangles and vertices first reordered for the codecs (as gltfpack does): positions as
    their integer codes on the cube grid (bytes up to 8 bits, shorts up to 16; the
    dequantization goes to the nodes), or as float32 on the grid for a skinned or
    instanced primitive and beyond 16 bits; normals and tangents through the octahedral
    filter; UVs rounded to their bits, as normalized unsigned shorts within [0, 1] and
    float32 beyond; colours and weights as normalized bytes; joints as bytes or shorts."""
    integer_positions = integer_positions and bits <= MESHOPT_INTEGER_BITS
    attributes = attributes or {}
    order_faces, old = _core.meshopt_reorder(
        np.ascontiguousarray(faces, dtype=np.uint32), len(vertices)
    )
    vertices = np.asarray(vertices)[old]
    attributes = {name: np.asarray(values)[old] for name, values in attributes.items()}
    faces = order_faces.astype(np.int64)
    n = len(vertices)
    step = grid_size / (2**bits - 1) if grid_size > 0 else 1.0
    codes = np.clip(np.round((vertices - origin) / step), 0, 2**bits - 1)
    grid = origin + codes * step
    streams, accessors = [], {}
    if integer_positions:
        dtype = np.uint8 if bits <= 8 else np.uint16
        stored = codes.astype(dtype)
        streams.append(_stream("POSITION", stored))
        accessors["POSITION"] = _accessor_fields(
            stored, COMPONENT_TYPES[np.dtype(dtype)], False, True
        )
    else:
        stored = grid.astype(np.float32)
        grid = stored.astype(np.float64)
        streams.append(_stream("POSITION", stored))
        accessors["POSITION"] = _accessor_fields(stored, 5126, False, True)
    for name, values in attributes.items():
        values = np.asarray(values)
        if name in ("NORMAL", "TANGENT"):
            vectors = np.zeros((n, 4), dtype=np.float32)
            vectors[:, :3] = values[:, :3]
            vectors[:, 3] = values[:, 3] if values.shape[1] == 4 else 1.0
            octa = _core.meshopt_encode_octahedral(
                np.ascontiguousarray(vectors), attribute_bits.normal
            )
            component = 5120 if octa.shape[1] == 4 else 5122
            stream = _stream(name, octa, "OCTAHEDRAL")
            stream["stride"] = octa.shape[1]
            streams.append(stream)
            width = 3 if name == "NORMAL" else 4
            accessors[name] = {
                "count": n,
                "componentType": component,
                "type": WIDTH_TYPES[width],
                "normalized": True,
            }
        elif name.startswith("TEXCOORD_"):
            b = attribute_bits.uv.get(name, DEFAULT_UV_BITS)
            levels = 2**b - 1
            if _in_unit_square(values, 0.5 / levels):
                # Normalized unsigned shorts (KHR_mesh_quantization): the b-bit steps of
                # [0, 1], each at its nearest short (exact for 8 and 16 bits, at most
                # 1/131070 off otherwise). A float32 stream of the same values compresses
                # worse: the new-user check's textured scene went from 23,292 to 20,484 bytes.
                steps = np.round(np.clip(values, 0.0, 1.0) * levels)
                stored = np.round(steps * (65535 / levels)).astype(np.uint16)
                streams.append(_stream(name, stored))
                accessors[name] = _accessor_fields(stored, 5123, True, False)
                continue
            lo, extent = values.min(axis=0), max(float(np.ptp(values, axis=0).max()), 1e-30)
            uv_step = extent / levels
            rounded = (lo + np.round((values - lo) / uv_step) * uv_step).astype(np.float32)
            streams.append(_stream(name, rounded))
            accessors[name] = _accessor_fields(rounded, 5126, False, False)
        elif name.startswith("COLOR_"):
            stored = _unit_u8(values)
            streams.append(_stream(name, stored))
            accessors[name] = _accessor_fields(stored, 5121, True, False)
        elif name.startswith("WEIGHTS_"):
            stored = _weights_u8(values)
            streams.append(_stream(name, stored))
            accessors[name] = _accessor_fields(stored, 5121, True, False)
        elif name.startswith("JOINTS_"):
            dtype = np.uint8 if values.size == 0 or values.max() < 256 else np.uint16
            stored = values.astype(dtype)
            streams.append(_stream(name, stored))
            accessors[name] = _accessor_fields(
                stored, COMPONENT_TYPES[np.dtype(dtype)], False, False
            )
        else:
            stored = values.astype(np.float32)
            streams.append(_stream(name, stored))
            accessors[name] = _accessor_fields(stored, 5126, False, False)
    index_component = _index_component(n)
    triangles = np.ascontiguousarray(faces, dtype=np.uint32)
    index_size = 2 if index_component == 5123 else 4
    streams.append(
        {
            "name": "indices",
            "data": _core.meshopt_encode_triangles(triangles, n),
            "raw": triangles.astype(np.uint16 if index_size == 2 else np.uint32).tobytes(),
            "stride": index_size,
            "count": int(triangles.size),
            "mode": "TRIANGLES",
            "filter": "NONE",
        }
    )
    accessors["indices"] = {
        "count": int(triangles.size),
        "componentType": index_component,
        "type": "SCALAR",
    }
    return Encoding(
        size_bits=8 * sum(len(s["data"]) for s in streams),
        vertices=grid,
        faces=np.asarray(faces, dtype=np.int64),
        accessors=accessors,
        streams=streams,
        dequantize=(np.asarray(origin, dtype=np.float64), float(step))
        if integer_positions
        else None,
    )


# --- results ------------------------------------------------------------------------------


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
    size_bytes : int
        The written file (GLB; for ``.gltf``, the JSON plus its buffer).
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

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready; a size budget is also given in bytes (``budget_bytes``), as
        :class:`meshbits.CompressResult` does."""
        out = {k: v for k, v in asdict(self).items() if k != "primitives"}
        out["budget_bytes"] = self.budget / 8 if self.constraint == "size" else None
        out["primitives"] = [p.to_dict() for p in self.primitives]
        return out


# --- the scene search ----------------------------------------------------------------------

#: What a primitive's search gives: its measurement, its encoding and its level; all None
#: for a primitive written as it was.
Outcome = tuple[Any, Any, Any]
KEPT: Outcome = (None, None, None)


@dataclass
class _Job:
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

    @property
    def meshes(self) -> set[int]:
        return {mesh for mesh, _ in self.targets}


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
        ],
        sort_keys=True,
    )


def _finer(a: AttributeBits, b: AttributeBits) -> AttributeBits:
    """The bits that keep both primitives of a shared geometry within their tolerances."""
    uv = {name: max(a.uv.get(name, 0), b.uv.get(name, 0)) for name in {*a.uv, *b.uv}}
    return AttributeBits(
        normal=max(a.normal, b.normal),
        uv=uv,
        color=max(a.color, b.color),
        weight=max(a.weight, b.weight),
    )


def _plan_jobs(
    document: Document,
    primitives: list[PrimitiveData],
    instances: dict[int, list[tuple[int, np.ndarray]]],
    normal_tolerance: float,
    where: str,
) -> tuple[list[_Job], list[PrimitiveData]]:
    """The geometries to compress (primitives sharing accessors as one) and the
    primitives kept as they are (morph targets, no faces)."""
    jobs: dict[str, _Job] = {}
    kept: list[PrimitiveData] = []
    for data in primitives:
        if data.morph or len(data.faces) == 0:
            kept.append(data)
            continue
        nodes = instances.get(data.mesh, [])
        scale = max((largest_scale(m) for _, m in nodes), default=1.0) or 1.0
        mesh_name = document.json["meshes"][data.mesh].get("name")
        finite_or_fail(
            f"{where}mesh {data.mesh} ({mesh_name or 'unnamed'}), primitive {data.index}: POSITION",
            data.positions,
        )
        bits = choose_attribute_bits(document, data, normal_tolerance)
        key = _geometry_key(document, data)
        job = jobs.get(key)
        if job is None:
            jobs[key] = _Job(data, mesh_name, len(nodes), scale, bits, [(data.mesh, data.index)])
            continue
        job.targets.append((data.mesh, data.index))
        job.scale = max(job.scale, scale)
        job.bits = _finer(job.bits, bits)
    for job in jobs.values():
        job.instances = sum(len(instances.get(mesh, [])) for mesh in job.meshes)
    return list(jobs.values()), kept


def _attribute_weights(names: list[str], budget: float, bits: AttributeBits) -> dict[str, float]:
    """meshoptimizer's attribute weights: an attribute off by its own tolerance costs like
    a position off by the error budget."""
    weights = {}
    for name in names:
        if name in ("NORMAL", "TANGENT"):
            weights[name] = budget / math.sin(math.radians(NORMAL_TOLERANCE_DEGREES) * 4)
        elif name.startswith("TEXCOORD_"):
            weights[name] = budget * 2 ** bits.uv.get(name, DEFAULT_UV_BITS) / 4
        elif name.startswith("COLOR_"):
            weights[name] = budget * 32
        else:
            weights[name] = 0.0
    return weights


def _job_reference(job: _Job, seed: int) -> Reference:
    """The job's original (its BVH and samples), with its K and grid, built once."""
    if job.reference is None:
        original = (job.data.positions, job.data.faces)
        samples = default_samples(len(job.data.faces))
        if len(job.data.faces) <= BASE_FACES:
            samples = min(samples, SCENE_SAMPLES)
        job.reference = Reference(original, samples=samples, seed=seed)
        complexity = shape_complexity(original)
        job.k = max(complexity.k, FLAT_K)
        job.grid_size = complexity.grid_size
    return job.reference


def _search_primitive(
    job: _Job,
    budget: float,
    codec: str,
    seed: int,
    certify: bool,
    constraint: str = "error",
) -> Outcome:
    """The fewest bytes of one primitive within a local error budget, or with
    ``constraint="size"`` the least error within ``budget`` bits of its own (cached).
    :data:`KEPT` when the encoder refuses every candidate: the job is then kept as it
    was, and says why."""
    if job.kept is not None:
        return KEPT
    if (constraint, budget, certify) in job.results:
        return job.results[(constraint, budget, certify)]
    data = job.data
    reference = _job_reference(job, seed)
    attributes = None
    if data.attributes:
        attributes = Attributes(
            values=data.attributes,
            weights=_attribute_weights(list(data.attributes), budget, job.bits),
            interpolate=not data.skinned,
        )

    def encode(vertices, faces, attrs, bits, origin, grid_size):
        if codec == "draco":
            return encode_draco_primitive(vertices, faces, attrs, bits, origin, grid_size, job.bits)
        return encode_meshopt_primitive(
            vertices,
            faces,
            attrs,
            bits,
            origin,
            grid_size,
            job.bits,
            integer_positions=job.framed,
        )

    max_bits = min(
        MESHOPT_MAX_BITS if codec == "meshopt" else draco_max_bits(job.grid_size),
        precision_bits(data.positions),
    )
    search = Search(
        (data.positions, data.faces),
        reference,
        constraint=constraint,
        budget=budget,
        k=job.k,
        grid_size=job.grid_size,
        max_bits=max_bits,
        format="draco",
        alpha=DRACO_ALPHA,
        connectivity_bits=DRACO_CONNECTIVITY_BITS,
        method="meshopt" if attributes is not None else "auto",
        samples=reference.samples,
        attributes=attributes,
        codec=encode,
    )
    try:
        run_search(search, SCENE_PASSES)
    except Refused as err:
        job.kept = f"{codec} could not encode it: {err}"
        return KEPT
    if certify and constraint == "error":
        certify_answer(search, CERTIFY_TOLERANCE * budget, SCENE_PASSES)
    elif certify:
        bound_answer(search, ANSWER_RELATIVE_TOLERANCE)
    chosen = search.best() or search.closest()
    outcome = (chosen, search.encoded(chosen), search.levels[chosen.level])
    job.skipped = tuple(
        f"level {index} at {bits} bits: {why}" for (index, bits), why in search.refused.items()
    )
    job.results[(constraint, budget, certify)] = outcome
    return outcome


def compress_scene(
    source: str | Path | Document,
    *,
    error: float | None = None,
    size: float | None = None,
    relative: bool = False,
    codec: str = "draco",
    normal_tolerance: float = NORMAL_TOLERANCE_DEGREES,
    output: str | Path | None = None,
    seed: int = 0,
    certify: bool = True,
    progress: ProgressCallback | None = None,
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
        ``"draco"`` (``KHR_draco_mesh_compression``) or ``"meshopt"``
        (``EXT_meshopt_compression`` with ``KHR_mesh_quantization``).
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

    Returns
    -------
    SceneResult
    """
    start = time.perf_counter()
    given = _check_scene_arguments(error, size, relative, codec, normal_tolerance, output)
    constraint = given.kind
    if output is not None and not isinstance(source, Document):
        check_not_an_input(output, source)
    if not isinstance(source, (str, Path, Document)):
        raise TypeError(
            f"compress_scene takes a file path or a meshbits.formats.Document, got "
            f"{type(source).__name__}: for a mesh in memory use meshbits.compress, or export "
            "the scene to a .glb first"
        )
    input_bytes = 0
    if isinstance(source, Document):
        document = source
    else:
        document = load_document(source)
        input_bytes = asset_bytes(source)

    def say(line: str) -> None:
        if progress is not None:
            progress(Progress("compress_scene", line))

    # A glTF's lengths are meters; another file's are its own coordinates, as its JSON
    # report says (``length_unit``).
    unit = "m" if isinstance(source, Document) else length_unit_of(source)
    instances = document.mesh_instances()
    where = "" if isinstance(source, Document) else f"{source}: "
    primitives = _decoded_primitives(document, where)
    jobs, kept = _plan_jobs(document, primitives, instances, normal_tolerance, where)
    if not jobs and not kept:
        raise MeshFileError("the scene has no triangle primitive")
    _place_in_frames(jobs, kept, document)
    world_size, reach = _world_box(primitives, instances)
    # The world positions a reader computes (float32 values through float64 node
    # transforms) carry float64 rounding that the measurement in each mesh's frame does
    # not: every bound is raised by it.
    margin = WORLD_ROUNDING * reach
    budget = given.resolve(world_size)

    def run_at(world_error: float) -> list[Outcome]:
        outcomes = []
        for job in jobs:
            local = max(world_error - margin, world_error / 2) / job.scale
            outcome = _search_primitive(job, local, codec, seed, certify)
            outcomes.append(outcome)
            if outcome[0] is not None:
                say(
                    f"mesh {job.data.mesh} primitive {job.data.index} within "
                    f"{world_error:.4g}: B = {outcome[0].bits}, V = {outcome[0].vertices}, "
                    f"{outcome[1].size_bits // 8} bytes, error "
                    f"{outcome[0].measured_error * job.scale:.4g} ({unit})"
                )
        return outcomes

    if not jobs:
        outcomes, target_error = [], budget if constraint == "error" else 0.0
    elif constraint == "error":
        outcomes, target_error = run_at(budget), budget
    else:
        outcomes, target_error = _size_search(
            document, jobs, budget, codec, seed, certify, run_at, world_size
        )
    encodings, measured, uppers = _final_encodings(
        jobs, outcomes, codec, certify, target_error, margin
    )
    _keep_what_grows(document, jobs, encodings)
    out, data = _rebuild(document, jobs, encodings, codec)
    written: bytes | None = None
    grew = _larger_than_input(source, output, input_bytes, out, data)
    if grew is not None:
        for job in jobs:
            job.kept = job.kept or grew
        out, data = _rebuild(document, jobs, encodings, codec)
        if _larger_than_input(source, output, input_bytes, out, data) and _verbatim(source, output):
            written = Path(source).read_bytes()  # type: ignore[arg-type]
    files, size_bytes = _emit(out, data, output, written)
    reports = [
        _job_report(
            document,
            job,
            outcome,
            encoding,
            error,
            upper,
            target_error,
            margin,
            certify,
            constraint,
        )
        for job, outcome, encoding, error, upper in zip(
            jobs, outcomes, encodings, measured, uppers, strict=True
        )
    ]
    reports += [_kept_report(document, data, instances, certify, margin) for data in kept]
    return _scene_result(
        constraint,
        budget,
        certify,
        codec,
        reports,
        size_bytes,
        input_bytes,
        files,
        unit,
        start,
        document.notes,
        given.describe(),
        [(job.data.positions, job.data.faces) for job in jobs] + [None] * len(kept),
    )


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


def _size_search(document, jobs, budget, codec, seed, certify, run_at, world_size):
    """A size budget (bits): one primitive's own size search, or the common world error
    that fills the file (:func:`_split_size`). Returns the outcomes and that error."""

    def file_bytes(outcomes: list[Outcome]) -> int:
        encodings, _, _ = _final_encodings(jobs, outcomes, codec, False, 0.0, 0.0, False)
        return _output_size(*_rebuild(document, jobs, encodings, codec), ".glb")

    fixed = _fixed_bytes(document, jobs)
    if budget / 8 - fixed <= 0:
        images = len(document.json.get("images", []))
        parts = (
            f"{images} image{'' if images == 1 else 's'}, its JSON and other data"
            if images
            else "its JSON and other data"
        )
        raise MeshbitsError(
            f"the size budget ({budget / 8:.6g} bytes) is less than what the output keeps "
            f"whatever its geometry: {parts} ({fixed} bytes)"
        )
    if len(jobs) == 1:
        return _size_one(jobs[0], budget, fixed, codec, seed, certify, file_bytes)
    return _split_size(jobs, budget, run_at, world_size, file_bytes)


def _final_encodings(
    jobs: list[_Job],
    outcomes: list[Outcome],
    codec: str,
    certify: bool,
    target_error: float,
    margin: float,
    measure: bool = True,
) -> tuple[list[Encoding | None], list[float], list[float | None]]:
    """Each job's encoding, measured error and certified bound (None where not
    certified; None encodings for jobs kept as they were): with meshopt, quantized again
    on one grid per cluster (:func:`_shared_grids`)."""
    measured = [0.0 if o[0] is None else o[0].measured_error for o in outcomes]
    uppers = [None if o[0] is None or not certify else o[0].measured_error_upper for o in outcomes]
    encodings = [o[1] for o in outcomes]
    if codec == "meshopt":
        budgets = (
            [max(target_error - margin, target_error / 2) / job.scale for job in jobs]
            if certify
            else None
        )
        encodings, measured, uppers = _shared_grids(jobs, outcomes, budgets, measure)
    return encodings, measured, uppers


def _input_views(document: Document, targets: list[tuple[int, int]]) -> set[int]:
    """The bufferViews a set of primitives read (attributes, indices, Draco data)."""
    views: set[int] = set()
    accessors = document.json.get("accessors", [])
    for mesh, index in targets:
        prim = document.json["meshes"][mesh]["primitives"][index]
        used = list((prim.get("attributes") or {}).values())
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
    document: Document, jobs: list[_Job], encodings: list[Encoding | None]
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
    size = _output_size(out, data, suffix)
    if size <= input_bytes:
        return None
    return f"compressed, the file would be larger than its input ({size:,} > {input_bytes:,} bytes)"


def _verbatim(source: Any, output: Any) -> bool:
    """Whether the input file itself can be the output: a .glb written as .glb."""
    suffix = Path(output).suffix.lower() if output is not None else ".glb"
    return suffix == ".glb" and Path(str(source)).suffix.lower() == ".glb"


def _kept_error(document: Document, job: _Job, certify: bool) -> tuple[float, float | None]:
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
    reference = _job_reference(job, 0)
    h = reference.hausdorff((stored, job.data.faces), bounds=certify)
    return h.distance, None if h.upper is None else float(h.upper)


def _job_report(
    document: Document,
    job: _Job,
    outcome: Outcome,
    encoding: Encoding | None,
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
    world_upper = None if upper is None else upper * job.scale + margin
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


def _kept_report(
    document: Document,
    data: PrimitiveData,
    instances: dict[int, list[tuple[int, np.ndarray]]],
    certify: bool,
    margin: float,
) -> PrimitiveReport:
    """The report of a primitive with morph targets or no faces, copied as it was (its
    bound the world rounding ``margin``)."""
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
        kept="morph targets" if data.morph else "no faces",
        error_upper=0.0 if certify else None,
        world_error_upper=margin if certify else None,
    )


def _scene_result(
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


def _shared_grids(
    jobs: list[_Job],
    outcomes: list[Outcome],
    budgets: list[float] | None = None,
    measure: bool = True,
) -> tuple[list[Encoding | None], list[float], list[float | None]]:
    """meshopt: the jobs of one cluster share their meshes' node transforms, so integer
    positions need one dequantization for all of them: they are quantized again on one
    cube grid over their boxes, with the bits whose step is at most the finest any of them
    chose. Where that takes more than 16 bits, or some job of the cluster stores float32
    positions (skinned, instanced, beyond 16 bits), every job stores float32 positions on
    its own grid instead, which need no shared transform. What changed is measured again
    (unless ``measure`` is False; with ``budgets``, one per job, certified again against
    them). Returns the encodings, their errors and their certified bounds (None where not
    certified, and for jobs kept as they were)."""
    clusters: dict[int, list[int]] = {}
    for i, (job, outcome) in enumerate(zip(jobs, outcomes, strict=True)):
        if outcome[0] is not None:
            clusters.setdefault(job.cluster, []).append(i)
    encodings = [o[1] for o in outcomes]
    measured = [0.0 if o[0] is None else o[0].measured_error for o in outcomes]
    uppers = [None if o[0] is None else o[0].measured_error_upper for o in outcomes]

    def again(i: int, encoding: Encoding) -> None:
        encodings[i] = encoding
        if not measure:
            return
        reference = jobs[i].reference
        assert reference is not None
        mesh = (encoding.vertices, encoding.faces)
        if budgets is None:
            measured[i], uppers[i] = reference.hausdorff(mesh).distance, None
            return
        h = reference.hausdorff(
            mesh, bounds=True, tolerance=CERTIFY_TOLERANCE * budgets[i], threshold=budgets[i]
        )
        measured[i] = h.distance
        uppers[i] = float(h.upper) if h.upper is not None else None

    for members in clusters.values():
        for i in members:
            encodings[i].bits = outcomes[i][0].bits
        integer = all(encodings[i].dequantize is not None for i in members)
        if integer and len(members) == 1:
            continue
        levels = [outcomes[i][2] for i in members]
        if integer:
            lo = np.min([np.minimum(lv.origin, lv.vertices.min(axis=0)) for lv in levels], axis=0)
            hi = np.max([lv.vertices.max(axis=0) for lv in levels], axis=0)
            origin, side = cube_grid(lo, np.maximum(hi, lo))
            finest = min(
                lv.grid_size / (2 ** outcomes[i][0].bits - 1)
                for i, lv in zip(members, levels, strict=True)
            )
            bits = max(1, math.ceil(math.log2(side / finest + 1))) if side > 0 else 1
            # The shared grid's points are not the ones each job was measured on: where
            # one now misses its budget, finer grids are tried before float32 positions.
            for shared_bits in range(
                bits, min(bits + SHARED_GRID_EXTRA_BITS, MESHOPT_INTEGER_BITS) + 1
            ):
                for i, level in zip(members, levels, strict=True):
                    encoding = encode_meshopt_primitive(
                        level.vertices,
                        level.faces,
                        level.attributes,
                        shared_bits,
                        origin,
                        side,
                        jobs[i].bits,
                    )
                    encoding.bits = shared_bits
                    again(i, encoding)
                if budgets is None or all(
                    uppers[i] is not None and uppers[i] <= budgets[i] for i in members
                ):
                    break
            else:
                if bits <= MESHOPT_INTEGER_BITS:
                    integer = False
            if integer and bits <= MESHOPT_INTEGER_BITS:
                continue
        for i, level in zip(members, levels, strict=True):
            if encodings[i].dequantize is None:
                continue
            bits = outcomes[i][0].bits
            encoding = encode_meshopt_primitive(
                level.vertices,
                level.faces,
                level.attributes,
                bits,
                level.origin,
                level.grid_size,
                jobs[i].bits,
                integer_positions=False,
            )
            encoding.bits = bits
            again(i, encoding)
    return encodings, measured, uppers


def _decoded_primitives(document: Document, where: str) -> list[PrimitiveData]:
    """``document.triangle_primitives()``, a file's errors prefixed with ``where`` (its
    path and a colon, or nothing)."""
    try:
        return document.triangle_primitives()
    except MeshFileError as error:
        if not where:
            raise
        raise MeshFileError(f"{where}{error}") from error


def _world_box(
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


def _place_in_frames(jobs: list[_Job], kept: list[PrimitiveData], document: Document) -> None:
    """Group the jobs into clusters of meshes that must share frames (a job shared by
    several meshes joins them), mark the clusters whose meshes can take a frame of their
    own from the nodes that show them (``_Job.framed``), and move those far from the
    origin to their centre (:func:`meshbits.formats.gltf.write.frame_centre`;
    ``_Job.offset``), so that their float32 and quantized positions keep their precision."""
    parent: dict[int, int] = {}

    def root(mesh: int) -> int:
        while parent.setdefault(mesh, mesh) != mesh:
            mesh = parent[mesh]
        return mesh

    for job in jobs:
        first, *others = sorted(job.meshes)
        for mesh in others:
            parent[root(mesh)] = root(first)
    clusters: dict[int, list[_Job]] = {}
    for job in jobs:
        clusters.setdefault(root(min(job.meshes)), []).append(job)
    unframed = document.instanced_meshes() | {data.mesh for data in kept}
    for number, members in enumerate(clusters.values()):
        meshes = {mesh for job in members for mesh in job.meshes}
        framed = not (meshes & unframed) and not any(job.data.skinned for job in members)
        centre = np.zeros(3)
        if framed:
            centre = frame_centre(np.concatenate([job.data.positions for job in members]))
        for job in members:
            job.cluster, job.framed = number, framed
            if centre.any():
                job.offset = centre
                job.data = replace(job.data, positions=job.data.positions - centre)


def _split_size(jobs, size_bits, run_at, world_size, file_bytes):
    """The common world-space error whose primitives fill the size budget: the split of
    bytes that minimises the scene's largest error. Each try is judged by the bytes of the
    file it makes (``file_bytes``: the document rebuilt around it, images, JSON and the
    codec's own entries included). The next error comes from the sizes measured so far,
    bytes against error on a log-log scale: the line through the two tries that bracket
    the budget, or through the last two (bytes fall about as 1/E) until they do. It stops
    when a file fills :data:`SIZE_SPLIT_FILL` of the budget, when the bracket is within 2%,
    or after :data:`SIZE_SPLIT_PASSES` tries. The answer is the try within the budget with
    the least measured world-space error (not the least target)."""
    budget_bytes = size_bits / 8
    aim = SIZE_SPLIT_AIM * budget_bytes
    error = 0.002 * world_size
    best = None  # (measured world error, outcomes, target error)
    tried: list[tuple[float, int]] = []
    for _ in range(SIZE_SPLIT_PASSES):
        outcomes = run_at(error)
        total = file_bytes(outcomes)
        tried.append((error, total))
        if total <= budget_bytes:
            measured = max(
                (
                    o[0].measured_error * job.scale
                    for o, job in zip(outcomes, jobs, strict=True)
                    if o[0] is not None
                ),
                default=0.0,
            )
            if best is None or measured < best[0]:
                best = (measured, outcomes, error)
            if total >= SIZE_SPLIT_FILL * budget_bytes:
                break
        fitting = [(e, t) for e, t in tried if t <= budget_bytes]
        over = [(e, t) for e, t in tried if t > budget_bytes]
        if fitting and over:
            e_fit, t_fit = min(fitting)  # the finest try that fits
            e_over, t_over = max(over)  # the coarsest try over the budget
            if e_fit / e_over < 1.02:
                break
            bracket = (min(e_fit, e_over), max(e_fit, e_over))
            error = _log_line(e_fit, t_fit, e_over, t_over, aim, inside=bracket)
        elif len(tried) >= 2:
            (e0, t0), (e1, t1) = tried[-2], tried[-1]
            error = _log_line(e0, t0, e1, t1, aim, inside=None)
        else:
            error *= min(max(total / aim, 1 / 16), 16.0)
    if best is None:
        error, _ = min(tried, key=lambda et: et[1])
        return run_at(error), error
    return best[1], best[2]


def _size_one(
    job: _Job, size_bits: float, fixed: int, codec: str, seed: int, certify: bool, file_bytes
):
    """A scene with one primitive to compress: its own size search (as ``compress`` runs
    it), for the budget less what the file keeps besides it (``fixed`` bytes, estimated,
    less than the budget). The answer's file tells the rest exactly; when it is over, the
    primitive's share shrinks by the excess (:data:`SIZE_ONE_TRIES` searches at most).
    Returns the outcome and, as the common error, the answer's certified bound (or its
    error), in world units."""
    budget_bytes = size_bits / 8
    share = budget_bytes - fixed
    outcome = KEPT
    for _ in range(SIZE_ONE_TRIES):
        outcome = _search_primitive(job, 8 * share, codec, seed, certify, "size")
        if outcome[0] is None:
            return [outcome], 0.0
        primitive = outcome[1].size_bits // 8
        total = file_bytes([outcome])
        if total <= budget_bytes:
            break
        share = primitive - (total - budget_bytes) - SIZE_ONE_MARGIN
        if share <= 0:
            break
    record = outcome[0]
    upper = record.measured_error_upper
    error = record.measured_error if upper is None else upper
    return [outcome], error * job.scale


def _log_line(
    e0: float, t0: float, e1: float, t1: float, aim: float, inside: tuple[float, float] | None
) -> float:
    """The error at which the line through ``(e0, t0)`` and ``(e1, t1)`` (error, bytes),
    on log-log axes, reaches ``aim`` bytes. Its slope is kept between -3 and -1/3 (bytes
    fall as the error grows; a flat or rising pair gives -1); ``inside`` keeps the answer
    at least a tenth of the log-distance from either end of a bracket; without one, a step
    is at most 16 times either way."""
    slope = -1.0
    if e0 > 0 and e1 > 0 and t0 > 0 and t1 > 0 and e0 != e1:
        fitted = math.log(t1 / t0) / math.log(e1 / e0)
        if fitted < 0:
            slope = min(max(fitted, -3.0), -1 / 3)
    error = e1 * (aim / max(t1, 1)) ** (1 / slope)
    if inside is not None:
        lo, hi = math.log(inside[0]), math.log(inside[1])
        margin = 0.1 * (hi - lo)
        return math.exp(min(max(math.log(error), lo + margin), hi - margin))
    return min(max(error, e1 / 16), e1 * 16)


def _fixed_bytes(document: Document, jobs: list[_Job]) -> int:
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
    images = {_image_key(document, i): i for i in range(len(document.json.get("images", [])))}
    for i in images.values():
        total += len(document.image_bytes(i)[0])
    return total + len(json.dumps(document.json))


def _image_key(document: Document, index: int) -> tuple[str, Any]:
    """What an image's data is: its bufferView or its URI (images sharing it share it)."""
    image = document.json["images"][index]
    if image.get("bufferView") is not None:
        return ("view", image["bufferView"])
    return ("uri", image.get("uri"))


# --- writing ------------------------------------------------------------------------------


class _Blob:
    """The output buffer: bytes appended at 4-byte alignment."""

    def __init__(self) -> None:
        self.parts: list[bytes] = []
        self.length = 0

    def add(self, data: bytes) -> int:
        pad = (-self.length) % 4
        if pad:
            self.parts.append(b"\0" * pad)
            self.length += pad
        offset = self.length
        self.parts.append(bytes(data))
        self.length += len(data)
        return offset

    def bytes(self) -> bytes:
        return b"".join(self.parts) + b"\0" * ((-self.length) % 4)


def _rebuild(
    document: Document, jobs: list[_Job], encodings: list[Encoding | None], codec: str
) -> tuple[dict[str, Any], bytes]:
    """The document (JSON) and its binary buffer with the compressed primitives: each
    job's data once, every primitive of its ``targets`` pointing at it; the primitives of
    jobs kept as they were, and everything else, copied."""
    out = copy.deepcopy(document.json)
    blob = _Blob()
    fallback = _Blob()
    views: list[dict[str, Any]] = []
    accessors: list[dict[str, Any]] = []
    compressed = [
        (job, encoding)
        for job, encoding in zip(jobs, encodings, strict=True)
        if job.kept is None and encoding is not None
    ]
    replaced = {target for job, _ in compressed for target in job.targets}
    view_map: dict[int, int] = {}

    def copy_view(old: int) -> int:
        if old not in view_map:
            spec = {
                k: v
                for k, v in document.json["bufferViews"][old].items()
                if k not in ("buffer", "byteOffset", "extensions")
            }
            spec["buffer"] = 0
            spec["byteOffset"] = blob.add(bytes(document.view_bytes(old)))
            views.append(spec)
            view_map[old] = len(views) - 1
        return view_map[old]

    accessor_map: dict[int, int] = {}

    def copy_accessor(old: int) -> int:
        if old not in accessor_map:
            spec = copy.deepcopy(document.json["accessors"][old])
            if spec.get("bufferView") is not None:
                spec["bufferView"] = copy_view(spec["bufferView"])
            if spec.get("sparse"):
                for part in ("indices", "values"):
                    spec["sparse"][part]["bufferView"] = copy_view(
                        spec["sparse"][part]["bufferView"]
                    )
            accessors.append(spec)
            accessor_map[old] = len(accessors) - 1
        return accessor_map[old]

    # Everything not replaced keeps its accessors (data copied as it was).
    for m, mesh in enumerate(out.get("meshes", [])):
        for p, prim in enumerate(mesh.get("primitives", [])):
            if (m, p) in replaced:
                continue
            source = document.json["meshes"][m]["primitives"][p]
            prim["attributes"] = {
                k: copy_accessor(v) for k, v in source.get("attributes", {}).items()
            }
            if source.get("indices") is not None:
                prim["indices"] = copy_accessor(source["indices"])
            if source.get("targets"):
                prim["targets"] = [
                    {k: copy_accessor(v) for k, v in t.items()} for t in source["targets"]
                ]
            draco = (source.get("extensions") or {}).get("KHR_draco_mesh_compression")
            if draco is not None:
                prim.setdefault("extensions", {})["KHR_draco_mesh_compression"] = {
                    **draco,
                    "bufferView": copy_view(draco["bufferView"]),
                }
    for skin in out.get("skins", []):
        if skin.get("inverseBindMatrices") is not None:
            skin["inverseBindMatrices"] = copy_accessor(skin["inverseBindMatrices"])
    for animation in out.get("animations", []):
        for sampler in animation.get("samplers", []):
            sampler["input"] = copy_accessor(sampler["input"])
            sampler["output"] = copy_accessor(sampler["output"])
    for node in out.get("nodes", []):
        instancing = (node.get("extensions") or {}).get("EXT_mesh_gpu_instancing")
        if instancing:
            instancing["attributes"] = {
                k: copy_accessor(v) for k, v in instancing.get("attributes", {}).items()
            }
    # Images that share their data (one bufferView, or one URI) keep sharing it.
    image_views: dict[Any, int] = {}
    for i, image in enumerate(out.get("images", [])):
        data, mime = document.image_bytes(i)
        key = _image_key(document, i)
        if key not in image_views:
            views.append({"buffer": 0, "byteOffset": blob.add(data), "byteLength": len(data)})
            image_views[key] = len(views) - 1
        image.pop("uri", None)
        image["bufferView"] = image_views[key]
        if mime:
            image["mimeType"] = mime

    frames: dict[int, tuple[np.ndarray, float]] = {}
    for job, encoding in compressed:
        attributes = {}
        for name, spec in encoding.accessors.items():
            if name == "indices":
                continue
            accessors.append(dict(spec))
            attributes[name] = len(accessors) - 1
        accessors.append(dict(encoding.accessors["indices"]))
        indices = len(accessors) - 1
        draco = None
        if codec == "draco":
            views.append(
                {
                    "buffer": 0,
                    "byteOffset": blob.add(encoding.draco),
                    "byteLength": len(encoding.draco),
                }
            )
            draco = {
                "bufferView": len(views) - 1,
                "attributes": {name: encoding.draco_ids[name] for name in attributes},
            }
        else:
            for stream in encoding.streams:
                target = 34963 if stream["mode"] == "TRIANGLES" else 34962
                view = {
                    "buffer": 1,
                    "byteOffset": fallback.add(stream["raw"]),
                    "byteLength": len(stream["raw"]),
                    "target": target,
                    "extensions": {
                        "EXT_meshopt_compression": {
                            "buffer": 0,
                            "byteOffset": blob.add(stream["data"]),
                            "byteLength": len(stream["data"]),
                            "byteStride": stream["stride"],
                            "count": stream["count"],
                            "mode": stream["mode"],
                            **({"filter": stream["filter"]} if stream["filter"] != "NONE" else {}),
                        }
                    },
                }
                if stream["mode"] == "ATTRIBUTES":
                    view["byteStride"] = stream["stride"]
                views.append(view)
                index = len(views) - 1
                key = indices if stream["name"] == "indices" else attributes[stream["name"]]
                accessors[key]["bufferView"] = index
        for mesh, number in job.targets:
            _point_at(out["meshes"][mesh]["primitives"][number], attributes, indices, draco)
            if encoding.dequantize is not None:
                origin, step = encoding.dequantize
                frames[mesh] = (job.offset + origin, step)
            elif job.offset.any():
                frames[mesh] = (job.offset, 1.0)
    if frames:
        _apply_frames(out, document, frames)
    out["accessors"] = accessors
    out["bufferViews"] = views
    extensions_used = set(out.get("extensionsUsed", []))
    extensions_required = set(out.get("extensionsRequired", []))
    still_draco = any(
        "KHR_draco_mesh_compression" in (p.get("extensions") or {})
        for mesh in out.get("meshes", [])
        for p in mesh.get("primitives", [])
    )
    if not still_draco:
        extensions_used.discard("KHR_draco_mesh_compression")
        extensions_required.discard("KHR_draco_mesh_compression")
    # A meshopt input's bufferViews were decoded on reading and are copied plain: only the
    # compressed primitives written here use meshopt.
    extensions_used.difference_update(MESHOPT_EXTENSIONS)
    extensions_required.difference_update(MESHOPT_EXTENSIONS)
    new = {"KHR_draco_mesh_compression"} if codec == "draco" else {"EXT_meshopt_compression"}
    if codec == "meshopt":
        new.add("KHR_mesh_quantization")
    if not compressed:
        new = set()
    out["extensionsUsed"] = sorted(extensions_used | new)
    out["extensionsRequired"] = sorted(extensions_required | new)
    data = blob.bytes()
    buffers = [{"byteLength": len(data)}]
    if codec == "meshopt" and compressed:
        buffers.append(
            {
                "byteLength": fallback.length + (-fallback.length) % 4,
                "extensions": {"EXT_meshopt_compression": {"fallback": True}},
            }
        )
    out["buffers"] = buffers
    out.setdefault("asset", {})["generator"] = "meshbits"
    return out, data


def _point_at(
    prim: dict[str, Any],
    attributes: dict[str, int],
    indices: int,
    draco: dict[str, Any] | None,
) -> None:
    """Point a primitive at its compressed accessors (and Draco data)."""
    extensions = prim.get("extensions") or {}
    extensions.pop("KHR_draco_mesh_compression", None)
    if draco is not None:
        extensions["KHR_draco_mesh_compression"] = dict(draco)
    if extensions:
        prim["extensions"] = extensions
    else:
        prim.pop("extensions", None)
    prim["mode"] = 4
    prim["attributes"] = dict(attributes)
    prim["indices"] = indices


def _output_size(out: dict[str, Any], data: bytes, suffix: str) -> int:
    """Bytes of the file :func:`_emit` writes: a GLB, or a ``.gltf``'s JSON and buffer."""
    if suffix == ".gltf":
        named = {**out, "buffers": [{**out["buffers"][0], "uri": "x.bin"}, *out["buffers"][1:]]}
        return len(json.dumps(named, separators=(",", ":")).encode()) + len(data)
    return len(_glb(out, data))


def _emit(
    out: dict[str, Any], data: bytes, output: str | Path | None, verbatim: bytes | None = None
) -> tuple[list[str], int]:
    """Write the document (atomically), as GLB or as ``.gltf`` with its buffer beside it
    named after it; or ``verbatim``, the input's own bytes. Returns the files and the
    output's size."""
    if output is None:
        return [], len(verbatim) if verbatim is not None else len(_glb(out, data))
    path = Path(output)
    if verbatim is not None:
        write_atomic(path, verbatim)
        return [str(path)], len(verbatim)
    if path.suffix.lower() == ".glb":
        glb = _glb(out, data)
        write_atomic(path, glb)
        return [str(path)], len(glb)
    bin_name = f"{path.stem}.bin"
    out["buffers"][0]["uri"] = bin_name
    text = json.dumps(out, separators=(",", ":")).encode()
    write_atomic(path.with_name(bin_name), data)
    write_atomic(path, text)
    return [str(path), str(path.with_name(bin_name))], len(text) + len(data)


def _glb(document: dict[str, Any], binary: bytes) -> bytes:
    """A GLB container: the JSON chunk (space-padded) and the binary chunk."""
    import struct

    text = json.dumps(document, separators=(",", ":")).encode()
    text += b" " * ((-len(text)) % 4)
    binary += b"\0" * ((-len(binary)) % 4)
    total = 12 + 8 + len(text) + (8 + len(binary) if binary else 0)
    parts = [struct.pack("<4sII", b"glTF", 2, total), struct.pack("<I4s", len(text), b"JSON"), text]
    if binary:
        parts += [struct.pack("<I4s", len(binary), b"BIN\0"), binary]
    return b"".join(parts)


def _apply_frames(
    out: dict[str, Any], document: Document, frames: dict[int, tuple[np.ndarray, float]]
) -> None:
    """A mesh whose positions are stored in a frame of their own (``mesh -> (origin,
    step)``: a reader places ``origin + step * stored``; integer codes with meshopt,
    positions relative to their centre with Draco) has it folded into the nodes that show
    it, or, for a node that carries more than the mesh (children, an animation, a skin, a
    camera, extensions), into a new child node that takes the mesh over."""
    animated = document.animated_nodes()
    nodes = out.setdefault("nodes", [])
    for index in range(len(nodes)):
        node = nodes[index]
        mesh = node.get("mesh")
        if mesh is None or mesh not in frames:
            continue
        origin, step = frames[mesh]
        alone = set(node) <= {"mesh", "name", "translation", "rotation", "scale", "matrix"}
        if not alone or index in animated:
            child: dict[str, Any] = {"mesh": mesh, "translation": [json_number(x) for x in origin]}
            if step != 1.0:
                child["scale"] = [step] * 3
            if "weights" in node:
                child["weights"] = node.pop("weights")
            node.pop("mesh")
            nodes.append(child)
            node.setdefault("children", []).append(len(nodes) - 1)
            continue
        local = document.node_matrix(index)
        d = np.eye(4)
        d[:3, :3] *= step
        d[:3, 3] = origin
        if "matrix" in node:
            node["matrix"] = [float(x) for x in (local @ d).T.reshape(-1)]
        else:
            rotation_scale = local[:3, :3]
            node["translation"] = [json_number(x) for x in local[:3, 3] + rotation_scale @ origin]
            if step != 1.0:
                node["scale"] = [float(s) * step for s in node.get("scale", [1.0, 1.0, 1.0])]


#: Inputs that can hold more than positions and faces (materials, textures, UVs, normals,
#: a node hierarchy): a merged-mesh output says what it leaves out of them
#: (:func:`omitted_by_merging`). An OBJ's MTL materials and textures count.
RICH_INPUT_SUFFIXES = (".glb", ".gltf", ".obj")


def merged_away(path: str | Path) -> dict[str, Any] | None:
    """:func:`omitted_by_merging` for an input of :data:`RICH_INPUT_SUFFIXES`; None for
    another file, and for an OBJ whose materials cannot be read as a scene (its mesh
    was read: trimesh's glTF export of it failed, so nothing of it is known to be lost)."""
    suffix = Path(path).suffix.lower()
    if suffix not in RICH_INPUT_SUFFIXES:
        return None
    try:
        return omitted_by_merging(path)
    except MeshbitsError:
        if suffix == ".obj":
            return None
        raise


def omitted_by_merging(path: str | Path) -> dict[str, Any]:
    """What writing a glTF scene (or an OBJ, read as one) as one merged mesh of positions
    (what :func:`meshbits.load_mesh` reads, written to ``.drc``, ``.ply``...) leaves out,
    counted:
    materials, textures, images, skins, animations and morph targets (those present), and
    ``attributes``, the names of the vertex attributes other than ``POSITION``, and for an
    OBJ whose ``mtllib`` files are not beside it, ``missing_material_libraries``. The node
    hierarchy is flattened: every instance is placed in world space."""
    j = load_document(path).json
    attributes: set[str] = set()
    targets = 0
    for mesh in j.get("meshes") or []:
        for primitive in mesh.get("primitives") or []:
            attributes.update(a for a in primitive.get("attributes") or {} if a != "POSITION")
            targets += len(primitive.get("targets") or [])
    counts = {
        key: len(j.get(key) or [])
        for key in ("materials", "textures", "images", "skins", "animations")
    }
    counts["morph_targets"] = targets
    missing = missing_material_libraries(Path(path))
    return {**{k: n for k, n in counts.items() if n}, "attributes": sorted(attributes)} | (
        {"missing_material_libraries": missing} if missing else {}
    )


def scene_info(path: str | Path) -> dict[str, Any]:
    """What a scene file holds: meshes, primitives with their attributes, materials,
    textures and images, nodes, animations, skins, extensions, and bytes by part."""
    document = load_document(path)
    j = document.json
    meshes = []
    geometry_views: set[int] = set()
    for m, mesh in enumerate(j.get("meshes", [])):
        prims = []
        for p, prim in enumerate(mesh.get("primitives", [])):
            attributes = {}
            for name, acc in prim.get("attributes", {}).items():
                spec = j["accessors"][acc]
                attributes[name] = (
                    f"{spec['type']} {np.dtype(_dtype_name(spec['componentType'])).name}"
                    + (" normalized" if spec.get("normalized") else "")
                )
                exact = document.exact_positions.get(acc) if name == "POSITION" else None
                if exact is not None and not np.array_equal(
                    exact.astype(np.float32).astype(np.float64), exact
                ):
                    # A PLY, OBJ... read as a glTF scene: meshbits measures and keeps the
                    # file's own float64 coordinates, not the float32 accessor.
                    attributes[name] = f"{spec['type']} float64"
                if spec.get("bufferView") is not None:
                    geometry_views.add(spec["bufferView"])
            if (
                prim.get("indices") is not None
                and j["accessors"][prim["indices"]].get("bufferView") is not None
            ):
                geometry_views.add(j["accessors"][prim["indices"]]["bufferView"])
            extensions = sorted((prim.get("extensions") or {}).keys())
            draco = (prim.get("extensions") or {}).get("KHR_draco_mesh_compression")
            if draco:
                geometry_views.add(draco["bufferView"])
            vertices = (
                j["accessors"][prim["attributes"]["POSITION"]]["count"]
                if "POSITION" in prim.get("attributes", {})
                else 0
            )
            faces = (
                (j["accessors"][prim["indices"]]["count"] // 3)
                if prim.get("indices") is not None
                else vertices // 3
            )
            prims.append(
                {
                    "primitive": p,
                    "mode": prim.get("mode", 4),
                    "vertices": vertices,
                    "faces": faces,
                    "attributes": attributes,
                    "material": prim.get("material"),
                    "morph_targets": len(prim.get("targets", [])),
                    "morph_target_attributes": sorted(
                        {name for target in prim.get("targets", []) for name in target}
                    ),
                    "extensions": extensions,
                }
            )
        meshes.append({"mesh": m, "name": mesh.get("name"), "primitives": prims})
    for data in _decoded_primitives(document, f"{path}: "):
        finite = np.isfinite(data.positions).all(axis=1)
        prim_info = meshes[data.mesh]["primitives"][data.index]
        prim_info["non_finite_positions"] = int(len(finite) - finite.sum())
        corners = data.positions[data.faces]
        with np.errstate(invalid="ignore"):
            doubled = np.linalg.norm(
                np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1
            )
        prim_info["zero_area_faces"] = int((doubled == 0).sum())
        prim_info["distinct_vertices"] = distinct_vertices(data.positions, data.attributes)
    image_views = {
        im["bufferView"] for im in j.get("images", []) if im.get("bufferView") is not None
    }
    animation_views = set()
    for animation in j.get("animations", []):
        for sampler in animation.get("samplers", []):
            for key in ("input", "output"):
                view = j["accessors"][sampler[key]].get("bufferView")
                if view is not None:
                    animation_views.add(view)
    sizes = {"geometry": 0, "images": 0, "animation": 0, "other": 0}
    for v, view in enumerate(j.get("bufferViews", [])):
        part = (
            "geometry"
            if v in geometry_views
            else "images"
            if v in image_views
            else "animation"
            if v in animation_views
            else "other"
        )
        # What the file holds: a meshopt bufferView's compressed bytes.
        compressed = next(
            (
                view["extensions"][name]
                for name in MESHOPT_EXTENSIONS
                if name in (view.get("extensions") or {})
            ),
            view,
        )
        sizes[part] += int(compressed.get("byteLength", 0))
    images = []
    for i, image in enumerate(j.get("images", [])):
        data, mime = document.image_bytes(i)
        if image.get("bufferView") is None:
            sizes["images"] += len(data)
        images.append(
            {
                "image": i,
                "name": image.get("name"),
                "mimeType": mime,
                "bytes": len(data),
                "size": image_size(data),
            }
        )
    return {
        "file": str(path),
        "bytes": asset_bytes(path),
        "meshes": meshes,
        "nodes": len(j.get("nodes", [])),
        "scenes": len(j.get("scenes", [])),
        "materials": len(j.get("materials", [])),
        "textures": len(j.get("textures", [])),
        "images": images,
        "samplers": len(j.get("samplers", [])),
        "skins": len(j.get("skins", [])),
        "animations": len(j.get("animations", [])),
        "skin_details": [
            {"skin": i, "name": skin.get("name"), "joints": len(skin.get("joints", []))}
            for i, skin in enumerate(j.get("skins", []))
        ],
        "animation_details": [
            _animation_info(document, i) for i in range(len(j.get("animations", [])))
        ],
        "cameras": len(j.get("cameras", [])),
        "extensions_used": j.get("extensionsUsed", []),
        "extensions_required": j.get("extensionsRequired", []),
        "bytes_by_part": sizes,
        "json_bytes": _json_bytes(Path(path), j),
    }


def _animation_info(document: Document, index: int) -> dict[str, Any]:
    """An animation's name, its channels by target path, its keyframes (the samplers'
    inputs, counted) and its duration (seconds, the largest input time)."""
    animation = document.json["animations"][index]
    paths: dict[str, int] = {}
    for channel in animation.get("channels", []):
        path = (channel.get("target") or {}).get("path", "?")
        paths[path] = paths.get(path, 0) + 1
    keyframes, duration = 0, 0.0
    for sampler in animation.get("samplers", []):
        times = document.accessor(sampler["input"])
        keyframes += len(times)
        if len(times):
            duration = max(duration, float(np.max(times)))
    return {
        "animation": index,
        "name": animation.get("name"),
        "channels": len(animation.get("channels", [])),
        "paths": paths,
        "keyframes": keyframes,
        "duration": duration,
    }


def _json_bytes(path: Path, document_json: dict) -> int:
    """Bytes of a file's glTF JSON: a .gltf's own size, a .glb's JSON chunk (padding
    included); for another format (converted on reading), the JSON as serialised here."""
    suffix = path.suffix.lower()
    if suffix == ".gltf":
        return path.stat().st_size
    if suffix == ".glb":
        with open(path, "rb") as file:
            header = file.read(20)
        if len(header) == 20 and header[:4] == b"glTF" and header[16:20] == b"JSON":
            return int.from_bytes(header[12:16], "little")
    return len(json.dumps(document_json))


def _dtype_name(component: int) -> Any:
    return COMPONENT_DTYPES[component]
