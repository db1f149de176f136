"""meshoptimizer's codecs for glTF: a primitive as ``EXT_meshopt_compression`` streams
under ``KHR_mesh_quantization`` (:func:`encode_meshopt_primitive`), as gltfpack writes
it: positions as integer grid codes (or float32 on the grid), normals and tangents through
the octahedral filter, texture coordinates at their bits, colours and weights as bytes."""

from __future__ import annotations

from typing import Any

import numpy as np

from .. import _core
from ..formats.gltf.spec import COMPONENT_TYPES, WIDTH_TYPES
from .attributes import DEFAULT_UV_BITS, AttributeBits, in_unit_square
from .morph_targets import morph_bound, target_rows
from .primitive import PrimitiveEncoding, accessor_fields, index_component, unit_u8, weights_u8

__all__ = ["MESHOPT_INTEGER_BITS", "MESHOPT_MAX_BITS", "encode_meshopt_primitive"]

#: The most bits meshopt's integer positions hold (``KHR_mesh_quantization``'s shorts);
#: beyond, positions are float32 on the grid, up to :data:`MESHOPT_MAX_BITS`.
MESHOPT_INTEGER_BITS = 16
MESHOPT_MAX_BITS = 24

#: One stream and its accessor's fields.
Stream = tuple[dict[str, Any], dict[str, Any]]


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
    targets: list[dict[str, np.ndarray]] | None = None,
) -> PrimitiveEncoding:
    """A primitive as ``EXT_meshopt_compression`` streams under ``KHR_mesh_quantization``,
    triangles and vertices first reordered for the codecs (as gltfpack does): positions as
    their integer codes on the cube grid (bytes up to 8 bits, shorts up to 16; the
    dequantization goes to the nodes), or as float32 on the grid for a skinned or
    instanced primitive and beyond 16 bits; normals and tangents through the octahedral
    filter; UVs rounded to their bits, as normalized unsigned shorts within [0, 1] and
    float32 beyond; colours and weights as normalized bytes; joints as bytes or shorts.
    Morph ``targets`` (each ``name -> displacements``, in the order of ``vertices``) are
    stored as :mod:`meshbits.codecs.morph_targets` says, and the encoding's
    ``morph_bound`` certifies the morphed primitive at any weights in [0, 1]."""
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
        accessors["POSITION"] = accessor_fields(
            stored, COMPONENT_TYPES[np.dtype(dtype)], False, True
        )
    else:
        stored = grid.astype(np.float32)
        grid = stored.astype(np.float64)
        streams.append(_stream("POSITION", stored))
        accessors["POSITION"] = accessor_fields(stored, 5126, False, True)
    for name, values in attributes.items():
        stream, accessors[name] = _attribute_stream(name, np.asarray(values), attribute_bits)
        streams.append(stream)
    stream, accessors["indices"] = _index_stream(faces, n)
    streams.append(stream)
    target_accessors, deltas, bound = [], [], None
    if targets:
        rows, deltas = target_rows(targets, old, step, integer_positions, attribute_bits.normal)
        for number, target in enumerate(rows):
            target_accessors.append({})
            for name, stored_rows, fields in target:
                streams.append({**_stream(name, stored_rows), "target": number})
                target_accessors[-1][name] = fields
        bound = morph_bound(
            grid - vertices,
            [
                decoded - np.asarray(target.get("POSITION", np.zeros((len(old), 3))))[old]
                for decoded, target in zip(deltas, targets, strict=True)
            ],
        )
    return PrimitiveEncoding(
        size_bits=8 * sum(len(s["data"]) for s in streams),
        vertices=grid,
        faces=np.asarray(faces, dtype=np.int64),
        accessors=accessors,
        streams=streams,
        dequantize=(np.asarray(origin, dtype=np.float64), float(step))
        if integer_positions
        else None,
        target_accessors=target_accessors,
        target_deltas=deltas,
        morph_bound=bound,
    )


