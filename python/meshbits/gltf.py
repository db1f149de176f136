"""glTF 2.0 documents in and out: accessors read into numpy, the scene graph walked into
world-space instances, and a document rebuilt with some primitives replaced by compressed
ones and everything else copied as it was.

pygltflib holds the document (JSON as a dict); numpy reads accessors: any component type,
``byteStride``, normalized integers, sparse accessors, and primitives already compressed
with ``KHR_draco_mesh_compression`` (decoded with DracoPy). Buffer views compressed with
``EXT_meshopt_compression`` or ``KHR_meshopt_compression`` are decoded when the document
is read (meshoptimizer's decoders in the Rust core), so the rest of the reader sees plain
bytes; their accessors are mostly ``KHR_mesh_quantization`` integers, whose dequantization
is in the node transforms. OBJ (with MTL and textures), PLY (with colours) and the other
formats trimesh reads come in through trimesh's own glTF export, so UV seams stay split and
textures keep their bytes.
"""

from __future__ import annotations

import base64
import json
import math
import struct
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from . import _core
from .errors import MeshbitsError, MeshFileError

__all__ = [
    "COMPONENT_DTYPES",
    "MESHOPT_EXTENSIONS",
    "Document",
    "PrimitiveData",
    "image_size",
    "load_document",
    "load_gltf_document",
    "unread_required_extensions",
]

#: numpy dtype of each glTF component type.
COMPONENT_DTYPES = {
    5120: np.dtype(np.int8),
    5121: np.dtype(np.uint8),
    5122: np.dtype(np.int16),
    5123: np.dtype(np.uint16),
    5125: np.dtype(np.uint32),
    5126: np.dtype(np.float32),
}
COMPONENT_TYPES = {dtype: code for code, dtype in COMPONENT_DTYPES.items()}

