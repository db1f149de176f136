"""Writing glTF: the one writer of every glTF meshbits writes.

One concept: a glTF document and its binary, rebuilt and written.
A scene's document is rebuilt around its compressed primitives
(:func:`rebuild_document`: Draco or meshopt data, frames folded into the nodes, everything
else copied), a mesh becomes a document through trimesh's glTF export
(:func:`mesh_document`), and either is written by :func:`write_document`, as GLB or as a
``.gltf`` with its buffer beside it named after it; the GLB container is
:func:`glb_bytes`, which the quantized GLB of :mod:`meshbits.codecs.fixed_width` also
uses. Also where to put the origin of
positions stored in float32 (:func:`frame_centre`) and short exact JSON numbers.
"""

from __future__ import annotations

import copy
import json
import math
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from ... import _core
from ...errors import MeshbitsError
from ...files import write_atomic
from .document import Document
from .skins import Frame, folded_matrix_bytes, skin_frames
from .spec import MESHOPT_EXTENSIONS

__all__ = [
    "FRAME_DISTANCE",
    "CompressedGeometry",
    "EncodedAnimations",
    "EncodedGeometry",
    "document_size",
    "float32_safe",
    "frame_centre",
    "glb_bytes",
    "image_key",
    "json_number",
    "json_text",
    "mesh_document",
    "number_text",
    "rebuild_document",
    "split_translation",
    "write_document",
    "write_mesh",
]

#: A mesh whose box centre is farther from the origin than this many times its largest
#: side is stored relative to that centre (:func:`frame_centre`): there float32 rounds a
#: position by up to 1e-6 of the side, a sixteenth of a grid step at 18 bits.
FRAME_DISTANCE = 16.0


def frame_centre(points: np.ndarray) -> np.ndarray:
    """Where to put the origin of positions stored in float32 (mesh units): the centre of
    the points' box when it is farther from the origin than :data:`FRAME_DISTANCE` sides
    (else the origin itself), rounded to a multiple of the power of two at or above its
    largest side and at or above the float32 spacing of its largest coordinate: a short
    number in the JSON that float32 holds exactly, so a reader that keeps node transforms
    in float32 places the positions where a float64 reader does. The positions stay
    within half that power of two plus half a side of it."""
    if len(points) == 0:
        return np.zeros(3)
    lo, hi = points.min(axis=0), points.max(axis=0)
    extent = float((hi - lo).max())
    centre = (lo + hi) / 2
    if not np.abs(centre).max() > FRAME_DISTANCE * extent:
        return np.zeros(3)
    return _float32_multiple(centre, extent)


def _float32_multiple(value: np.ndarray, extent: float) -> np.ndarray:
    """``value`` rounded, component by component, to the float32 that :func:`json_text`
    writes shortest among those within half a unit of it (the unit: the power of two at
    or above ``extent`` and at or above the float32 spacing of its largest component):
    the multiple of the unit nearest to it, or a decimal of fewer digits (``42e4`` for
    420000.3 at a unit of 0.25, where the multiple is 420000.25). Every component is a
    float32 exactly and within half a unit of ``value``."""
    value = np.asarray(value, dtype=np.float64)
    largest = float(np.abs(value).max()) if value.size else 0.0
    unit = float(np.spacing(np.float32(largest))) if largest > 0 else 0.0
    if extent > 0:
        unit = max(unit, 2.0 ** math.ceil(math.log2(extent)))
    if unit == 0:
        return value.copy()
    return np.array([_short_within(float(v), unit) for v in value])


def _short_within(value: float, unit: float) -> float:
    """The float32 of the shortest JSON text within ``unit / 2`` of ``value``: the
    nearest multiple of ``unit``, or a rounding of ``value`` to fewer significant digits
    (ties: the nearer one)."""
    candidates = [round(value / unit) * unit]
    for digits in range(1, 10):
        rounded = float(f"{value:.{digits - 1}e}")
        if abs(rounded - value) <= unit / 2 and float(np.float32(rounded)) == rounded:
            candidates.append(rounded)
    return min(candidates, key=lambda c: (len(number_text(c)), abs(c - value)))


