"""Fixed-width formats: quantized binary PLY and quantized glTF (GLB with
``KHR_mesh_quantization``), every vertex and face in a fixed number of bytes, no entropy
coding; and their size, exact up to the JSON header's numbers, without encoding
(:func:`fixed_width_size_bits`)."""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from ..constants import FORMAT_MAX_BITS
from ..errors import MeshbitsError
from ..formats.gltf.spec import COMPONENT_TYPES
from ..formats.gltf.write import float32_safe, glb_bytes, json_number, split_translation
from ..mesh import MeshLike, as_mesh, compact
from ..quantize import quantize
from .encoded import Encoded, check_bits, encoding_grid

__all__ = ["encode_quantized_glb", "encode_quantized_ply", "fixed_width_size_bits"]


def encode_quantized_ply(
    mesh: MeshLike, bits: int, *, origin: Any = None, grid_size: float | None = None
) -> Encoded:
    """Binary PLY with positions quantized to ``bits`` on the cube grid (by
    :func:`meshbits.quantize`) and stored as dequantised float32 (what any PLY reader
    accepts); unreferenced vertices dropped."""
    vertices, faces = as_mesh(mesh)
    bits = check_bits(bits, FORMAT_MAX_BITS["ply"])
    vertices, faces = compact(vertices, faces)
    lo, size = encoding_grid(vertices, origin, grid_size)
    quantized = quantize(vertices, bits, box=(lo, lo + size))
    positions = quantized.positions.astype(np.float32)
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"comment meshbits quantized positions: {bits} bits per coordinate, "
        f"origin {lo.tolist()}, grid size {size!r}\n"
        f"element vertex {len(positions)}\nproperty float x\nproperty float y\nproperty float z\n"
        f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    face_records = np.zeros(len(faces), dtype=[("n", "u1"), ("v", "<i4", (3,))])
    face_records["n"] = 3
    face_records["v"] = faces
    data = header.encode() + positions.astype("<f4").tobytes() + face_records.tobytes()
    return Encoded(
        "ply",
        data,
        bits,
        positions.astype(np.float64),
        faces.astype(np.int64),
        np.asarray(quantized.codes, dtype=np.uint32),
    )


def _padded(data: bytes) -> bytes:
    return data + b"\0" * (-len(data) % 4)


def encode_quantized_glb(
    mesh: MeshLike, bits: int, *, origin: Any = None, grid_size: float | None = None
) -> Encoded:
    """Binary glTF 2.0 (GLB) with positions stored as their integer grid codes.

    The glTF route to quantized positions, as gltfpack writes it: the extension
    ``KHR_mesh_quantization`` (required by the file) lets ``POSITION`` be unsigned bytes
    (``bits <= 8``) or unsigned shorts (``bits <= 16``), not normalized, holding the corner
    codes of :func:`meshbits.quantize` on the cube grid; the mesh's node carries
    ``translation = origin`` and ``scale = step`` (``grid_size / (2^B - 1)``) so that a
    viewer places ``origin + code * step``. Each vertex takes 4 (bytes) or 8 (shorts)
    bytes, padded to glTF's 4-byte alignment; indices are unsigned shorts below 65,536
    vertices, else unsigned ints. No entropy coding: the size is ``~ V * stride + 3 * F *
    index_size`` plus a small JSON header. Unreferenced vertices are dropped.

    The returned ``vertices`` are the codes through the node's transform composed in
    float64, ``origin + step * code``, as the node's JSON numbers give it (the convention of
    every certified bound: stored positions through float64 node transforms).
    """
    vertices, faces = as_mesh(mesh)
    bits = check_bits(bits, FORMAT_MAX_BITS["glb"])
    vertices, faces = compact(vertices, faces)
    lo, size = encoding_grid(vertices, origin, grid_size)
    q = quantize(vertices, bits, box=(lo, lo + size))
    codes = np.asarray(q.codes, dtype=np.uint16)
    step = float(q.step[0])
    data = _quantized_glb(bits, lo, step, codes, faces)
    decoded = lo + step * codes.astype(np.float64)
    return Encoded(
        "glb",
        data,
        bits,
        decoded.astype(np.float64),
        faces.astype(np.int64),
        codes.astype(np.uint32),
    )


def _placed(lo: np.ndarray, step: float, extent: float) -> list[dict[str, Any]]:
    """The nodes placing the codes: one at ``translation = lo``, ``scale = step``; or,
    where a float32 reader would round ``lo`` by more than a position near the origin,
    a float32-exact parent and that node inside it
    (:func:`meshbits.formats.gltf.write.split_translation`)."""
    if float32_safe(lo, extent):
        return [{"mesh": 0, "translation": [float(x) for x in lo], "scale": [step] * 3}]
    outer, inner = split_translation(lo, extent)
    return [
        {"translation": [json_number(x) for x in outer], "children": [1]},
        {"mesh": 0, "translation": [float(x) for x in inner], "scale": [step] * 3},
    ]