#: Components of each accessor type.
TYPE_WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
WIDTH_TYPES = {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4"}

#: Primitive modes (glTF 2.0 `mesh.primitive.mode`).
TRIANGLES, TRIANGLE_STRIP, TRIANGLE_FAN = 4, 5, 6

GLB_MAGIC = b"glTF"

#: The bufferView compressions the reader decodes (meshoptimizer's codecs).
MESHOPT_EXTENSIONS = ("EXT_meshopt_compression", "KHR_meshopt_compression")

#: The primitive compression the reader decodes (with DracoPy).
DRACO = "KHR_draco_mesh_compression"

#: Extensions that change how geometry is stored, which the reader decodes, and one that
#: the scene writer carries over as it is (``EXT_mesh_gpu_instancing``).
READ_EXTENSIONS = frozenset(
    {DRACO, "KHR_mesh_quantization", "EXT_mesh_gpu_instancing"} | set(MESHOPT_EXTENSIONS)
)

#: Families of extensions that leave the geometry as glTF stores it (materials, textures,
#: images, lights, metadata): a reader of meshes may skip them, required or not.
GEOMETRY_NEUTRAL_PREFIXES = (
    "KHR_materials_",
    "KHR_texture_",
    "EXT_texture_",
    "MSFT_texture_",
    "KHR_lights_",
    "EXT_lights_",
    "KHR_xmp",
    "KHR_animation_pointer",
    "KHR_node_visibility",
)

#: Largest ``count`` or ``byteStride`` of a meshopt bufferView the reader takes.
_MESHOPT_LIMIT = 1 << 62


def unread_required_extensions(document: Any) -> list[str]:
    """The extensions a document requires (``extensionsRequired``) that change how its
    geometry is stored and that meshbits does not decode: a reader must refuse it."""
    required = document.get("extensionsRequired") if isinstance(document, dict) else None
    if not isinstance(required, list):
        return []
    names = [str(name) for name in required]
    return [
        name
        for name in names
        if name not in READ_EXTENSIONS and not name.startswith(GEOMETRY_NEUTRAL_PREFIXES)
    ]


def _normalized(values: np.ndarray) -> np.ndarray:
    """Normalized integers as the glTF spec maps them to floats."""
    kind = values.dtype
    if kind == np.uint8:
        return values / 255.0
    if kind == np.uint16:
        return values / 65535.0
    if kind == np.int8:
        return np.maximum(values / 127.0, -1.0)
    if kind == np.int16:
        return np.maximum(values / 32767.0, -1.0)
    return values.astype(np.float64)


@dataclass
class PrimitiveData:
    """A triangle primitive read from a document.

    Attributes
    ----------
    mesh, index : int
        Its mesh and its place among the mesh's primitives.
    positions : ndarray, shape (n, 3), float64
        ``POSITION`` (the mesh's local units).
    faces : ndarray, shape (m, 3), int64
        Triangles (strips and fans converted).
    attributes : dict
        Every other vertex attribute by its glTF name, as floats (normalized integers
        mapped to [0, 1] or [-1, 1]), or as integers for ``JOINTS_n``.
    source_types : dict
        ``name -> (componentType, normalized)`` of the input accessors.
    material : int or None
    morph : bool
        It has morph targets (kept as they are: not simplified nor quantized).
    """

    mesh: int
    index: int
    positions: np.ndarray = field(repr=False)
    faces: np.ndarray = field(repr=False)
    attributes: dict[str, np.ndarray] = field(repr=False)
    source_types: dict[str, tuple[int, bool]] = field(repr=False)
    material: int | None
    morph: bool

    @property
    def skinned(self) -> bool:
        return any(name.startswith("JOINTS_") for name in self.attributes)


class Document:
    """A glTF 2.0 document (``json``, a dict) with its buffers in memory.

    Parameters
    ----------
    data : dict
        The glTF JSON.
    buffers : list of bytes
        Each buffer's bytes.
    base : Path or None
        Folder of the file, for images referenced by relative URIs.
    """

    def __init__(self, data: dict[str, Any], buffers: list[bytes], base: Path | None) -> None:
        self.json = data
        self.buffers = buffers
        self.base = base
        #: What reading the file left out or changed, said in the reports (an OBJ's
        #: missing material library).
        self.notes: list[str] = []
        #: ``POSITION`` accessor -> its values as the input gave them (float64), for a
        #: document made from another format, whose accessors hold them rounded to float32
        #: (:func:`load_document`): what every measurement compares against.
        self.exact_positions: dict[int, np.ndarray] = {}
        asset = data.get("asset", {})
        if not str(asset.get("version", "")).startswith("2."):
            raise MeshFileError(f"not a glTF 2.0 document (asset.version {asset.get('version')!r})")
        #: The bytes of each bufferView compressed with meshopt, decoded.
        self.decoded_views: dict[int, bytes] = self._decode_meshopt_views()

    # --- raw data -----------------------------------------------------------------------

    def view_bytes(self, index: int) -> memoryview:
        """The bytes of a bufferView (decoded, for one compressed with meshopt)."""
        view = self._item("bufferViews", index)
        if index in self.decoded_views:
            return memoryview(self.decoded_views[index])
        buffer = view.get("buffer", 0)
        if not 0 <= buffer < len(self.buffers):
            raise MeshFileError(f"bufferView {index} refers to missing buffer {buffer}")
        start = int(view.get("byteOffset", 0))
        end = start + int(view["byteLength"])
        data = self.buffers[buffer]
        if end > len(data):
            raise MeshFileError(
                f"bufferView {index} ends at byte {end}, past its buffer's {len(data)}"
            )
        return memoryview(data)[start:end]

    def _decode_meshopt_views(self) -> dict[int, bytes]:
        """Every bufferView carrying ``EXT_meshopt_compression`` or
        ``KHR_meshopt_compression``, decoded to the plain bytes its layout declares."""
        out: dict[int, bytes] = {}
        views = self.json.get("bufferViews") or []
        for index, view in enumerate(views if isinstance(views, list) else []):
            extensions = view.get("extensions") if isinstance(view, dict) else None
            if not isinstance(extensions, dict):
                continue
            names = [name for name in MESHOPT_EXTENSIONS if name in extensions]
            if len(names) > 1:
                raise MeshFileError(
                    f"bufferView {index} carries both EXT_meshopt_compression and "
                    "KHR_meshopt_compression, which the extensions forbid"
                )
            if names:
                out[index] = self._decode_meshopt_view(index, view, names[0])
        return out

    def _decode_meshopt_view(self, index: int, view: dict[str, Any], name: str) -> bytes:
        """One bufferView's meshopt stream decoded (the extension's rules checked)."""
        where = f"bufferView {index} ({name})"
        spec = view["extensions"][name]
        if not isinstance(spec, dict):
            raise MeshFileError(f"{where}: the extension is not an object")
        fields = {}
        for key, default in (
            ("buffer", None),
            ("byteOffset", 0),
            ("byteLength", None),
            ("byteStride", None),
            ("count", None),
        ):
            value = spec.get(key, default)
            if value is None:
                raise MeshFileError(f"{where}: the extension has no {key}")
            if not isinstance(value, int) or isinstance(value, bool) or value < 0:
                raise MeshFileError(f"{where}: {key} is {value!r}, not a whole number >= 0")
            if value > _MESHOPT_LIMIT:
                raise MeshFileError(f"{where}: {key} {value:,} is beyond any file's size")
            fields[key] = value
        mode = spec.get("mode")
        filter_name = spec.get("filter", "NONE")
        if filter_name == "COLOR" and name == "EXT_meshopt_compression":
            raise MeshFileError(
                f"{where}: the COLOR filter belongs to KHR_meshopt_compression, not "
                "EXT_meshopt_compression"
            )
        if not isinstance(mode, str) or not isinstance(filter_name, str):
            raise MeshFileError(f"{where}: mode {mode!r} or filter {filter_name!r} is not a name")
        buffer, offset, length = fields["buffer"], fields["byteOffset"], fields["byteLength"]
        count, stride = fields["count"], fields["byteStride"]
        if buffer >= len(self.buffers):
            raise MeshFileError(f"{where}: the compressed data is in missing buffer {buffer}")
        data = self.buffers[buffer]
        if offset + length > len(data):
            raise MeshFileError(
                f"{where}: the compressed data ends at byte {offset + length:,}, past its "
                f"buffer's {len(data):,}"
                + (" (a fallback buffer, which holds none)" if not data else "")
            )
        declared = view.get("byteLength")
        if declared != count * stride:
            raise MeshFileError(
                f"{where}: {count:,} elements of {stride} bytes make {count * stride:,} bytes, "
                f"but the bufferView's byteLength is {declared!r}"
            )
        if view.get("byteStride") is not None and view["byteStride"] != stride:
            raise MeshFileError(
                f"{where}: byteStride {stride} differs from the bufferView's {view['byteStride']!r}"
            )
        try:
            return _core.meshopt_decode(
                bytes(memoryview(data)[offset : offset + length]), count, stride, mode, filter_name
            )
        except MeshbitsError as err:
            raise MeshFileError(f"{where}: {err}") from None

    def _item(self, kind: str, index: int) -> dict[str, Any]:
        items = self.json.get(kind, [])
        if not isinstance(index, int) or not 0 <= index < len(items):
            raise MeshFileError(f"{kind}[{index}] does not exist ({len(items)} {kind})")
        return items[index]

    def accessor(self, index: int, *, normalize: bool = True) -> np.ndarray:
        """An accessor's values, ``(count, components)``: floats for float and
        normalized accessors (when ``normalize``), else the stored integers."""
        acc = self._item("accessors", index)
        dtype = COMPONENT_DTYPES.get(acc.get("componentType"))
        width = TYPE_WIDTHS.get(acc.get("type"))
        if dtype is None or width is None:
            raise MeshFileError(
                f"accessor {index}: unknown componentType {acc.get('componentType')} or "
                f"type {acc.get('type')}"
            )
        count = int(acc.get("count", 0))
        if count < 0:
            raise MeshFileError(f"accessor {index}: negative count {count}")
        if "bufferView" in acc and acc["bufferView"] is not None:
            values = self._strided(
                acc["bufferView"], int(acc.get("byteOffset", 0)), dtype, width, count, index
            )
        else:
            values = np.zeros((count, width), dtype=dtype)
        sparse = acc.get("sparse")
        if sparse:
            values = values.copy()
            n = int(sparse["count"])
            idx_dtype = COMPONENT_DTYPES[sparse["indices"]["componentType"]]
            ids = np.frombuffer(
                self.view_bytes(sparse["indices"]["bufferView"]),
                dtype=idx_dtype,
                count=n,
                offset=int(sparse["indices"].get("byteOffset", 0)),
            ).astype(np.int64)
            replacement = np.frombuffer(
                self.view_bytes(sparse["values"]["bufferView"]),
                dtype=dtype,
                count=n * width,
                offset=int(sparse["values"].get("byteOffset", 0)),
            ).reshape(n, width)
            if n and (ids.min() < 0 or ids.max() >= count):
                raise MeshFileError(f"accessor {index}: sparse index out of range")
            values[ids] = replacement
        if normalize and (acc.get("normalized") or dtype == np.float32):
            return _normalized(values) if acc.get("normalized") else values.astype(np.float64)
        return values

    def _strided(
        self, view_index: int, offset: int, dtype: np.dtype, width: int, count: int, index: int
    ) -> np.ndarray:
        data = self.view_bytes(view_index)
        view = self._item("bufferViews", view_index)
        element = dtype.itemsize * width
        stride = int(view.get("byteStride") or element)
        needed = offset + (count - 1) * stride + element if count else 0
        if needed > len(data):
            raise MeshFileError(
                f"accessor {index} needs {needed} bytes of bufferView {view_index}, which "
                f"has {len(data)}"
            )
        if count == 0:
            return np.zeros((0, width), dtype=dtype)
        raw = np.frombuffer(data, dtype=np.uint8, count=needed - offset, offset=offset)
        rows = np.lib.stride_tricks.as_strided(
            raw, shape=(count, element), strides=(stride, 1), writeable=False
        )
        return np.ascontiguousarray(rows).view(dtype).reshape(count, width)

    def image_bytes(self, index: int) -> tuple[bytes, str | None]:
        """An image's bytes, exactly as stored, and its MIME type."""
        image = self._item("images", index)
        mime = image.get("mimeType")
        if image.get("bufferView") is not None:
            return bytes(self.view_bytes(image["bufferView"])), mime
        uri = image.get("uri")
        if uri is None:
            raise MeshFileError(f"image {index} has neither a bufferView nor a uri")
        if uri.startswith("data:"):
            header, _, payload = uri.partition(",")
            mime = mime or header[5:].split(";")[0] or None
            return base64.b64decode(payload), mime
        if self.base is None:
            raise MeshFileError(f"image {index} refers to {uri!r}, but the document has no folder")
        path = self.base / _unquote(uri)
        if not path.is_file():
            raise MeshFileError(f"image {index}: no such file {path}")
        return path.read_bytes(), mime or _mime_of(path.name)

    # --- meshes -------------------------------------------------------------------------

    def primitive(self, mesh: int, index: int) -> PrimitiveData | None:
        """A triangle primitive's data; None for points and lines."""
        prim = self._item("meshes", mesh).get("primitives", [])[index]
        mode = prim.get("mode", TRIANGLES)
        if mode not in (TRIANGLES, TRIANGLE_STRIP, TRIANGLE_FAN):
            return None
        draco = (prim.get("extensions") or {}).get(DRACO)
        if draco is not None:
            attributes, indices, types = self._draco(prim, draco)
        else:
            attributes, types = {}, {}
            for name, acc in prim.get("attributes", {}).items():
                joints = name.startswith("JOINTS_")
                if name == "POSITION" and acc in self.exact_positions:
                    values = self.exact_positions[acc]
                else:
                    values = self.accessor(acc, normalize=not joints)
                # KHR_mesh_quantization: integers that are not normalized are values as
                # they are (positions as grid codes, their scale in the node transforms).
                attributes[name] = values if joints else values.astype(np.float64, copy=False)
                spec = self._item("accessors", acc)
                types[name] = (int(spec["componentType"]), bool(spec.get("normalized", False)))
            if "POSITION" not in attributes:
                raise MeshFileError(f"meshes[{mesh}].primitives[{index}] has no POSITION")
            n = len(attributes["POSITION"])
            if prim.get("indices") is not None:
                indices = self.accessor(prim["indices"], normalize=False).reshape(-1)
            else:
                indices = np.arange(n)
        positions = attributes.pop("POSITION")
        faces = _triangles(indices.astype(np.int64), mode)
        if len(faces) and (faces.min() < 0 or faces.max() >= len(positions)):
            bad = int(np.flatnonzero(((faces < 0) | (faces >= len(positions))).any(axis=1))[0])
            raise MeshFileError(
                f"meshes[{mesh}].primitives[{index}]: face {bad} = {faces[bad].tolist()} "
                f"refers to a vertex out of range (there are {len(positions)} vertices)"
            )
        types.pop("POSITION", None)
        return PrimitiveData(
            mesh=mesh,
            index=index,
            positions=positions.astype(np.float64),
            faces=faces,
            attributes=attributes,
            source_types=types,
            material=prim.get("material"),
            morph=bool(prim.get("targets")),
        )

    def _draco(
        self, prim: dict[str, Any], draco: dict[str, Any]
    ) -> tuple[dict[str, np.ndarray], np.ndarray, dict[str, tuple[int, bool]]]:
        import DracoPy

        try:
            mesh = DracoPy.decode(bytes(self.view_bytes(draco["bufferView"])))
        except Exception as err:
            raise MeshFileError(f"cannot decode a Draco primitive: {err}") from err
        by_id = {a["unique_id"]: a for a in mesh.attributes}
        attributes, types = {}, {}
        for name, unique_id in draco.get("attributes", {}).items():
            if unique_id not in by_id:
                raise MeshFileError(f"Draco primitive has no attribute {unique_id} for {name}")
            data = np.asarray(by_id[unique_id]["data"])
            spec = self._item("accessors", prim["attributes"][name])
            normalized = bool(spec.get("normalized", False))
            if normalized and data.dtype.kind in "ui":
                dtype = COMPONENT_DTYPES[spec["componentType"]]
                data = _normalized(data.astype(dtype))
            attributes[name] = data if name.startswith("JOINTS_") else data.astype(np.float64)
            types[name] = (int(spec["componentType"]), normalized)
        indices = np.asarray(mesh.faces, dtype=np.int64).reshape(-1)
        return attributes, indices, types

    def triangle_primitives(self) -> list[PrimitiveData]:
        """Every triangle primitive of every mesh."""
        out = []
        for m, mesh in enumerate(self.json.get("meshes", [])):
            for p in range(len(mesh.get("primitives", []))):
                data = self.primitive(m, p)
                if data is not None:
                    out.append(data)
        return out

    # --- the scene graph ----------------------------------------------------------------

    def node_matrix(self, index: int) -> np.ndarray:
        """A node's local transform, 4x4."""
        node = self._item("nodes", index)
        if "matrix" in node:
            return np.asarray(node["matrix"], dtype=np.float64).reshape(4, 4).T
        return _trs_matrix(
            node.get("translation", [0, 0, 0]),
            node.get("rotation", [0, 0, 0, 1]),
            node.get("scale", [1, 1, 1]),
        )

    def mesh_instances(self) -> dict[int, list[tuple[int, np.ndarray]]]:
        """Each mesh's instances: ``(node, world matrix)`` over every scene's node trees
        (a mesh in no scene gets the identity)."""
        out: dict[int, list[tuple[int, np.ndarray]]] = {}
        nodes = self.json.get("nodes", [])
        roots = [n for scene in self.json.get("scenes", []) for n in scene.get("nodes", [])]
        if not roots:
            children = {c for node in nodes for c in node.get("children", [])}
            roots = [i for i in range(len(nodes)) if i not in children]
        stack = [(r, np.eye(4), 0) for r in roots]
        seen_depth = 0
        while stack:
            index, parent, depth = stack.pop()
            if depth > len(nodes):
                raise MeshFileError("the node hierarchy has a cycle")
            seen_depth = max(seen_depth, depth)
            world = parent @ self.node_matrix(index)
            node = self._item("nodes", index)
            if node.get("mesh") is not None:
                shown = out.setdefault(int(node["mesh"]), [])
                instancing = self.instance_matrices(index)
                if instancing is None:
                    shown.append((index, world))
                else:
                    shown.extend((index, world @ matrix) for matrix in instancing)
            stack.extend((c, world, depth + 1) for c in node.get("children", []))
        for m in range(len(self.json.get("meshes", []))):
            out.setdefault(m, [(-1, np.eye(4))])
        return out

    def instance_matrices(self, index: int) -> list[np.ndarray] | None:
        """The transforms ``EXT_mesh_gpu_instancing`` gives node ``index``'s mesh, each
        applied before the node's own (4x4); None for a node without the extension."""
        node = self._item("nodes", index)
        spec = (node.get("extensions") or {}).get("EXT_mesh_gpu_instancing")
        if not isinstance(spec, dict):
            return None
        attributes = spec.get("attributes") or {}
        columns = {
            name: self.accessor(attributes[name])
            for name in ("TRANSLATION", "ROTATION", "SCALE")
            if attributes.get(name) is not None
        }
        counts = {len(values) for values in columns.values()}
        if len(counts) > 1:
            raise MeshFileError(
                f"nodes[{index}]: EXT_mesh_gpu_instancing attributes of different counts "
                f"{sorted(counts)}"
            )
        out = []
        for i in range(counts.pop() if counts else 0):
            t = columns["TRANSLATION"][i] if "TRANSLATION" in columns else np.zeros(3)
            q = columns["ROTATION"][i] if "ROTATION" in columns else (0.0, 0.0, 0.0, 1.0)
            scale = columns["SCALE"][i] if "SCALE" in columns else np.ones(3)
            out.append(_trs_matrix(t, q, scale))
        return out

    def instanced_meshes(self) -> set[int]:
        """Meshes some node shows through ``EXT_mesh_gpu_instancing``."""
        return {
            int(node["mesh"])
            for node in self.json.get("nodes", [])
            if node.get("mesh") is not None
            and "EXT_mesh_gpu_instancing" in (node.get("extensions") or {})
        }

    def world_triangles(self) -> tuple[np.ndarray, np.ndarray]:
        """Every triangle primitive at each of its instances (:meth:`mesh_instances`), in
        world coordinates, as one mesh: ``(vertices float64 (n, 3), faces int64 (m, 3))``,
        what trimesh makes of a scene with its node transforms applied."""
        instances = self.mesh_instances()
        vertices, faces, offset = [], [], 0
        for data in self.triangle_primitives():
            for _, matrix in instances.get(data.mesh, [(-1, np.eye(4))]):
                vertices.append(data.positions @ matrix[:3, :3].T + matrix[:3, 3])
                faces.append(data.faces + offset)
                offset += len(data.positions)
        if not faces or not sum(len(f) for f in faces):
            raise MeshFileError("the document holds no triangles")
        return np.concatenate(vertices), np.concatenate(faces)

    def animated_nodes(self) -> set[int]:
        """Nodes whose translation, rotation or scale an animation drives."""
        return {
            channel["target"]["node"]
            for animation in self.json.get("animations", [])
            for channel in animation.get("channels", [])
            if channel.get("target", {}).get("node") is not None
            and channel["target"].get("path") in ("translation", "rotation", "scale")
        }


def _trs_matrix(translation: Any, rotation: Any, scale: Any) -> np.ndarray:
    """``T * R * S`` (4x4) from a translation, a unit quaternion ``(x, y, z, w)`` and a
    scale, as glTF composes a node's."""
    x, y, z, w = (float(c) for c in rotation)
    r = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
    out = np.eye(4)
    out[:3, :3] = r * np.asarray(scale, dtype=np.float64)
    out[:3, 3] = np.asarray(translation, dtype=np.float64)
    return out


def largest_scale(matrix: np.ndarray) -> float:
    """The largest singular value of a transform's linear part: how much it can stretch a
    length."""
    return float(np.linalg.svd(matrix[:3, :3], compute_uv=False).max())


def _triangles(indices: np.ndarray, mode: int) -> np.ndarray:
    if mode == TRIANGLES:
        if len(indices) % 3:
            raise MeshFileError(f"a triangle list has {len(indices)} indices, not a multiple of 3")
        return indices.reshape(-1, 3)
    if len(indices) < 3:
        return np.zeros((0, 3), dtype=np.int64)
    if mode == TRIANGLE_STRIP:
        i = np.arange(len(indices) - 2)
        tri = np.stack([indices[i], indices[i + 1], indices[i + 2]], axis=1)
        odd = i % 2 == 1
        tri[odd] = tri[odd][:, [1, 0, 2]]
        return tri
    i = np.arange(1, len(indices) - 1)
    return np.stack([np.full(len(i), indices[0]), indices[i], indices[i + 1]], axis=1)


def _unquote(uri: str) -> str:
    from urllib.parse import unquote

    return unquote(uri)


def _mime_of(name: str) -> str | None:
    suffix = name.rsplit(".", 1)[-1].lower()
    return {
        "png": "image/png",
        "jpg": "image/jpeg",
        "jpeg": "image/jpeg",
        "webp": "image/webp",
        "ktx2": "image/ktx2",
    }.get(suffix)


def image_size(data: bytes) -> tuple[int, int] | None:
    """``(width, height)`` of a PNG, JPEG or WebP image from its header; None if unknown."""
    if data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) >= 24:
        width, height = struct.unpack(">II", data[16:24])
        return int(width), int(height)
    if data[:2] == b"\xff\xd8":
        i = 2
        while i + 9 < len(data):
            if data[i] != 0xFF:
                return None
            marker = data[i + 1]
            length = struct.unpack(">H", data[i + 2 : i + 4])[0]
            if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
                height, width = struct.unpack(">HH", data[i + 5 : i + 9])
                return int(width), int(height)
            i += 2 + length
        return None
    if data[:4] == b"RIFF" and data[8:12] == b"WEBP" and len(data) >= 30:
        chunk = data[12:16]
        if chunk == b"VP8 ":
            width, height = struct.unpack("<HH", data[26:30])
            return int(width & 0x3FFF), int(height & 0x3FFF)
        if chunk == b"VP8L":
            b = data[21:25]
            width = 1 + (((b[1] & 0x3F) << 8) | b[0])
            height = 1 + (((b[3] & 0xF) << 10) | (b[2] << 2) | ((b[1] & 0xC0) >> 6))
            return int(width), int(height)
        if chunk == b"VP8X":
            width = 1 + int.from_bytes(data[24:27], "little")
            height = 1 + int.from_bytes(data[27:30], "little")
            return width, height
    return None