def float32_safe(translation: np.ndarray, extent: float) -> bool:
    """Whether a reader that rounds ``translation`` to float32 moves what it places by no
    more than float32 rounds a position within :data:`FRAME_DISTANCE` sides of the
    origin: it is a float32 exactly, or within that distance of the origin."""
    translation = np.asarray(translation, dtype=np.float64)
    if np.array_equal(translation.astype(np.float32).astype(np.float64), translation):
        return True
    return bool(np.abs(translation).max() <= FRAME_DISTANCE * extent)


def split_translation(translation: np.ndarray, extent: float) -> tuple[np.ndarray, np.ndarray]:
    """``translation`` as ``outer + inner``, ``outer`` a float32 exactly (a multiple of a
    power of two at or above ``extent``, :func:`frame_centre`'s rounding) and ``inner``
    within that power of two of the origin: two nodes, the outer the parent, that a
    float32 reader places as a float64 reader does (to float32's rounding of ``inner``)."""
    translation = np.asarray(translation, dtype=np.float64)
    outer = _float32_multiple(translation, extent)
    return outer, translation - outer


def json_number(value: float) -> float:
    """A float64 for the JSON: :func:`json_text` writes it shortest and exactly
    (``42e4`` for ``420000.0``; ``0`` for ``-0.0``)."""
    return float(value)


def number_text(value: float) -> str:
    """The shortest JSON number that reads back as ``value`` exactly: an integral value
    as an integer or, where three or more zeros end it, with an exponent (``1e6``, as
    gltfpack writes such numbers too); any other as Python's shortest round-trip decimal
    with the exponent's ``+`` and leading zeros dropped (``1e-5``, not ``1e-05``). A
    value that is not finite, which only an input's own JSON copied as it was can hold
    (Python's reader takes ``NaN``), is written back as :func:`json.dumps` writes it."""
    value = float(value)
    if not math.isfinite(value):
        return json.dumps(value)
    if value.is_integer() and abs(value) < 1e16:
        digits = str(int(value))
        stripped = digits.rstrip("0")
        zeros = len(digits) - len(stripped)
        return f"{stripped}e{zeros}" if zeros >= 3 else digits
    text = repr(value)
    if "e" in text:
        mantissa, exponent = text.split("e")
        text = f"{mantissa}e{int(exponent)}"
    return text


def json_text(document: object) -> bytes:
    """The compact JSON of a glTF document (no spaces): integers (counts, offsets,
    indices) as integers, every float as :func:`number_text` writes it, strings as
    :func:`json.dumps` writes them (ASCII, escaped)."""
    parts: list[str] = []
    _encode(document, parts)
    return "".join(parts).encode()


def _encode(value: object, parts: list[str]) -> None:
    if value is None:
        parts.append("null")
    elif value is True or value is False:
        parts.append("true" if value else "false")
    elif isinstance(value, int | np.integer):
        parts.append(str(int(value)))
    elif isinstance(value, float | np.floating):
        parts.append(number_text(float(value)))
    elif isinstance(value, str):
        parts.append(json.dumps(value))
    elif isinstance(value, dict):
        parts.append("{")
        for i, (key, item) in enumerate(value.items()):
            parts.append(("," if i else "") + json.dumps(str(key)) + ":")
            _encode(item, parts)
        parts.append("}")
    elif isinstance(value, list | tuple):
        parts.append("[")
        for i, item in enumerate(value):
            if i:
                parts.append(",")
            _encode(item, parts)
        parts.append("]")
    else:
        raise TypeError(f"a glTF document holds no {type(value).__name__}")


# --- a mesh ---------------------------------------------------------------------------------


def mesh_document(mesh: object) -> tuple[dict[str, Any], bytes]:
    """A trimesh mesh as a glTF document (JSON) and its one buffer's bytes, through
    trimesh's glTF export."""
    # trimesh is imported on first use: it takes longer to import than meshbits.
    from trimesh.exchange.gltf import export_gltf

    files = export_gltf(mesh, merge_buffers=True)
    document = json.loads(files.pop("model.gltf"))
    buffers = document.get("buffers", [])
    binary = files.pop(buffers[0].pop("uri")) if buffers else b""
    return document, binary


