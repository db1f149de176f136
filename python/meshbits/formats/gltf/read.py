"""Reading glTF: GLB and glTF bytes into a :class:`~.document.Document`, and a mesh of
another format into one through trimesh's GLB export.

A GLB's header is checked against its size before anything is parsed
(:func:`check_glb_header`); a document's references and values are checked
(:mod:`.validate`) before its buffers are taken from the GLB's binary chunk, data URIs or
files beside it. Which file is read how is the dispatcher's choice
(:mod:`meshbits.formats.open`).
"""

from __future__ import annotations

import base64
import json
import struct
from pathlib import Path
from typing import Any
from urllib.parse import unquote

import numpy as np

from ...errors import MeshFileError
from ..obj import missing_material_libraries
from .document import Document
from .spec import GLB_MAGIC, MESHOPT_EXTENSIONS, unread_required_extensions
from .validate import check_references
from .write import frame_centre, json_number

__all__ = [
    "check_glb_header",
    "document_from_trimesh",
    "drop_materials",
    "read_glb",
    "read_gltf",
    "read_gltf_json",
]


def check_glb_header(buffer: Any, size: int) -> None:
    """Compare what a GLB file's header and chunk headers declare with what ``buffer``
    (the whole file, ``size`` bytes) holds, and refuse a document that requires an
    extension meshbits does not read."""
    head = bytes(buffer[: min(size, 20)])
    if size < 20 or head[:4] != GLB_MAGIC:
        raise MeshFileError(
            "the file does not start with a GLB header ('glTF' and 16 more bytes): "
            "not a binary glTF"
        )
    version, length = (int(x) for x in np.frombuffer(head, "<u4", 2, 4))
    if version != 2:
        raise MeshFileError(f"GLB version {version}: only version 2 is read")
    if length > size:
        raise MeshFileError(
            f"the GLB header declares {length:,} bytes but the file has {size:,}: truncated "
            "or damaged"
        )
    if head[16:20] != b"JSON":
        raise MeshFileError("the GLB's first chunk is not its JSON: damaged")
    (json_length,) = np.frombuffer(head, "<u4", 1, 12)
    try:
        document = json.loads(bytes(buffer[20 : 20 + min(int(json_length), size - 20)]))
    except (ValueError, UnicodeDecodeError):
        document = None  # the GLB reader says what is wrong with the JSON
    # Meshopt compression (EXT_ and KHR_meshopt_compression) and Draco are decoded, and
    # KHR_mesh_quantization read; any other required extension that changes how geometry
    # is stored cannot be read right.
    unread = unread_required_extensions(document)
    if unread:
        raise MeshFileError(
            f"the GLB requires the extension{'s' if len(unread) > 1 else ''} "
            f"{', '.join(unread)}, which meshbits does not read"
        )
    offset, number = 12, 0
    while offset + 8 <= min(length, size):
        (chunk,) = np.frombuffer(buffer, "<u4", 1, offset)
        if offset + 8 + int(chunk) > size:
            raise MeshFileError(
                f"GLB chunk {number} declares {int(chunk):,} bytes but {size - offset - 8:,} "
                "follow it: truncated or damaged"
            )
        offset += 8 + int(chunk)
        number += 1


def read_gltf(path: Path, file_type: str, data: bytes | None = None) -> Document:
    """The document of a ``.glb`` or ``.gltf`` file (``file_type`` ``"glb"`` or
    ``"gltf"``): its bytes ``data``, or read from ``path``; buffers and images named by
    relative URI are looked for beside ``path``. Raises :class:`MeshFileError` naming
    ``path`` when the document is refused; a file whose JSON does not parse raises the
    parser's error, for the caller to explain."""
    try:
        if file_type == "glb":
            return read_glb(path.read_bytes() if data is None else data, path.parent)
        text = path.read_text(encoding="utf-8") if data is None else data.decode("utf-8")
        return read_gltf_json(json.loads(text), path.parent)
    except MeshFileError as err:
        raise MeshFileError(f"cannot read {path}: {err}") from None


def read_glb(data: bytes, base: Path | None) -> Document:
    """A GLB's document: its JSON chunk and its first binary chunk; ``base`` is the
    folder of files its URIs name."""
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
    return read_gltf_json(document, base, binary)


def read_gltf_json(document: dict[str, Any], base: Path | None, binary: bytes = b"") -> Document:
    """A glTF JSON's document, once its references and values are checked: each buffer
    from ``binary`` (a GLB's chunk), a data URI or a file in ``base``."""
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
            file = base / unquote(uri)
            if not file.is_file():
                raise MeshFileError(f"buffer {i}: no such file {file}")
            data = file.read_bytes()
        if len(data) < int(buffer.get("byteLength", 0)):
            raise MeshFileError(
                f"buffer {i} should hold {buffer.get('byteLength')} bytes, has {len(data)}"
            )
        buffers.append(data)
    return Document(document, buffers, base)


def document_from_trimesh(loaded: Any, path: Path, file_type: str) -> Document:
    """A mesh file of another format, parsed by trimesh (``loaded``, from ``path``), as a
    glTF document, through trimesh's glTF export. The export stores positions as
    float32; the document keeps the file's own (float64) in
    :attr:`Document.exact_positions`. A mesh far from the origin (its box's centre
    farther than its largest side) is exported relative to that centre, which a root node
    carries as its translation (float64 in the JSON), so that float32 keeps its
    precision."""
    # trimesh is imported on first use: it takes longer to import than meshbits.
    import trimesh

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
    document = read_glb(scene.export(file_type="glb"), path.parent)
    _keep_exact_positions(document, exact, centre)
    missing = missing_material_libraries(path) if file_type == "obj" else []
    if missing:
        drop_materials(document.json)
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
            nodes[root]["translation"] = [json_number(x) for x in centre]
    return document


def _keep_exact_positions(
    document: Document, exact: dict[str, np.ndarray], centre: np.ndarray
) -> None:
    """Record each exported ``POSITION`` accessor's float64 values (relative to
    ``centre``) where they round to what the accessor stores."""
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


def drop_materials(document: dict[str, Any]) -> None:
    """Remove every material, texture, sampler and image of a document (and the
    primitives' references to them): what an OBJ without its material library holds."""
    for key in ("materials", "textures", "samplers", "images"):
        document.pop(key, None)
    for mesh in document.get("meshes", []):
        for prim in mesh.get("primitives", []):
            prim.pop("material", None)