def load_document(path: str | Path) -> Document:
    """Read a scene file into a glTF document.

    ``.glb`` and ``.gltf`` (with its buffers and images) are read as they are; OBJ (with
    its MTL and textures), PLY (with colours), STL, OFF and the rest of what trimesh
    reads, gzip-compressed too, go through trimesh's glTF export.

    Raises
    ------
    FileNotFoundError
        ``path`` does not exist.
    MeshFileError
        The file cannot be read as a scene.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no such file: {path}")
    suffix = path.suffix.lower()
    try:
        if suffix not in (".glb", ".gltf"):
            return _from_trimesh(path)  # its messages name the file
        try:
            if suffix == ".glb":
                return _from_glb(path.read_bytes(), path.parent)
            return _from_gltf(json.loads(path.read_text(encoding="utf-8")), path.parent)
        except MeshFileError as err:
            raise MeshFileError(f"cannot read {path}: {err}") from None
    except (MeshbitsError, FileNotFoundError):
        raise
    except Exception as err:
        from ._filecheck import explain

        suffixes = [x.lower() for x in path.suffixes]
        kind = suffixes[-2] if suffix == ".gz" and len(suffixes) > 1 else suffix
        raise MeshFileError(f"cannot read {path}: {explain(kind.lstrip('.'), err)}") from err


def load_gltf_document(
    path: str | Path, file_type: str, data: bytes | None = None
) -> Document | None:
    """The document of a ``.glb`` or ``.gltf`` file (``file_type`` ``"glb"`` or
    ``"gltf"``; its bytes ``data``, or read from ``path``), for :func:`meshbits.load_mesh`
    to take its triangles from (:meth:`Document.world_triangles`): one glTF reader for
    every command. trimesh does not decode meshopt, read a Draco primitive it could not
    decode as zeros with only a log message (a GLB with one byte of its Draco data changed
    gave ``k`` a mesh at the origin), and refused a valid document whose root node holds a
    skin and a camera ("No path from world->1!"). None for another file type. Raises
    :class:`MeshFileError` naming ``path`` when the document is refused; a file whose
    JSON does not parse raises the parser's error, for the caller to explain."""
    path = Path(path)
    if file_type not in ("glb", "gltf"):
        return None
    if data is None:
        return load_document(path)
    try:
        if file_type == "glb":
            return _from_glb(data, path.parent)
        return _from_gltf(json.loads(data.decode("utf-8")), path.parent)
    except MeshFileError as err:
        raise MeshFileError(f"cannot read {path}: {err}") from None


