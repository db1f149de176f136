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
    vertices = np.asarray(vertices, dtype=np.float64)
    n = len(vertices)
    step = grid_size / (2**bits - 1) if grid_size > 0 else 1.0
    codes = np.clip(np.round((vertices - origin) / step), 0, 2**bits - 1)
    grid = origin + codes * step
    # Every stream's rows in the input's order first: vertices whose rows are all the
    # same are one vertex (a flat-shaded mesh's corners, stored once per face), then
    # triangles and vertices are reordered for the codecs.
    if integer_positions:
        dtype = np.uint8 if bits <= 8 else np.uint16
        stored = codes.astype(dtype)
        columns = [
            (
                "POSITION",
                stored,
                accessor_fields(stored, COMPONENT_TYPES[np.dtype(dtype)], False, True),
                "NONE",
            )
        ]
    else:
        stored = grid.astype(np.float32)
        grid = stored.astype(np.float64)
        columns = [("POSITION", stored, accessor_fields(stored, 5126, False, True), "NONE")]
    for name, values in (attributes or {}).items():
        columns.append((name, *_attribute_rows(name, np.asarray(values), attribute_bits)))
    target_accessors, deltas, bound = [], [], None
    target_columns: list[list[tuple[str, np.ndarray, dict[str, Any]]]] = []
    if targets:
        target_columns, deltas = target_rows(
            targets, np.arange(n), step, integer_positions, attribute_bits.normal
        )
        bound = morph_bound(
            grid - vertices,
            [
                decoded - np.asarray(target.get("POSITION", np.zeros((n, 3))))
                for decoded, target in zip(deltas, targets, strict=True)
            ],
        )
    every = [rows for _, rows, _, _ in columns]
    every += [rows for target in target_columns for _, rows, _ in target]
    first, inverse = _same_rows(every, n)
    welded = inverse[np.asarray(faces, dtype=np.int64)]
    order_faces, old = _core.meshopt_reorder(
        np.ascontiguousarray(welded, dtype=np.uint32), len(first)
    )
    keep = first[old]
    faces = order_faces.astype(np.int64)
    streams, accessors = [], {}
    for name, rows, fields, filter_name in columns:
        streams.append(_stream(name, rows[keep], filter_name))
        accessors[name] = {**fields, "count": len(keep)}
    stream, accessors["indices"] = _index_stream(faces, len(keep))
    streams.append(stream)
    for number, target in enumerate(target_columns):
        target_accessors.append({})
        for name, rows, fields in target:
            streams.append({**_stream(name, rows[keep]), "target": number})
            target_accessors[-1][name] = {**fields, "count": len(keep)}
    deltas = [d[keep] for d in deltas]
    grid = grid[keep]
    return PrimitiveEncoding(
        size_bits=8 * sum(len(s["data"]) for s in streams),
        vertices=grid,
        faces=faces,
        accessors=accessors,
        streams=streams,
        dequantize=(np.asarray(origin, dtype=np.float64), float(step))
        if integer_positions
        else None,
        target_accessors=target_accessors,
        target_deltas=deltas,
        morph_bound=bound,
    )


#: One attribute's rows to store, their accessor fields and the stream's filter.
Rows = tuple[np.ndarray, dict[str, Any], str]


def _same_rows(columns: list[np.ndarray], count: int) -> tuple[np.ndarray, np.ndarray]:
    """Vertices whose stored rows are the same in every column, as one: the first vertex
    of each distinct set of rows (in the order they first appear) and each vertex's index
    among those. Merging them changes no decoded value."""
    if count == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    raw = np.hstack([np.ascontiguousarray(c).view(np.uint8).reshape(count, -1) for c in columns])
    keys = np.ascontiguousarray(raw).view(np.dtype((np.void, raw.shape[1]))).reshape(-1)
    _, first, inverse = np.unique(keys, return_index=True, return_inverse=True)
    # Number the distinct rows in the order they first appear.
    rank = np.empty(len(first), dtype=np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(len(first))
    return np.sort(first), rank[inverse.reshape(-1)]


def _attribute_rows(name: str, values: np.ndarray, attribute_bits: AttributeBits) -> Rows:
    """A vertex attribute other than positions: its rows, accessor fields and filter."""
    if name in ("NORMAL", "TANGENT"):
        return _octahedral_rows(name, values, attribute_bits.normal)
    if name.startswith("TEXCOORD_"):
        return _uv_rows(values, attribute_bits.uv.get(name, DEFAULT_UV_BITS))
    if name.startswith("COLOR_"):
        stored = unit_u8(values)
        return stored, accessor_fields(stored, 5121, True, False), "NONE"
    if name.startswith("WEIGHTS_"):
        stored = weights_u8(values)
        return stored, accessor_fields(stored, 5121, True, False), "NONE"
    if name.startswith("JOINTS_"):
        dtype = np.uint8 if values.size == 0 or values.max() < 256 else np.uint16
        stored = values.astype(dtype)
        component = COMPONENT_TYPES[np.dtype(dtype)]
        return stored, accessor_fields(stored, component, False, False), "NONE"
    stored = values.astype(np.float32)
    return stored, accessor_fields(stored, 5126, False, False), "NONE"


def _octahedral_rows(name: str, values: np.ndarray, bits: int) -> Rows:
    """Normals or tangents through meshoptimizer's octahedral filter at ``bits``: signed
    bytes (up to 8 bits) or shorts, normalized; a normal's fourth component is 1."""
    n = len(values)
    vectors = np.zeros((n, 4), dtype=np.float32)
    vectors[:, :3] = values[:, :3]
    vectors[:, 3] = values[:, 3] if values.shape[1] == 4 else 1.0
    octa = _core.meshopt_encode_octahedral(np.ascontiguousarray(vectors), bits)
    component = 5120 if octa.shape[1] == 4 else 5122
    width = 3 if name == "NORMAL" else 4
    accessor = {
        "count": n,
        "componentType": component,
        "type": WIDTH_TYPES[width],
        "normalized": True,
    }
    return octa, accessor, "OCTAHEDRAL"


def _uv_rows(values: np.ndarray, bits: int) -> Rows:
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
        return stored, accessor_fields(stored, 5123, True, False), "NONE"
    lo, extent = values.min(axis=0), max(float(np.ptp(values, axis=0).max()), 1e-30)
    uv_step = extent / levels
    rounded = (lo + np.round((values - lo) / uv_step) * uv_step).astype(np.float32)
    return rounded, accessor_fields(rounded, 5126, False, False), "NONE"


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