def _attribute_stream(name: str, values: np.ndarray, attribute_bits: AttributeBits) -> Stream:
    """A vertex attribute other than positions as its stream and accessor."""
    if name in ("NORMAL", "TANGENT"):
        return _octahedral_stream(name, values, attribute_bits.normal)
    if name.startswith("TEXCOORD_"):
        return _uv_stream(name, values, attribute_bits.uv.get(name, DEFAULT_UV_BITS))
    if name.startswith("COLOR_"):
        stored = unit_u8(values)
        return _stream(name, stored), accessor_fields(stored, 5121, True, False)
    if name.startswith("WEIGHTS_"):
        stored = weights_u8(values)
        return _stream(name, stored), accessor_fields(stored, 5121, True, False)
    if name.startswith("JOINTS_"):
        dtype = np.uint8 if values.size == 0 or values.max() < 256 else np.uint16
        stored = values.astype(dtype)
        component = COMPONENT_TYPES[np.dtype(dtype)]
        return _stream(name, stored), accessor_fields(stored, component, False, False)
    stored = values.astype(np.float32)
    return _stream(name, stored), accessor_fields(stored, 5126, False, False)


def _octahedral_stream(name: str, values: np.ndarray, bits: int) -> Stream:
    """Normals or tangents through meshoptimizer's octahedral filter at ``bits``: signed
    bytes (up to 8 bits) or shorts, normalized; a normal's fourth component is 1."""
    n = len(values)
    vectors = np.zeros((n, 4), dtype=np.float32)
    vectors[:, :3] = values[:, :3]
    vectors[:, 3] = values[:, 3] if values.shape[1] == 4 else 1.0
    octa = _core.meshopt_encode_octahedral(np.ascontiguousarray(vectors), bits)
    component = 5120 if octa.shape[1] == 4 else 5122
    stream = _stream(name, octa, "OCTAHEDRAL")
    stream["stride"] = octa.shape[1]
    width = 3 if name == "NORMAL" else 4
    accessor = {
        "count": n,
        "componentType": component,
        "type": WIDTH_TYPES[width],
        "normalized": True,
    }
    return stream, accessor


def _uv_stream(name: str, values: np.ndarray, bits: int) -> Stream:
    """Texture coordinates rounded to ``bits`` over their range: normalized unsigned
    shorts within [0, 1], else float32."""
    levels = 2**bits - 1
    if in_unit_square(values, 0.5 / levels):
        # Normalized unsigned shorts (KHR_mesh_quantization): the b-bit steps of
        # [0, 1], each at its nearest short (exact for 8 and 16 bits, at most
        # 1/131070 off otherwise). A float32 stream of the same values compresses
        # worse: the new-user check's textured scene went from 23,292 to 20,484 bytes.
        steps = np.round(np.clip(values, 0.0, 1.0) * levels)
        stored = np.round(steps * (65535 / levels)).astype(np.uint16)
        return _stream(name, stored), accessor_fields(stored, 5123, True, False)
    lo, extent = values.min(axis=0), max(float(np.ptp(values, axis=0).max()), 1e-30)
    uv_step = extent / levels
    rounded = (lo + np.round((values - lo) / uv_step) * uv_step).astype(np.float32)
    return _stream(name, rounded), accessor_fields(rounded, 5126, False, False)


def _index_stream(faces: np.ndarray, vertex_count: int) -> Stream:
    """The triangles through meshoptimizer's index codec, and their accessor (unsigned
    shorts below 65,536 vertices, else unsigned ints)."""
    component = index_component(vertex_count)
    triangles = np.ascontiguousarray(faces, dtype=np.uint32)
    index_size = 2 if component == 5123 else 4
    stream = {
        "name": "indices",
        "data": _core.meshopt_encode_triangles(triangles, vertex_count),
        "raw": triangles.astype(np.uint16 if index_size == 2 else np.uint32).tobytes(),
        "stride": index_size,
        "count": int(triangles.size),
        "mode": "TRIANGLES",
        "filter": "NONE",
    }
    accessor = {"count": int(triangles.size), "componentType": component, "type": "SCALAR"}
    return stream, accessor