#: Top-level glTF collections (arrays of objects) that other objects refer to by index.
COLLECTIONS = (
    "accessors",
    "animations",
    "bufferViews",
    "buffers",
    "cameras",
    "images",
    "materials",
    "meshes",
    "nodes",
    "samplers",
    "scenes",
    "skins",
    "textures",
)


def check_references(document: Any) -> None:
    """Refuse a glTF document whose structure a reader would trip on: not a JSON object,
    a top-level collection that is not an array of objects, or an index (glTF 2.0 Sec.
    3.7.2 and 5: a scene's nodes, a node's mesh, children, skin and camera, a
    primitive's attributes, indices, material and morph targets, an accessor's and an
    image's bufferView, a sparse accessor's views, a bufferView's buffer, a texture's
    source and sampler and its extensions' sources, a material's textures, a skin's
    joints, skeleton and matrices, an animation's samplers, targets and accessors, the
    Draco and meshopt extensions' views and buffers) that is not an integer naming an
    existing item. Raises :class:`MeshFileError` naming the reference, e.g.
    ``meshes[0].primitives[0].material is 3, past the end of materials (0)``."""
    if not isinstance(document, dict):
        raise MeshFileError("the glTF JSON is not an object")
    sizes: dict[str, int] = {}
    for kind in COLLECTIONS:
        items = document.get(kind, [])
        if not isinstance(items, list) or not all(isinstance(i, dict) for i in items):
            raise MeshFileError(f"{kind} is not an array of objects")
        sizes[kind] = len(items)

    def ref(value: Any, kind: str, where: str, required: bool = False) -> None:
        if value is None:
            if required:
                raise MeshFileError(f"{where} is missing: it must name one of the {kind}")
            return
        if isinstance(value, bool) or not isinstance(value, int):
            raise MeshFileError(f"{where} is {value!r}, not an index into {kind}")
        if not 0 <= value < sizes[kind]:
            raise MeshFileError(f"{where} is {value}, past the end of {kind} ({sizes[kind]})")

    def need(container: dict[str, Any], key: str, kind: str, where: str) -> None:
        ref(container.get(key), kind, f"{where}.{key}", True)

    def obj(value: Any, where: str) -> dict[str, Any]:
        if value is None:
            return {}
        if not isinstance(value, dict):
            raise MeshFileError(f"{where} is not an object")
        return value

    def array(value: Any, where: str) -> list[Any]:
        if value is None:
            return []
        if not isinstance(value, list):
            raise MeshFileError(f"{where} is not an array")
        return value

    ref(document.get("scene"), "scenes", "scene")
    for i, scene in enumerate(document.get("scenes", [])):
        for k, node in enumerate(array(scene.get("nodes"), f"scenes[{i}].nodes")):
            ref(node, "nodes", f"scenes[{i}].nodes[{k}]", True)
    for i, node in enumerate(document.get("nodes", [])):
        where = f"nodes[{i}]"
        for key, kind in (("mesh", "meshes"), ("skin", "skins"), ("camera", "cameras")):
            ref(node.get(key), kind, f"{where}.{key}")
        for k, child in enumerate(array(node.get("children"), f"{where}.children")):
            ref(child, "nodes", f"{where}.children[{k}]", True)
    for m, mesh in enumerate(document.get("meshes", [])):
        for p, prim in enumerate(array(mesh.get("primitives"), f"meshes[{m}].primitives")):
            where = f"meshes[{m}].primitives[{p}]"
            prim = obj(prim, where)
            for name, index in obj(prim.get("attributes"), f"{where}.attributes").items():
                ref(index, "accessors", f"{where}.attributes.{name}", True)
            ref(prim.get("indices"), "accessors", f"{where}.indices")
            ref(prim.get("material"), "materials", f"{where}.material")
            for t, target in enumerate(array(prim.get("targets"), f"{where}.targets")):
                for name, index in obj(target, f"{where}.targets[{t}]").items():
                    ref(index, "accessors", f"{where}.targets[{t}].{name}", True)
            extensions = obj(prim.get("extensions"), f"{where}.extensions")
            draco = obj(extensions.get(DRACO), f"{where}.extensions.{DRACO}")
            if DRACO in extensions:
                need(draco, "bufferView", "bufferViews", f"{where}.extensions.{DRACO}")
    for i, accessor in enumerate(document.get("accessors", [])):
        count = accessor.get("count")
        if isinstance(count, bool) or not isinstance(count, int) or count < 0:
            raise MeshFileError(f"accessors[{i}].count is {count!r}, not a count")
        if accessor.get("componentType") not in COMPONENT_DTYPES:
            raise MeshFileError(
                f"accessors[{i}].componentType is {accessor.get('componentType')!r}, not a "
                f"glTF component type"
            )
        if accessor.get("type") not in TYPE_WIDTHS:
            raise MeshFileError(f"accessors[{i}].type is {accessor.get('type')!r}, not a glTF type")
        ref(accessor.get("bufferView"), "bufferViews", f"accessors[{i}].bufferView")
        sparse = obj(accessor.get("sparse"), f"accessors[{i}].sparse")
        for part in ("indices", "values") if sparse else ():
            inner = obj(sparse.get(part), f"accessors[{i}].sparse.{part}")
            need(inner, "bufferView", "bufferViews", f"accessors[{i}].sparse.{part}")
    for i, view in enumerate(document.get("bufferViews", [])):
        ref(view.get("buffer"), "buffers", f"bufferViews[{i}].buffer", True)
        extensions = obj(view.get("extensions"), f"bufferViews[{i}].extensions")
        for name in MESHOPT_EXTENSIONS:
            inner = obj(extensions.get(name), f"bufferViews[{i}].extensions.{name}")
            if name in extensions:
                need(inner, "buffer", "buffers", f"bufferViews[{i}].extensions.{name}")
    for i, image in enumerate(document.get("images", [])):
        ref(image.get("bufferView"), "bufferViews", f"images[{i}].bufferView")
    for i, texture in enumerate(document.get("textures", [])):
        ref(texture.get("source"), "images", f"textures[{i}].source")
        ref(texture.get("sampler"), "samplers", f"textures[{i}].sampler")
        extensions = obj(texture.get("extensions"), f"textures[{i}].extensions")
        for name, inner in extensions.items():
            if isinstance(inner, dict):
                ref(inner.get("source"), "images", f"textures[{i}].extensions.{name}.source")

    def texture_infos(value: Any, where: str) -> None:
        if isinstance(value, dict):
            for key, inner in value.items():
                here = f"{where}.{key}"
                if key.endswith(("Texture", "texture")) and isinstance(inner, dict):
                    ref(inner.get("index"), "textures", f"{here}.index", True)
                texture_infos(inner, here)
        elif isinstance(value, list):
            for k, inner in enumerate(value):
                texture_infos(inner, f"{where}[{k}]")

    for i, material in enumerate(document.get("materials", [])):
        texture_infos(material, f"materials[{i}]")
    for i, skin in enumerate(document.get("skins", [])):
        for k, joint in enumerate(array(skin.get("joints"), f"skins[{i}].joints")):
            ref(joint, "nodes", f"skins[{i}].joints[{k}]", True)
        ref(skin.get("skeleton"), "nodes", f"skins[{i}].skeleton")
        ref(skin.get("inverseBindMatrices"), "accessors", f"skins[{i}].inverseBindMatrices")
    for a, animation in enumerate(document.get("animations", [])):
        samplers = array(animation.get("samplers"), f"animations[{a}].samplers")
        for k, sampler in enumerate(samplers):
            sampler = obj(sampler, f"animations[{a}].samplers[{k}]")
            for key in ("input", "output"):
                ref(sampler.get(key), "accessors", f"animations[{a}].samplers[{k}].{key}", True)
        for k, channel in enumerate(array(animation.get("channels"), f"animations[{a}].channels")):
            where = f"animations[{a}].channels[{k}]"
            channel = obj(channel, where)
            index = channel.get("sampler")
            if (
                isinstance(index, bool)
                or not isinstance(index, int)
                or not 0 <= index < len(samplers)
            ):
                raise MeshFileError(
                    f"{where}.sampler is {index!r}, but the animation has {len(samplers)} samplers"
                )
            ref(
                obj(channel.get("target"), f"{where}.target").get("node"),
                "nodes",
                f"{where}.target.node",
            )
    _check_values(document)