def write_mesh(path: Path, mesh: object) -> Path:
    """Write a trimesh mesh as ``path``, a ``.glb``, or a ``.gltf`` with its buffer beside
    it (:func:`mesh_document`, :func:`write_document`); the buffer is written first."""
    write_document(*mesh_document(mesh), path)
    return path


# --- a scene around its compressed primitives ---------------------------------------------


class EncodedGeometry(Protocol):
    """What the writer reads of a compressed primitive
    (:class:`meshbits.codecs.primitive.PrimitiveEncoding` is one)."""

    #: ``name -> accessor fields`` (count, componentType, type...), and ``"indices"``.
    accessors: dict[str, dict[str, Any]]
    #: The ``KHR_draco_mesh_compression`` buffer (None with meshopt), and its attribute
    #: ids by glTF name.
    draco: bytes | None
    draco_ids: dict[str, int]
    #: meshopt: per stream ``name``, ``data`` (compressed), ``raw`` (the fallback's bytes),
    #: ``stride``, ``count``, ``mode`` and ``filter``.
    streams: list[dict[str, Any]]
    #: meshopt's integer positions: ``(origin, step)`` placing them in mesh units.
    dequantize: tuple[np.ndarray, float] | None
    #: Each morph target's accessor fields by attribute name (meshopt; its streams carry
    #: ``target``, the target's index).
    target_accessors: list[dict[str, dict[str, Any]]]


@dataclass(frozen=True)
class CompressedGeometry:
    """One compressed geometry to write, and every primitive that shows it.

    Attributes
    ----------
    targets : list of (mesh, primitive)
        The primitives that read it (they shared their accessors in the input).
    encoding : EncodedGeometry
        Its compressed data and accessors.
    offset : ndarray, shape (3,)
        What its positions were moved by before encoding (mesh units; zero when they were
        not): the nodes that show its meshes put it back.
    """

    targets: list[tuple[int, int]]
    encoding: EncodedGeometry
    offset: np.ndarray


@dataclass(frozen=True)
class EncodedAnimations:
    """Animation samplers' new data to write (:mod:`meshbits.scene.animation` makes it).

    Attributes
    ----------
    streams : list of dict
        One bufferView each: ``raw`` (the bytes a reader gets), ``data`` (meshopt's vertex
        codec bytes, or None for a plain bufferView), ``stride``, ``count`` and ``filter``.
    accessors : list of dict
        glTF accessors whose ``bufferView`` is an index into ``streams``.
    samplers : dict
        ``(animation, sampler) -> (input, output)``, indices into ``accessors``; every
        other sampler is copied as it was.
    """

    streams: list[dict[str, Any]]
    accessors: list[dict[str, Any]]
    samplers: dict[tuple[int, int], tuple[int, int]]

    @property
    def meshopt(self) -> bool:
        """Whether a stream is written with ``EXT_meshopt_compression``."""
        return any(stream["data"] is not None for stream in self.streams)


class _Blob:
    """A buffer being written: bytes appended at 4-byte alignment."""

    def __init__(self) -> None:
        self.parts: list[bytes] = []
        self.length = 0

    def add(self, data: bytes) -> int:
        """Append ``data`` (after padding to 4 bytes); returns its offset."""
        pad = (-self.length) % 4
        if pad:
            self.parts.append(b"\0" * pad)
            self.length += pad
        offset = self.length
        self.parts.append(bytes(data))
        self.length += len(data)
        return offset

    def bytes(self) -> bytes:
        """The buffer, padded to 4 bytes."""
        return b"".join(self.parts) + b"\0" * ((-self.length) % 4)


def image_key(document: Document, index: int) -> tuple[str, Any]:
    """What an image's data is: its bufferView or its URI (images sharing it share it)."""
    image = document.json["images"][index]
    if image.get("bufferView") is not None:
        return ("view", image["bufferView"])
    return ("uri", image.get("uri"))


