"""Draco: a mesh (:func:`encode_draco`) or a glTF primitive with its attributes
(:func:`encode_draco_primitive`, for ``KHR_draco_mesh_compression``) encoded through
DracoPy, positions quantized on the cube grid, and decoded back, since what a reader gets
is what is measured; with the workarounds Draco 1.5.7 needs (tiny grids, levels it
refuses, its messages on the process's output)."""

from __future__ import annotations

import contextlib
import math
import os
import sys
import threading
from collections.abc import Iterator
from typing import Any

import numpy as np

from ..constants import FORMAT_MAX_BITS
from ..errors import MeshbitsError
from ..formats.drc import decode_draco
from ..mesh import MeshLike, all_faces_degenerate, as_mesh
from .attributes import AttributeBits
from .encoded import Encoded, check_bits, encoding_grid
from .primitive import PrimitiveEncoding, accessor_fields, index_component, unit_u8

__all__ = [
    "DRACO_FALLBACK_LEVELS",
    "DRACO_MIN_RANGE",
    "draco_codes",
    "draco_encode",
    "draco_max_bits",
    "draco_quantization",
    "encode_draco",
    "encode_draco_primitive",
]

#: The smallest quantization range (length) handed to Draco. DracoPy 2.2 (Draco 1.5.7)
#: quantizes a range below 1e-6 as if it were 1e-6, and one below about 5e-7 decodes every
#: vertex to one point (measured on the bunny scaled to sides of 2e-6 down to 1e-8): a
#: smaller grid is handed over as a larger range with more bits and the same step.
DRACO_MIN_RANGE = 2e-6


def draco_quantization(bits: int, grid_size: float) -> tuple[int, float]:
    """The bits and range to hand Draco for a cube grid of side ``grid_size`` at ``bits``:
    as they are, or for a grid below :data:`DRACO_MIN_RANGE`, the range doubled ``k``
    times and ``k`` more bits (a step within 2^-bits of the same; codes beyond the grid
    go unused, and cost no bytes to speak of: 0.2% on the bunny at 11 bits and k = 1..10).
    A non-positive ``grid_size`` (one point) passes as Draco's own range (-1)."""
    if not grid_size > 0:
        return int(bits), -1.0
    extra = max(0, math.ceil(math.log2(DRACO_MIN_RANGE / grid_size)))
    return int(bits) + extra, float(grid_size) * 2.0**extra


#: Compression levels tried after the one asked for, when Draco refuses to encode a mesh
#: at it: Draco 1.5.7 at levels 7 to 10 fails ("Failed to encode point attributes") on some
#: meshes with texture coordinates at some position bits (the bunny at 3,851 faces with
#: UVs, at B = 18 to 21), where levels 6 and below, whose predictions differ, encode it.
DRACO_FALLBACK_LEVELS = (6, 5, 0)


@contextlib.contextmanager
def _quiet_output() -> Iterator[None]:
    """Silence the process's standard output and error (file descriptors 1 and 2) for the
    duration: DracoPy prints "Draco encoding error: ..." when it refuses a mesh, into a
    terminal or a report a caller may be writing as JSON. The refusal itself is raised,
    and said in words."""
    with _OUTPUT_LOCK:  # threads must not interleave their swaps of the descriptors
        sys.stdout.flush()
        sys.stderr.flush()
        try:
            saved = [os.dup(1), os.dup(2)]
        except OSError:  # no standard output to silence
            yield
            return
        try:
            with open(os.devnull, "wb") as null:
                os.dup2(null.fileno(), 1)
                os.dup2(null.fileno(), 2)
                yield
        finally:
            for descriptor, copy in zip((1, 2), saved, strict=True):
                os.dup2(copy, descriptor)
                os.close(copy)


_OUTPUT_LOCK = threading.Lock()


def draco_encode(vertices: np.ndarray, faces: np.ndarray, **options: Any) -> bytes:
    """``DracoPy.encode`` at ``options["compression_level"]``, or when Draco refuses the
    mesh there, at the first of :data:`DRACO_FALLBACK_LEVELS` below it that it takes.
    Raises :class:`MeshbitsError` when no level does."""
    import DracoPy

    level = int(options.pop("compression_level", 7))
    levels = [level, *(x for x in DRACO_FALLBACK_LEVELS if x < level)]
    for attempt in levels:
        try:
            with _quiet_output():
                return DracoPy.encode(vertices, faces, compression_level=attempt, **options)
        except DracoPy.EncodingFailedException as err:
            failure = err
    raise MeshbitsError(
        f"Draco could not encode the mesh at compression levels {levels} "
        f"({options.get('quantization_bits')} bits per coordinate): {failure}"
    )


def draco_max_bits(grid_size: float) -> int:
    """The most bits per coordinate Draco can take on a grid of side ``grid_size``:
    30, less the bits :func:`draco_quantization` adds to a tiny grid."""
    extra = draco_quantization(0, grid_size)[0]
    return max(1, FORMAT_MAX_BITS["draco"] - extra)