#: Accessor types each standard attribute allows (glTF 2.0 Sec. 3.7.2.1).
ATTRIBUTE_TYPES = {
    "POSITION": ("VEC3",),
    "NORMAL": ("VEC3",),
    "TANGENT": ("VEC4",),
    "TEXCOORD": ("VEC2",),
    "COLOR": ("VEC3", "VEC4"),
    "JOINTS": ("VEC4",),
    "WEIGHTS": ("VEC4",),
}

#: Animation channel paths (glTF 2.0, and KHR_animation_pointer's ``pointer``).
ANIMATION_PATHS = ("translation", "rotation", "scale", "weights", "pointer")


def _check_values(document: dict[str, Any]) -> None:
    """The values :func:`check_references` does not cover and the readers rely on, once
    every index is known to be valid: counts, offsets, lengths and strides that are
    non-negative integers and fit their buffer view and buffer, accessor types that fit
    their attribute, node transforms of the right number of finite numbers, a node
    hierarchy of disjoint trees, primitive modes and animation paths of the
    specification."""

    def integer(
        container: dict[str, Any], key: str, where: str, least: int, *, required: bool = False
    ) -> int | None:
        if key not in container and not required:
            return None
        value = container.get(key)
        if isinstance(value, bool) or not isinstance(value, int) or value < least:
            raise MeshFileError(f"{where}.{key} is {value!r}, not an integer >= {least}")
        return value

    def numbers(container: dict[str, Any], key: str, count: int | None, where: str) -> None:
        if key not in container:
            return
        value = container[key]
        if count is None:
            count = len(value) if isinstance(value, list) else -1
        if (
            not isinstance(value, list)
            or len(value) != count
            or not all(
                isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
                for x in value
            )
        ):
            size = "a list of" if count < 0 else str(count)
            raise MeshFileError(f"{where}.{key} is not {size} finite numbers")

    buffers = document.get("buffers", [])
    views = document.get("bufferViews", [])
    accessors = document.get("accessors", [])
    for i, buffer in enumerate(buffers):
        integer(buffer, "byteLength", f"buffers[{i}]", 1, required=True)
    for i, view in enumerate(views):
        where = f"bufferViews[{i}]"
        offset = integer(view, "byteOffset", f"{where}", 0) or 0
        length = integer(view, "byteLength", f"{where}", 1, required=True)
        stride = integer(view, "byteStride", f"{where}", 4)
        if stride is not None and (stride > 252 or stride % 4):
            raise MeshFileError(f"{where}.byteStride is {stride}: not a multiple of 4 up to 252")
        available = buffers[view["buffer"]]["byteLength"]
        if offset + length > available:
            raise MeshFileError(
                f"{where} ends at byte {offset + length:,}, past its buffer's byteLength "
                f"({available:,})"
            )
    for i, accessor in enumerate(accessors):
        where = f"accessors[{i}]"
        offset = integer(accessor, "byteOffset", f"{where}", 0) or 0
        if "normalized" in accessor and not isinstance(accessor["normalized"], bool):
            raise MeshFileError(f"{where}.normalized is {accessor['normalized']!r}, not a boolean")
        count = accessor["count"]
        element = (
            COMPONENT_DTYPES[accessor["componentType"]].itemsize * TYPE_WIDTHS[accessor["type"]]
        )
        if accessor.get("bufferView") is not None and count > 0:
            view = views[accessor["bufferView"]]
            stride = view.get("byteStride") or element
            if stride < element:
                raise MeshFileError(
                    f"{where}: elements of {element} bytes in bufferViews"
                    f"[{accessor['bufferView']}] whose byteStride is {stride}"
                )
            end = offset + stride * (count - 1) + element
            if end > view["byteLength"]:
                raise MeshFileError(
                    f"{where} ends at byte {end:,} of bufferViews[{accessor['bufferView']}], "
                    f"past its byteLength ({view['byteLength']:,})"
                )
        sparse = accessor.get("sparse")
        if sparse:
            stored = integer(sparse, "count", f"{where}.sparse", 1, required=True)
            if stored > count:
                raise MeshFileError(f"{where}.sparse.count is {stored}, over the count {count}")
            kind = sparse["indices"].get("componentType")
            if kind not in (5121, 5123, 5125):
                raise MeshFileError(
                    f"{where}.sparse.indices.componentType is {kind!r}, not an unsigned "
                    "integer type"
                )
            sizes = {"indices": COMPONENT_DTYPES[kind].itemsize, "values": element}
            for part in ("indices", "values"):
                start = integer(sparse[part], "byteOffset", f"{where}.sparse.{part}", 0)
                view = views[sparse[part]["bufferView"]]
                end = (start or 0) + stored * sizes[part]
                if end > view["byteLength"]:
                    raise MeshFileError(
                        f"{where}.sparse.{part} ends at byte {end:,} of bufferViews"
                        f"[{sparse[part]['bufferView']}], past its byteLength "
                        f"({view['byteLength']:,})"
                    )

    def accessor_type(index: int, allowed: tuple[str, ...], where: str) -> None:
        kind = accessors[index]["type"]
        if kind not in allowed:
            raise MeshFileError(f"{where} is a {kind} accessor, not {' or '.join(allowed)}")

    for m, mesh in enumerate(document.get("meshes", [])):
        numbers(mesh, "weights", None, f"meshes[{m}]")
        primitives = mesh.get("primitives")
        if not isinstance(primitives, list) or not primitives:
            raise MeshFileError(f"meshes[{m}].primitives is not a non-empty array")
        for p, prim in enumerate(primitives):
            where = f"meshes[{m}].primitives[{p}]"
            mode = integer(prim, "mode", f"{where}", 0)
            if mode is not None and mode > 6:
                raise MeshFileError(f"{where}.mode is {mode}, not a glTF primitive mode (0-6)")
            if DRACO in (prim.get("extensions") or {}):
                continue  # Draco's attributes are described by its own stream
            for name, index in prim.get("attributes", {}).items():
                allowed = ATTRIBUTE_TYPES.get(name.split("_")[0] if "_" in name else name)
                if allowed is not None and not name.startswith("_"):
                    accessor_type(index, allowed, f"{where}.attributes.{name}")
            if prim.get("indices") is not None:
                accessor_type(prim["indices"], ("SCALAR",), f"{where}.indices")
                kind = accessors[prim["indices"]]["componentType"]
                if kind not in (5121, 5123, 5125):
                    raise MeshFileError(
                        f"{where}.indices has componentType {kind}, not an unsigned integer type"
                    )
            for t, target in enumerate(prim.get("targets") or []):
                for name, index in target.items():
                    if name in ("POSITION", "NORMAL", "TANGENT"):
                        accessor_type(index, ("VEC3",), f"{where}.targets[{t}].{name}")
    nodes = document.get("nodes", [])
    parent: dict[int, int] = {}
    for i, node in enumerate(nodes):
        where = f"nodes[{i}]"
        for key, count in (("matrix", 16), ("translation", 3), ("rotation", 4), ("scale", 3)):
            numbers(node, key, count, where)
        numbers(node, "weights", None, where)
        for child in node.get("children") or []:
            if child == i or child in parent:
                raise MeshFileError(
                    f"{where}.children holds node {child}, "
                    + ("itself" if child == i else f"already a child of node {parent[child]}")
                    + ": the nodes must form trees"
                )
            parent[child] = i
    # Each node has at most one parent: walk up from each node until a root or a node
    # already known to reach one, so every node is walked once.
    rooted: set[int] = set()
    for start in range(len(nodes)):
        path, node = {start}, start
        while node in parent and node not in rooted:
            node = parent[node]
            if node in path:
                raise MeshFileError(
                    f"nodes[{start}] is its own ancestor: the nodes must form trees"
                )
            path.add(node)
        rooted.update(path)
    for a, animation in enumerate(document.get("animations", [])):
        for k, channel in enumerate(animation.get("channels") or []):
            path = (channel.get("target") or {}).get("path")
            if path not in ANIMATION_PATHS:
                raise MeshFileError(
                    f"animations[{a}].channels[{k}].target.path is {path!r}, not one of "
                    f"{', '.join(ANIMATION_PATHS)}"
                )