def rebuild_document(
    document: Document,
    geometries: list[CompressedGeometry],
    codec: str,
    animations: EncodedAnimations | None = None,
) -> tuple[dict[str, Any], bytes]:
    """The document (JSON) and its binary buffer with the compressed ``geometries``
    (``codec``: ``"draco"`` or ``"meshopt"``): each one's data once, every primitive of its
    ``targets`` pointing at it, frames folded into the nodes; the samplers of
    ``animations`` pointed at their new data; every other primitive, and everything else,
    copied (images into the buffer)."""
    frames = _frames(geometries)
    extents = _extents(geometries)
    skins = skin_frames(document, frames)
    rebuilt = _Rebuilt(document, {t for geometry in geometries for t in geometry.targets})
    rebuilt.add_animations(animations)
    rebuilt.copy_kept_data(skins)
    for geometry in geometries:
        rebuilt.add_geometry(geometry, codec)
    rebuilt.add_streams()
    out = rebuilt.out
    if frames:
        _apply_frames(out, document, frames, extents)
    out["accessors"] = rebuilt.accessors
    out["bufferViews"] = rebuilt.views
    meshopt_animations = animations is not None and animations.meshopt
    _set_extensions(out, codec, bool(geometries), meshopt_animations)
    data = rebuilt.blob.bytes()
    buffers: list[dict[str, Any]] = [{"byteLength": len(data)}]
    if (codec == "meshopt" and geometries) or meshopt_animations:
        fallback = rebuilt.fallback.length
        buffers.append(
            {
                "byteLength": fallback + (-fallback) % 4,
                "extensions": {"EXT_meshopt_compression": {"fallback": True}},
            }
        )
    out["buffers"] = buffers
    out.setdefault("asset", {})["generator"] = "meshbits"
    return out, data


