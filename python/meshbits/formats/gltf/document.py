"""The glTF document: a glTF 2.0 JSON with its buffers in memory, read into numpy.

:class:`Document` reads accessors (any component type, ``byteStride``, normalized
integers, sparse accessors), decodes what compression left (buffer views compressed
with ``EXT_meshopt_compression`` or ``KHR_meshopt_compression`` when the document is
made, with meshoptimizer's decoders in the Rust core; primitives compressed with
``KHR_draco_mesh_compression`` when read, with DracoPy), and walks the scene graph into
world-space instances. Its JSON is checked first (:mod:`.validate`); files become
documents in :mod:`.read`.
"""

from __future__ import annotations

import base64
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import unquote

import numpy as np

from ... import _core
from ...errors import MeshbitsError, MeshFileError
from ..sniff import mime_type
from .spec import (
    COMPONENT_DTYPES,
    DRACO,
    MESHOPT_EXTENSIONS,
    MESHOPT_LIMIT,
    TRIANGLE_FAN,
    TRIANGLE_STRIP,
    TRIANGLES,
    TYPE_WIDTHS,
    from_normalized,
    triangles,
    trs_matrix,
)

__all__ = ["Document", "PrimitiveData", "largest_scale"]


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
        It has morph targets.
    targets : list of dict
        Each morph target's displacements by attribute name (``POSITION``, ``NORMAL``,
        ``TANGENT``...), float64 ``(n, 3)`` (normalized integers mapped to [-1, 1]), in
        the order of ``positions``; empty for a primitive without targets and for a Draco
        primitive's (whose decoded vertex order need not be its accessors').
    """

    mesh: int
    index: int
    positions: np.ndarray = field(repr=False)
    faces: np.ndarray = field(repr=False)
    attributes: dict[str, np.ndarray] = field(repr=False)
    source_types: dict[str, tuple[int, bool]] = field(repr=False)
    material: int | None
    morph: bool
    targets: list[dict[str, np.ndarray]] = field(default_factory=list, repr=False)

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
            if value > MESHOPT_LIMIT:
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
            return from_normalized(values) if acc.get("normalized") else values.astype(np.float64)
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
        path = self.base / unquote(uri)
        if not path.is_file():
            raise MeshFileError(f"image {index}: no such file {path}")
        return path.read_bytes(), mime or mime_type(path.name)

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
        faces = triangles(indices.astype(np.int64), mode)
        if len(faces) and (faces.min() < 0 or faces.max() >= len(positions)):
            bad = int(np.flatnonzero(((faces < 0) | (faces >= len(positions))).any(axis=1))[0])
            raise MeshFileError(
                f"meshes[{mesh}].primitives[{index}]: face {bad} = {faces[bad].tolist()} "
                f"refers to a vertex out of range (there are {len(positions)} vertices)"
            )
        types.pop("POSITION", None)
        targets = [] if draco is not None else self._targets(prim, len(positions), mesh, index)
        return PrimitiveData(
            mesh=mesh,
            index=index,
            positions=positions.astype(np.float64),
            faces=faces,
            attributes=attributes,
            source_types=types,
            material=prim.get("material"),
            morph=bool(prim.get("targets")),
            targets=targets,
        )

    def _targets(
        self, prim: dict[str, Any], count: int, mesh: int, index: int
    ) -> list[dict[str, np.ndarray]]:
        """A primitive's morph targets: each one's displacements by attribute name,
        float64, one row per vertex (``count``)."""
        out = []
        for t, target in enumerate(prim.get("targets") or []):
            values = {}
            for name, acc in target.items():
                delta = self.accessor(acc).astype(np.float64)
                if len(delta) != count:
                    raise MeshFileError(
                        f"meshes[{mesh}].primitives[{index}].targets[{t}].{name}: "
                        f"{len(delta)} values for {count} vertices"
                    )
                values[name] = delta
            out.append(values)
        return out

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
                data = from_normalized(data.astype(dtype))
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
        return trs_matrix(
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
            out.append(trs_matrix(t, q, scale))
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


def largest_scale(matrix: np.ndarray) -> float:
    """The largest singular value of a transform's linear part: how much it can stretch a
    length."""
    return float(np.linalg.svd(matrix[:3, :3], compute_uv=False).max())