def _from_glb(data: bytes, base: Path | None) -> Document:
    if not data:
        raise MeshFileError("the file is empty")
    if data[:4] != GLB_MAGIC or len(data) < 20:
        raise MeshFileError(
            "the file does not start with a GLB header ('glTF' and 16 more bytes): "
            "not a binary glTF"
        )
    version, length = struct.unpack("<II", data[4:12])
    if version != 2:
        raise MeshFileError(f"GLB version {version}: only version 2 is read")
    if length > len(data):
        raise MeshFileError(
            f"the GLB header declares {length:,} bytes but the file has {len(data):,}: "
            "truncated or damaged"
        )
    offset, document, binary = 12, None, b""
    while offset + 8 <= length:
        chunk_length, kind = struct.unpack("<II", data[offset : offset + 8])
        chunk = data[offset + 8 : offset + 8 + chunk_length]
        if len(chunk) < chunk_length:
            raise MeshFileError("a GLB chunk runs past the end of the file")
        if kind == 0x4E4F534A:
            document = json.loads(chunk.decode("utf-8"))
        elif kind == 0x004E4942 and not binary:
            binary = bytes(chunk)
        offset += 8 + chunk_length
    if document is None:
        raise MeshFileError("the GLB file has no JSON chunk")
    return _from_gltf(document, base, binary)