class _Rebuilt:
    """A document being rebuilt: its JSON (``out``), its new bufferViews and accessors,
    the buffer (``blob``) and meshopt's fallback buffer, and where each input bufferView
    and accessor went."""

    def __init__(self, document: Document, replaced: set[tuple[int, int]]) -> None:
        self.document, self.replaced = document, replaced
        self.out = copy.deepcopy(document.json)
        self.blob, self.fallback = _Blob(), _Blob()
        self.views: list[dict[str, Any]] = []
        self.accessors: list[dict[str, Any]] = []
        self.view_map: dict[int, int] = {}
        self.accessor_map: dict[int, int] = {}
        #: ``(animation, sampler) -> (input, output)`` accessors written anew.
        self.samplers: dict[tuple[int, int], tuple[int, int]] = {}
        #: ``(mode, stride, filter) -> [(stream, accessor)]``: the geometries' meshopt
        #: streams, written by :meth:`add_streams`.
        self.pending: dict[tuple[str, int, str], list[tuple[dict[str, Any], int]]] = {}

    def add_animations(self, animations: EncodedAnimations | None) -> None:
        """The new animation data: a bufferView per stream (meshopt's, without a target
        nor a byteStride as animation data takes, or plain), its accessors, and where
        each replaced sampler's input and output went."""
        if animations is None:
            return
        views = []
        for stream in animations.streams:
            if stream["data"] is None:
                raw = stream["raw"]
                self.views.append(
                    {"buffer": 0, "byteOffset": self.blob.add(raw), "byteLength": len(raw)}
                )
            else:
                view = self._meshopt_view({**stream, "mode": "ATTRIBUTES"})
                view.pop("target")
                view.pop("byteStride")
                self.views.append(view)
            views.append(len(self.views) - 1)
        first = len(self.accessors)
        for spec in animations.accessors:
            self.accessors.append({**spec, "bufferView": views[spec["bufferView"]]})
        self.samplers = {key: (first + i, first + o) for key, (i, o) in animations.samplers.items()}

    def copy_view(self, old: int) -> int:
        """The input's bufferView ``old``, its bytes copied into the buffer (once)."""
        if old not in self.view_map:
            spec = {
                k: v
                for k, v in self.document.json["bufferViews"][old].items()
                if k not in ("buffer", "byteOffset", "extensions")
            }
            spec["buffer"] = 0
            spec["byteOffset"] = self.blob.add(bytes(self.document.view_bytes(old)))
            self.views.append(spec)
            self.view_map[old] = len(self.views) - 1
        return self.view_map[old]

    def copy_accessor(self, old: int) -> int:
        """The input's accessor ``old``, with its bufferViews (sparse ones too), once."""
        if old not in self.accessor_map:
            spec = copy.deepcopy(self.document.json["accessors"][old])
            if spec.get("bufferView") is not None:
                spec["bufferView"] = self.copy_view(spec["bufferView"])
            if spec.get("sparse"):
                for part in ("indices", "values"):
                    spec["sparse"][part]["bufferView"] = self.copy_view(
                        spec["sparse"][part]["bufferView"]
                    )
            self.accessors.append(spec)
            self.accessor_map[old] = len(self.accessors) - 1
        return self.accessor_map[old]

    def copy_kept_data(self, skins: dict[int, Frame]) -> None:
        """Copy what is not replaced, with its data as it was: the primitives not
        compressed, skins' matrices (with the frame of the meshes they pose folded in, for
        the ``skins`` given), animations, instancing, and every image (images that share
        their data, one bufferView or one URI, keep sharing it)."""
        for m, mesh in enumerate(self.out.get("meshes", [])):
            for p, prim in enumerate(mesh.get("primitives", [])):
                if (m, p) not in self.replaced:
                    self._copy_primitive(prim, self.document.json["meshes"][m]["primitives"][p])
        for index, skin in enumerate(self.out.get("skins", [])):
            if index in skins:
                data, accessor = folded_matrix_bytes(self.document, index, skins[index])
                self.views.append(
                    {"buffer": 0, "byteOffset": self.blob.add(data), "byteLength": len(data)}
                )
                self.accessors.append({**accessor, "bufferView": len(self.views) - 1})
                skin["inverseBindMatrices"] = len(self.accessors) - 1
            elif skin.get("inverseBindMatrices") is not None:
                skin["inverseBindMatrices"] = self.copy_accessor(skin["inverseBindMatrices"])
        for a, animation in enumerate(self.out.get("animations", [])):
            for k, sampler in enumerate(animation.get("samplers", [])):
                if (a, k) in self.samplers:
                    sampler["input"], sampler["output"] = self.samplers[(a, k)]
                    continue
                sampler["input"] = self.copy_accessor(sampler["input"])
                sampler["output"] = self.copy_accessor(sampler["output"])
        for node in self.out.get("nodes", []):
            instancing = (node.get("extensions") or {}).get("EXT_mesh_gpu_instancing")
            if instancing:
                instancing["attributes"] = {
                    k: self.copy_accessor(v) for k, v in instancing.get("attributes", {}).items()
                }
        image_views: dict[Any, int] = {}
        for i, image in enumerate(self.out.get("images", [])):
            data, mime = self.document.image_bytes(i)
            key = image_key(self.document, i)
            if key not in image_views:
                self.views.append(
                    {"buffer": 0, "byteOffset": self.blob.add(data), "byteLength": len(data)}
                )
                image_views[key] = len(self.views) - 1
            image.pop("uri", None)
            image["bufferView"] = image_views[key]
            if mime:
                image["mimeType"] = mime

    def _copy_primitive(self, prim: dict[str, Any], source: dict[str, Any]) -> None:
        """A primitive kept as it was: its accessors (and morph targets, Draco data)."""
        prim["attributes"] = {
            k: self.copy_accessor(v) for k, v in source.get("attributes", {}).items()
        }
        if source.get("indices") is not None:
            prim["indices"] = self.copy_accessor(source["indices"])
        if source.get("targets"):
            prim["targets"] = [
                {k: self.copy_accessor(v) for k, v in t.items()} for t in source["targets"]
            ]
        draco = (source.get("extensions") or {}).get("KHR_draco_mesh_compression")
        if draco is not None:
            prim.setdefault("extensions", {})["KHR_draco_mesh_compression"] = {
                **draco,
                "bufferView": self.copy_view(draco["bufferView"]),
            }

    def add_geometry(self, geometry: CompressedGeometry, codec: str) -> None:
        """A compressed geometry's accessors and data (morph targets too), every primitive
        of its targets pointed at them."""
        encoding = geometry.encoding
        attributes = {}
        for name, spec in encoding.accessors.items():
            if name == "indices":
                continue
            self.accessors.append(dict(spec))
            attributes[name] = len(self.accessors) - 1
        self.accessors.append(dict(encoding.accessors["indices"]))
        indices = len(self.accessors) - 1
        targets: list[dict[str, int]] = []
        for target in encoding.target_accessors:
            targets.append({})
            for name, spec in target.items():
                self.accessors.append(dict(spec))
                targets[-1][name] = len(self.accessors) - 1
        draco = None
        if codec == "draco":
            assert encoding.draco is not None
            self.views.append(
                {
                    "buffer": 0,
                    "byteOffset": self.blob.add(encoding.draco),
                    "byteLength": len(encoding.draco),
                }
            )
            draco = {
                "bufferView": len(self.views) - 1,
                "attributes": {name: encoding.draco_ids[name] for name in attributes},
            }
        else:
            for stream in encoding.streams:
                if stream.get("target") is not None:
                    key = targets[stream["target"]][stream["name"]]
                elif stream["name"] == "indices":
                    key = indices
                else:
                    key = attributes[stream["name"]]
                group = (stream["mode"], stream["stride"], stream["filter"])
                self.pending.setdefault(group, []).append((stream, key))
        for mesh, number in geometry.targets:
            prim = self.out["meshes"][mesh]["primitives"][number]
            if prim.get("targets") and len(prim["targets"]) != len(targets):
                raise MeshbitsError(
                    f"mesh {mesh} primitive {number}: its {len(prim['targets'])} morph "
                    f"targets were not encoded"
                )
            _point_at(prim, attributes, indices, draco)
            if targets:
                prim["targets"] = [dict(target) for target in targets]

    def add_streams(self) -> None:
        """The geometries' meshopt streams as bufferViews: those of one mode, stride and
        filter in one view, as gltfpack lays them out, where that is fewer bytes (their
        raw bytes concatenated and encoded again as one stream, each accessor at its
        ``byteOffset`` in the decoded view: the decoded values are the same, and a view's
        JSON, about :data:`VIEW_JSON_BYTES`, is written once; BrainStem's 59 primitives
        took 299 views and 65 kB of JSON), else one view each."""
        for group in self.pending.values():
            streams = [stream for stream, _ in group]
            merged = _merged_stream(streams) if len(streams) > 1 else None
            separate = sum(len(stream["data"]) for stream in streams)
            if merged is None or len(merged["data"]) >= separate + VIEW_JSON_BYTES * (
                len(streams) - 1
            ):
                for stream, key in group:
                    self.views.append(self._meshopt_view(stream))
                    self.accessors[key]["bufferView"] = len(self.views) - 1
                continue
            self.views.append(self._meshopt_view(merged))
            offset = 0
            for stream, key in group:
                self.accessors[key]["bufferView"] = len(self.views) - 1
                if offset:
                    self.accessors[key]["byteOffset"] = offset
                offset += len(stream["raw"])
        self.pending.clear()

    def _meshopt_view(self, stream: dict[str, Any]) -> dict[str, Any]:
        """A meshopt stream's bufferView: its raw bytes in the fallback buffer, its
        compressed bytes in the buffer."""
        target = 34963 if stream["mode"] == "TRIANGLES" else 34962
        view = {
            "buffer": 1,
            "byteOffset": self.fallback.add(stream["raw"]),
            "byteLength": len(stream["raw"]),
            "target": target,
            "extensions": {
                "EXT_meshopt_compression": {
                    "buffer": 0,
                    "byteOffset": self.blob.add(stream["data"]),
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
        return view


#: About what one meshopt bufferView's JSON and its accessor's reference to it cost
#: (bytes): ``{"buffer":1,"byteOffset":…,"extensions":{"EXT_meshopt_compression":…}}``.
VIEW_JSON_BYTES = 180


def _merged_stream(streams: list[dict[str, Any]]) -> dict[str, Any]:
    """Streams of one mode, stride and filter as one: their raw bytes (the codec's input:
    rows of ``stride`` bytes, or triangles' indices) concatenated and encoded again."""
    first = streams[0]
    raw = b"".join(stream["raw"] for stream in streams)
    if first["mode"] == "TRIANGLES":
        dtype = np.uint16 if first["stride"] == 2 else np.uint32
        triangles = np.frombuffer(raw, dtype).astype(np.uint32).reshape(-1, 3)
        data = _core.meshopt_encode_triangles(triangles, int(triangles.max()) + 1)
    else:
        data = _core.meshopt_encode_vertices(np.frombuffer(raw, np.uint8), first["stride"])
    count = sum(int(stream["count"]) for stream in streams)
    return {**first, "name": None, "target": None, "raw": raw, "data": data, "count": count}


def _frames(geometries: list[CompressedGeometry]) -> dict[int, Frame]:
    """``mesh -> (origin, step)`` of every mesh whose positions are stored in a frame of
    their own: integer codes (meshopt), or positions moved to their centre."""
    frames: dict[int, Frame] = {}
    for geometry in geometries:
        encoding = geometry.encoding
        for mesh, _ in geometry.targets:
            if encoding.dequantize is not None:
                origin, step = encoding.dequantize
                frames[mesh] = (geometry.offset + origin, step)
            elif geometry.offset.any():
                frames[mesh] = (geometry.offset, 1.0)
    return frames


def _extents(geometries: list[CompressedGeometry]) -> dict[int, float]:
    """``mesh -> `` the largest side of its positions' box (mesh units), from the
    ``POSITION`` accessor's bounds (0 where it has none)."""
    extents: dict[int, float] = {}
    for geometry in geometries:
        encoding = geometry.encoding
        position = encoding.accessors.get("POSITION", {})
        step = 1.0 if encoding.dequantize is None else encoding.dequantize[1]
        extent = 0.0
        if "min" in position and "max" in position:
            sides = np.subtract(position["max"], position["min"], dtype=np.float64)
            extent = float(sides.max()) * step
        for mesh, _ in geometry.targets:
            extents[mesh] = max(extents.get(mesh, 0.0), extent)
    return extents


def _set_extensions(
    out: dict[str, Any], codec: str, compressed: bool, meshopt_animations: bool = False
) -> None:
    """The rebuilt document's extensions used and required: Draco's kept while a copied
    primitive still uses it, meshopt's input extensions dropped (its bufferViews were
    decoded on reading and are copied plain), the codec's own added when a geometry was
    compressed, and ``EXT_meshopt_compression`` when animation data was."""
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
    extensions_used.difference_update(MESHOPT_EXTENSIONS)
    extensions_required.difference_update(MESHOPT_EXTENSIONS)
    new = {"KHR_draco_mesh_compression"} if codec == "draco" else {"EXT_meshopt_compression"}
    if codec == "meshopt":
        new.add("KHR_mesh_quantization")
    if not compressed:
        new = set()
    if meshopt_animations:
        new.add("EXT_meshopt_compression")
    out["extensionsUsed"] = sorted(extensions_used | new)
    out["extensionsRequired"] = sorted(extensions_required | new)


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


def _apply_frames(
    out: dict[str, Any],
    document: Document,
    frames: dict[int, tuple[np.ndarray, float]],
    extents: dict[int, float],
) -> None:
    """A mesh whose positions are stored in a frame of their own (``mesh -> (origin,
    step)``: a reader places ``origin + step * stored``; integer codes with meshopt,
    positions relative to their centre with Draco) has it folded into the nodes that show
    it, or, for a node that carries more than the mesh (children, an animation, a skin, a
    camera, extensions), into a new child node that takes the mesh over.

    No translation is written that a float32 reader of node transforms would round by
    more than a position near the origin (:func:`float32_safe`): one that would is split
    into a float32-exact parent and a small child (:func:`split_translation`), and a
    node whose folded translation would be is left as it was, its frame in a child."""
    animated = document.animated_nodes()
    nodes = out.setdefault("nodes", [])
    for index in range(len(nodes)):
        node = nodes[index]
        mesh = node.get("mesh")
        if mesh is None or mesh not in frames:
            continue
        origin, step = frames[mesh]
        extent = extents.get(mesh, 0.0)
        alone = set(node) <= {
            "mesh",
            "name",
            "translation",
            "rotation",
            "scale",
            "matrix",
            "weights",
        }
        if alone and index not in animated and _fold(node, document, index, origin, step, extent):
            continue
        parent = index
        if not float32_safe(origin, extent):
            outer, origin = split_translation(origin, extent)
            nodes.append({"translation": [json_number(x) for x in outer]})
            node.setdefault("children", []).append(len(nodes) - 1)
            parent = len(nodes) - 1
        child: dict[str, Any] = {"mesh": mesh, "translation": [json_number(x) for x in origin]}
        if step != 1.0:
            child["scale"] = [step] * 3
        if "weights" in node:
            child["weights"] = node.pop("weights")
        node.pop("mesh")
        nodes.append(child)
        nodes[parent].setdefault("children", []).append(len(nodes) - 1)


def _fold(
    node: dict[str, Any],
    document: Document,
    index: int,
    origin: np.ndarray,
    step: float,
    extent: float,
) -> bool:
    """Fold the frame ``(origin, step)`` into ``node``'s own transform, unless the folded
    translation would not be :func:`float32_safe` (then the node is left as it was and
    False returned). The translation is in the node's parent's units, where the mesh's
    ``extent`` (mesh units) is scaled by the node's own scale (its largest singular
    value: a node scaled by 100 shows a 0.02 cube 2 units wide)."""
    local = document.node_matrix(index)
    d = np.eye(4)
    d[:3, :3] *= step
    d[:3, 3] = origin
    folded = local @ d
    scale = float(np.linalg.norm(local[:3, :3], 2))
    if not float32_safe(folded[:3, 3], extent * scale):
        return False
    if "matrix" in node:
        node["matrix"] = [float(x) for x in folded.T.reshape(-1)]
    else:
        node["translation"] = [json_number(x) for x in folded[:3, 3]]
        if step != 1.0:
            node["scale"] = [float(s) * step for s in node.get("scale", [1.0, 1.0, 1.0])]
    return True


#: Inputs that can hold more than positions and faces (materials, textures, UVs, normals,


# --- the one document writer: GLB, or .gltf with its buffer beside it ----------------------


def glb_bytes(document: dict[str, Any], binary: bytes) -> bytes:
    """A GLB container: the JSON chunk (space-padded) and the binary chunk."""
    text = json_text(document)
    text += b" " * ((-len(text)) % 4)
    binary += b"\0" * ((-len(binary)) % 4)
    total = 12 + 8 + len(text) + (8 + len(binary) if binary else 0)
    parts = [struct.pack("<4sII", b"glTF", 2, total), struct.pack("<I4s", len(text), b"JSON"), text]
    if binary:
        parts += [struct.pack("<I4s", len(binary), b"BIN\0"), binary]
    return b"".join(parts)


def document_size(document: dict[str, Any], binary: bytes, suffix: str) -> int:
    """Bytes of the file :func:`write_document` writes: a GLB, or a ``.gltf``'s JSON and
    buffer."""
    if suffix == ".gltf":
        buffers = document["buffers"]
        named = {**document, "buffers": [{**buffers[0], "uri": "x.bin"}, *buffers[1:]]}
        return len(json_text(named)) + len(binary)
    return len(glb_bytes(document, binary))


def write_document(
    document: dict[str, Any],
    binary: bytes,
    output: str | Path | None,
    verbatim: bytes | None = None,
) -> tuple[list[str], int]:
    """Write a glTF document (its JSON, and its first buffer's bytes ``binary``),
    atomically: as GLB, or for a ``.gltf`` as its JSON with the buffer beside it, named
    after it (``out.gltf`` and ``out.bin``, so that two outputs in one folder never share
    one); or ``verbatim``, an input's own bytes. With ``output`` None nothing is written.
    Returns the files written and the output's size in bytes."""
    if output is None:
        return [], len(verbatim) if verbatim is not None else len(glb_bytes(document, binary))
    path = Path(output)
    if verbatim is not None:
        write_atomic(path, verbatim)
        return [str(path)], len(verbatim)
    if path.suffix.lower() == ".glb":
        glb = glb_bytes(document, binary)
        write_atomic(path, glb)
        return [str(path)], len(glb)
    if not document.get("buffers"):  # a document without binary data: its JSON alone
        text = json_text(document)
        write_atomic(path, text)
        return [str(path)], len(text)
    bin_name = f"{path.stem}.bin"
    document["buffers"][0]["uri"] = bin_name
    text = json_text(document)
    write_atomic(path.with_name(bin_name), binary)
    write_atomic(path, text)
    return [str(path), str(path.with_name(bin_name))], len(text) + len(binary)