def _quantized_glb(
    bits: int, lo: np.ndarray, step: float, codes: np.ndarray, faces: np.ndarray
) -> bytes:
    """The GLB of :func:`encode_quantized_glb` (through the one glTF writer,
    :func:`meshbits.formats.gltf.write.glb_bytes`): integer ``codes`` (uint16) at
    ``bits``, placed by the node at ``translation = lo`` and ``scale = step``, and
    ``faces``. Its JSON is pygltflib's, which wrote these files before (the same bytes)."""
    if bits <= 8:
        component, stride = COMPONENT_TYPES[np.dtype(np.uint8)], 4
        packed = np.zeros((len(codes), 4), dtype=np.uint8)
    else:
        component, stride = COMPONENT_TYPES[np.dtype(np.uint16)], 8
        packed = np.zeros((len(codes), 4), dtype="<u2")
    packed[:, :3] = codes
    if len(codes) < 65536:
        index_component, indices = COMPONENT_TYPES[np.dtype(np.uint16)], faces.astype("<u2")
    else:
        index_component, indices = COMPONENT_TYPES[np.dtype(np.uint32)], faces.astype("<u4")
    index_data, position_data = _padded(indices.tobytes()), packed.tobytes()
    accessors = [
        (index_component, int(faces.size), "SCALAR", [int(faces.max())], [int(faces.min())]),
        (
            component,
            len(codes),
            "VEC3",
            [int(x) for x in codes.max(axis=0)],
            [int(x) for x in codes.min(axis=0)],
        ),
    ]
    document = {
        "accessors": [
            {
                "bufferView": view,
                "byteOffset": 0,
                "componentType": component_type,
                "normalized": False,
                "count": count,
                "type": kind,
                "max": high,
                "min": low,
            }
            for view, (component_type, count, kind, high, low) in enumerate(accessors)
        ],
        "asset": {"generator": f"meshbits, {bits} bits per coordinate", "version": "2.0"},
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": indices.nbytes, "target": 34963},
            {
                "buffer": 0,
                "byteOffset": len(index_data),
                "byteLength": len(position_data),
                "byteStride": stride,
                "target": 34962,
            },
        ],
        "buffers": [{"byteLength": len(index_data) + len(position_data)}],
        "extensionsUsed": ["KHR_mesh_quantization"],
        "extensionsRequired": ["KHR_mesh_quantization"],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 1}, "indices": 0, "mode": 4}]}],
        "nodes": _placed(lo, step, float(np.ptp(codes, axis=0).max(initial=0)) * step),
        "scene": 0,
        "scenes": [{"nodes": [0]}],
    }
    return glb_bytes(document, index_data + position_data)


def fixed_width_size_bits(format: str, bits: int, vertices: float, faces: float) -> float:
    """Size in bits of a mesh encoded in a fixed-width ``format`` (``"glb"`` or ``"ply"``:
    :func:`encode_quantized_glb`, :func:`encode_quantized_ply`) for a mesh of
    ``vertices`` referenced vertices and ``faces`` triangles.

    These formats store every vertex and face in a fixed number of bytes, so the size is
    ``header + V * vertex_bytes + F * face_bytes`` and depends on ``B`` only through the
    component type: glb positions take 4 bytes (``B <= 8``) or 8 (``B <= 16``) per vertex
    and its indices 2 bytes per corner below 65,536 vertices, else 4; ply takes 12 bytes
    per vertex (float32) and 13 per face. The header is measured by encoding a
    tetrahedron in the format; the JSON numbers of a real header (its box, translation and
    scale) make it up to about 100 bytes longer or shorter.
    """
    bits = check_bits(bits, FORMAT_MAX_BITS.get(format, 0) or 1)
    if format not in ("glb", "ply"):
        raise MeshbitsError(f"format must be 'glb' or 'ply' (fixed width), got {format!r}")
    vertex_bytes, face_bytes = _fixed_width_record(format, bits, vertices)
    return 8.0 * (_fixed_width_header(format, bits) + vertices * vertex_bytes + faces * face_bytes)


def _fixed_width_record(format: str, bits: int, vertices: float) -> tuple[int, int]:
    """Bytes of one vertex and of one face in ``format`` at ``bits``."""
    if format == "ply":
        return 12, 13
    return (4 if bits <= 8 else 8), 3 * (2 if vertices < 65536 else 4)


@functools.lru_cache(maxsize=64)
def _fixed_width_header(format: str, bits: int) -> int:
    """Bytes of ``format``'s file besides its vertex and face records (measured on a
    tetrahedron)."""
    tetrahedron = (
        np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]),
        np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]),
    )
    encoder = encode_quantized_glb if format == "glb" else encode_quantized_ply
    encoded = encoder(tetrahedron, bits)
    vertex_bytes, face_bytes = _fixed_width_record(format, bits, 4)
    payload = 4 * vertex_bytes + len(_padded(b"\0" * (4 * face_bytes)))
    if format == "ply":
        payload = 4 * vertex_bytes + 4 * face_bytes
    return encoded.size_bits // 8 - payload