def _from_gltf(document: dict[str, Any], base: Path | None, binary: bytes = b"") -> Document:
    check_references(document)
    buffers = []
    for i, buffer in enumerate(document.get("buffers", [])):
        uri = buffer.get("uri")
        extensions = buffer.get("extensions") or {}
        fallback = any(
            isinstance(extensions.get(name), dict) and extensions[name].get("fallback")
            for name in MESHOPT_EXTENSIONS
        )
        if fallback or (uri is None and i != 0):
            # A fallback buffer of meshopt compression: its bufferViews are decoded from
            # their compressed data (one without a uri has no data at all).
            buffers.append(b"")
            continue
        if uri is None:
            data = binary
        elif uri.startswith("data:"):
            data = base64.b64decode(uri.partition(",")[2])
        else:
            if base is None:
                raise MeshFileError(f"buffer {i} refers to {uri!r}, but the document has no folder")
            file = base / _unquote(uri)
            if not file.is_file():
                raise MeshFileError(f"buffer {i}: no such file {file}")
            data = file.read_bytes()
        if len(data) < int(buffer.get("byteLength", 0)):
            raise MeshFileError(
                f"buffer {i} should hold {buffer.get('byteLength')} bytes, has {len(data)}"
            )
        buffers.append(data)
    return Document(document, buffers, base)