def encode_draco(
    mesh: MeshLike,
    bits: int,
    *,
    compression_level: int = 7,
    origin: Any = None,
    grid_size: float | None = None,
) -> Encoded:
    """Encode with Draco, quantizing positions to ``bits`` per coordinate.

    The grid is the cube of side ``grid_size`` (default: the largest bounding-box side)
    at ``origin`` (default: the bounding box's min corner), the paper's grid and the one
    :func:`meshbits.quantize` uses. Draco drops unreferenced vertices.
    """

    vertices, faces = as_mesh(mesh)
    bits = check_bits(bits, FORMAT_MAX_BITS["draco"])
    lo, size = encoding_grid(vertices, origin, grid_size)
    if bits > draco_max_bits(size):
        raise MeshbitsError(
            f"bits must be at most {draco_max_bits(size)} for Draco on a grid of side "
            f"{size:.4g}: a grid below {DRACO_MIN_RANGE:g} takes more bits (got {bits})"
        )
    draco_bits, draco_range = draco_quantization(bits, size)
    # Draco refuses a mesh whose every face has two corners at one position, and says so
    # on the process's stderr: refuse it here in words instead.
    if all_faces_degenerate(vertices, faces):
        which = "its only face is" if len(faces) == 1 else f"all {len(faces)} faces are"
        raise MeshbitsError(
            f"{which} degenerate (two corners at one position): Draco encodes none of them"
        )
    data = draco_encode(
        vertices,
        faces,
        quantization_bits=draco_bits,
        compression_level=int(compression_level),
        quantization_range=draco_range,
        quantization_origin=lo,
    )
    decoded_vertices, decoded_faces = decode_draco(data)
    codes = draco_codes(decoded_vertices, lo, size, bits)
    return Encoded("draco", data, bits, decoded_vertices, decoded_faces, codes)


def draco_codes(decoded: Any, origin: Any, grid_size: float, bits: int) -> np.ndarray:
    """The grid codes of positions decoded from a Draco file quantized to ``bits`` on the
    cube at ``origin`` with side ``grid_size``: the nearest code of each coordinate.

    Draco does not decode onto the nominal grid exactly: on the bunny its decoded
    positions sit up to 2.6e-6 S off ``origin + code * step`` at B = 8 to 16 (a shift of
    its stored origin, not float32 rounding), 0.18 step at B = 16, 0.37 at B = 20 and
    0.5 at B = 24. Up to about 18 bits the nearest code is therefore the one Draco
    stored; beyond, a decoded coordinate can lie halfway and the code is the nearest
    one, not necessarily Draco's.
    """
    x = np.asarray(decoded, dtype=np.float64)
    step = float(grid_size) / (2**bits - 1)
    if step == 0:
        return np.zeros(x.shape, dtype=np.uint32)
    codes = np.rint((x - np.asarray(origin, dtype=np.float64)) / step)
    return np.clip(codes, 0, 2**bits - 1).astype(np.uint32)


def encode_draco_primitive(
    vertices: np.ndarray,
    faces: np.ndarray,
    attributes: dict[str, np.ndarray] | None,
    bits: int,
    origin: np.ndarray,
    grid_size: float,
    attribute_bits: AttributeBits,
) -> PrimitiveEncoding:
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
            generic[name] = unit_u8(values)
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
        colors=unit_u8(attributes[colors[0]]) if colors else None,
        generic_attributes=generic or None,
        normal_quantization_bits=attribute_bits.normal if "NORMAL" in attributes else None,
        tex_coord_quantization_bits=attribute_bits.uv.get(uv_names[0]) if uv_names else None,
    )
    mesh = DracoPy.decode(data)
    ids, decoded = _decoded_attributes(
        mesh, uv_names[0] if uv_names else None, colors[0] if colors else None
    )
    positions = decoded["POSITION"].astype(np.float64)
    triangles = np.asarray(mesh.faces, dtype=np.int64).reshape(-1, 3)
    accessors = {"POSITION": accessor_fields(positions, 5126, False, True)}
    for name, values in decoded.items():
        if name == "POSITION":
            continue
        if name.startswith("COLOR_"):
            accessors[name] = accessor_fields(values, 5121, True, False)
        elif name.startswith("JOINTS_"):
            accessors[name] = accessor_fields(values, 5123, False, False)
        else:
            accessors[name] = accessor_fields(values, 5126, False, False)
    accessors["indices"] = {
        "count": int(triangles.size),
        "componentType": index_component(len(positions)),
        "type": "SCALAR",
    }
    return PrimitiveEncoding(
        size_bits=8 * len(data),
        vertices=positions,
        faces=triangles,
        accessors=accessors,
        draco=data,
        draco_ids=ids,
    )


def _decoded_attributes(
    mesh: Any, uv_name: str | None, color_name: str | None
) -> tuple[dict[str, int], dict[str, np.ndarray]]:
    """A decoded Draco primitive's attributes by glTF name (its generic attributes by
    their own names; ``uv_name`` and ``color_name`` the sets Draco stored as its own
    texture coordinates and colours): their Draco ids, and their decoded values."""
    ids: dict[str, int] = {}
    decoded: dict[str, np.ndarray] = {}
    for attribute in mesh.attributes:
        kind, name = attribute["attribute_type"], attribute["name"]
        glname = (
            {0: "POSITION", 1: "NORMAL", 2: color_name, 3: uv_name}.get(kind) if kind != 4 else name
        )
        if glname is None:
            continue
        ids[glname] = int(attribute["unique_id"])
        decoded[glname] = np.asarray(attribute["data"])
    return ids, decoded