def _from_trimesh(path: Path) -> Document:
    """A file of another format as a glTF document, through trimesh's glTF export. The
    export stores positions as float32; the document keeps the file's own (float64) in
    :attr:`Document.exact_positions`. A mesh far from the origin (its box's centre farther
    than its largest side) is exported relative to that centre, which a root node carries
    as its translation (float64 in the JSON), so that float32 keeps its precision."""
    import trimesh

    from .io import checked_mesh_file, parse_mesh_file

    source, file_type, compressed = checked_mesh_file(path)
    loaded = parse_mesh_file(path, source, file_type, compressed)
    scene = loaded if isinstance(loaded, trimesh.Scene) else trimesh.Scene(loaded)
    meshes = {
        name: g
        for name, g in scene.geometry.items()
        if isinstance(g, trimesh.Trimesh) and len(g.faces)
    }
    if not meshes:
        raise MeshFileError(f"{path} holds no triangle mesh")
    placed = all(
        np.array_equal(scene.graph[node][0], np.eye(4)) for node in scene.graph.nodes_geometry
    )
    exact = {name: np.asarray(g.vertices, dtype=np.float64) for name, g in meshes.items()}
    centre = np.zeros(3)
    if placed:
        centre = frame_centre(np.concatenate(list(exact.values())))
    if centre.any():
        for name, g in meshes.items():
            g.vertices = exact[name] - centre
    document = _from_glb(scene.export(file_type="glb"), path.parent)
    for mesh in document.json.get("meshes", []):
        local = exact.get(mesh.get("name"))
        for prim in mesh.get("primitives", []):
            index = prim.get("attributes", {}).get("POSITION")
            if local is None or index is None:
                continue
            values = local - centre
            stored = document.accessor(index)
            if stored.shape == values.shape and np.array_equal(
                stored.astype(np.float32), values.astype(np.float32)
            ):
                document.exact_positions[index] = values
    missing = _missing_material_libraries(path) if file_type == "obj" else []
    if missing:
        _drop_materials(document.json)
        document.notes.append(
            f"material librar{'ies' if len(missing) > 1 else 'y'} {', '.join(missing)} not "
            "found: written without materials"
        )
    if centre.any():
        # The export's nodes are all at the identity (``placed``): the roots take the
        # centre as their translation.
        nodes = document.json.get("nodes", [])
        roots = {n for scene_spec in document.json.get("scenes", []) for n in scene_spec["nodes"]}
        for root in sorted(roots):
            nodes[root].pop("matrix", None)
            nodes[root]["translation"] = [float(x) for x in centre]
    return document


#: A mesh whose box centre is farther from the origin than this many times its largest
#: side is stored relative to that centre (:func:`frame_centre`): there float32 rounds a
#: position by up to 1e-6 of the side, a sixteenth of a grid step at 18 bits.
FRAME_DISTANCE = 16.0


def _missing_material_libraries(path: Path) -> list[str]:
    """The ``mtllib`` files an OBJ names that are not beside it (trimesh then invents a
    material, with a placeholder image for one with UVs)."""
    if not path.suffix.lower() == ".obj":
        return []
    missing = []
    with path.open("rb") as lines:
        for line in lines:
            if line.startswith(b"mtllib"):
                for name in line[6:].decode("utf-8", "replace").split():
                    if not (path.parent / name).is_file():
                        missing.append(name)
    return missing


def _drop_materials(document: dict[str, Any]) -> None:
    """Remove every material, texture, sampler and image of a document (and the
    primitives' references to them): what an OBJ without its material library holds."""
    for key in ("materials", "textures", "samplers", "images"):
        document.pop(key, None)
    for mesh in document.get("meshes", []):
        for prim in mesh.get("primitives", []):
            prim.pop("material", None)


def frame_centre(points: np.ndarray) -> np.ndarray:
    """Where to put the origin of positions stored in float32 (mesh units): the centre of
    the points' box, rounded to the power of two at or above its largest side (a short
    number in the JSON; the positions stay within 1.5 sides of it), when that centre is
    farther from the origin than :data:`FRAME_DISTANCE` sides; else the origin itself."""
    if len(points) == 0:
        return np.zeros(3)
    lo, hi = points.min(axis=0), points.max(axis=0)
    extent = float((hi - lo).max())
    centre = (lo + hi) / 2
    if not np.abs(centre).max() > FRAME_DISTANCE * extent:
        return np.zeros(3)
    if extent > 0:
        unit = 2.0 ** math.ceil(math.log2(extent))
        centre = np.round(centre / unit) * unit
    return centre


def merged_bounds(points: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Bounding box of several point sets."""
    lo = np.min([p.min(axis=0) for p in points if len(p)], axis=0)
    hi = np.max([p.max(axis=0) for p in points if len(p)], axis=0)
    return lo, hi


def finite_or_fail(name: str, values: np.ndarray) -> None:
    """Refuse positions (rows of coordinates) holding NaN or infinity, naming the first
    such row as :func:`meshbits.shape_complexity` and ``load_mesh`` do."""
    if values.size and not np.isfinite(values).all():
        rows = values.reshape(len(values), -1)
        bad = ~np.isfinite(rows).all(axis=1)
        first = int(np.flatnonzero(bad)[0])
        raise MeshFileError(
            f"{name}[{first}] = {rows[first].tolist()} is not finite ({int(bad.sum())} "
            f"row{'s have' if bad.sum() > 1 else ' has'} NaN or infinite coordinates)"
        )


def rounded_bits(value: float, low: int, high: int) -> int:
    return int(min(max(math.ceil(value), low), high))
