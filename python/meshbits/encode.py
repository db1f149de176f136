"""Real compressed output: Draco (through DracoPy), quantized glTF (GLB with
KHR_mesh_quantization, through pygltflib) and quantized PLY, with measured sizes.

The model's file size ``F = (3 alpha B + T) V`` (paper Eq. 1) is only as good as its alpha
and T: :func:`fit_size_model` fits them to measured encodings, and :func:`calibrate` runs
such encodings on a mesh, so that later plans predict real bytes.
"""

from __future__ import annotations

import contextlib
import functools
import math
import os
import sys
import threading
from collections.abc import Iterator, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .constants import FORMAT_MAX_BITS
from .errors import MeshbitsError, MeshFileError
from .files import write_atomic
from .mesh import MeshLike, all_faces_degenerate, as_mesh, compact
from .quantize import cube_grid, quantize
from .results import ArrayResult

__all__ = [
    "ENCODERS",
    "Encoded",
    "SizeModelFit",
    "decode_draco",
    "draco_codes",
    "encode",
    "encode_draco",
    "encode_quantized_glb",
    "encode_quantized_ply",
    "fit_size_model",
    "fixed_width_size_bits",
]

#: Output formats by file extension.
ENCODERS = {".drc": "draco", ".glb": "glb", ".ply": "ply"}


@dataclass(frozen=True, eq=False)
class Encoded(ArrayResult):
    """One encoded mesh and what a decoder gets back from it.

    Attributes
    ----------
    format : str
        ``"draco"``, ``"glb"`` or ``"ply"``.
    data : bytes
        The file's bytes.
    bits : int
        Bits per coordinate B.
    vertices, faces : ndarray
        The decoded mesh (float64 positions in the input's units, int64 faces): what a
        reader of the file sees, and what the error is measured on.
    codes : ndarray, shape (n, 3), uint32
        The integer grid code of each decoded vertex: for glb and ply the quantizer's own,
        exactly what the file stores; for Draco the nearest code of each decoded position
        (:func:`draco_codes` says when that is Draco's).
    """

    format: str
    data: bytes = field(repr=False)
    bits: int
    vertices: np.ndarray = field(repr=False)
    faces: np.ndarray = field(repr=False)
    codes: np.ndarray = field(repr=False)

    @property
    def size_bytes(self) -> int:
        return len(self.data)

    @property
    def size_bits(self) -> int:
        return 8 * len(self.data)

    def to_dict(self, *, arrays: bool = False) -> dict[str, Any]:
        """JSON-ready dict: format, bits, size and counts (with ``arrays=True``, also the
        decoded vertices and faces; never the bytes)."""
        out: dict[str, Any] = {
            "format": self.format,
            "bits": self.bits,
            "size_bytes": self.size_bytes,
            "size_bits": self.size_bits,
            "vertex_count": len(self.vertices),
            "face_count": len(self.faces),
        }
        if arrays:
            out |= {"vertices": self.vertices.tolist(), "faces": self.faces.tolist()}
        return out

    def write(self, path: str | Path) -> Path:
        """Write the file's bytes atomically (see :func:`meshbits.files.write_atomic`)."""
        return write_atomic(Path(path), self.data)


#: Largest float32: Draco, glTF and PLY store positions (and Draco its grid) in float32.
FLOAT32_MAX = float(np.finfo(np.float32).max)


def _grid(vertices: np.ndarray, origin: Any, grid_size: Any) -> tuple[np.ndarray, float]:
    """The cube grid at ``origin`` (default: the vertices' min corner) with side
    ``grid_size`` (default: the smallest that holds the vertices); refused when it or the
    vertices reach beyond float32's range (DracoPy crashed the process on such a mesh)."""
    lo = vertices.min(axis=0) if origin is None else np.asarray(origin, dtype=np.float64)
    if grid_size is None:
        lo, size = cube_grid(lo, np.maximum(vertices.max(axis=0), lo))
    else:
        size = float(grid_size)
    reach = max(float(np.abs(vertices).max(initial=0.0)), float(np.abs(lo).max()) + size)
    if not reach <= FLOAT32_MAX:
        raise MeshbitsError(
            f"coordinates reach {reach:.4g}: beyond float32's range ({FLOAT32_MAX:.4g}), in "
            "which Draco, glTF and PLY store positions"
        )
    return lo, size


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


def _check_bits(bits: int, high: int) -> int:
    if not isinstance(bits, (int, np.integer)) or not 1 <= bits <= high:
        raise MeshbitsError(f"bits must be an integer from 1 to {high}, got {bits!r}")
    return int(bits)


def decode_draco(data: bytes) -> tuple[np.ndarray, np.ndarray]:
    """Decode a Draco buffer to ``(vertices float64 (n, 3), faces int64 (m, 3))``."""
    import DracoPy

    mesh = DracoPy.decode(data)
    points = np.asarray(mesh.points, dtype=np.float64).reshape(-1, 3)
    if not hasattr(mesh, "faces"):
        raise MeshFileError(
            f"it is a Draco point cloud ({len(points):,} points, no faces): it holds no "
            "triangle mesh"
        )
    return points, np.asarray(mesh.faces, dtype=np.int64).reshape(-1, 3)


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
    bits = _check_bits(bits, FORMAT_MAX_BITS["draco"])
    lo, size = _grid(vertices, origin, grid_size)
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


def encode_quantized_ply(
    mesh: MeshLike, bits: int, *, origin: Any = None, grid_size: float | None = None
) -> Encoded:
    """Binary PLY with positions quantized to ``bits`` on the cube grid (by
    :func:`meshbits.quantize`) and stored as dequantised float32 (what any PLY reader
    accepts); unreferenced vertices dropped."""
    vertices, faces = as_mesh(mesh)
    bits = _check_bits(bits, FORMAT_MAX_BITS["ply"])
    vertices, faces = compact(vertices, faces)
    lo, size = _grid(vertices, origin, grid_size)
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
    import pygltflib as gl

    vertices, faces = as_mesh(mesh)
    bits = _check_bits(bits, FORMAT_MAX_BITS["glb"])
    vertices, faces = compact(vertices, faces)
    lo, size = _grid(vertices, origin, grid_size)
    q = quantize(vertices, bits, box=(lo, lo + size))
    codes = np.asarray(q.codes, dtype=np.uint16)
    if bits <= 8:
        component, stride = gl.UNSIGNED_BYTE, 4
        packed = np.zeros((len(codes), 4), dtype=np.uint8)
    else:
        component, stride = gl.UNSIGNED_SHORT, 8
        packed = np.zeros((len(codes), 4), dtype="<u2")
    packed[:, :3] = codes
    if len(codes) < 65536:
        index_component, indices = gl.UNSIGNED_SHORT, faces.astype("<u2").tobytes()
    else:
        index_component, indices = gl.UNSIGNED_INT, faces.astype("<u4").tobytes()
    index_data, position_data = _padded(indices), packed.tobytes()
    step = float(q.step[0])
    gltf = gl.GLTF2(
        asset=gl.Asset(generator=f"meshbits, {bits} bits per coordinate"),
        extensionsUsed=["KHR_mesh_quantization"],
        extensionsRequired=["KHR_mesh_quantization"],
        scene=0,
        scenes=[gl.Scene(nodes=[0])],
        nodes=[gl.Node(mesh=0, translation=[float(x) for x in lo], scale=[step, step, step])],
        meshes=[
            gl.Mesh(primitives=[gl.Primitive(attributes=gl.Attributes(POSITION=1), indices=0)])
        ],
        accessors=[
            gl.Accessor(
                bufferView=0,
                componentType=index_component,
                count=faces.size,
                type=gl.SCALAR,
                min=[int(faces.min())],
                max=[int(faces.max())],
            ),
            gl.Accessor(
                bufferView=1,
                componentType=component,
                count=len(codes),
                type=gl.VEC3,
                min=[int(x) for x in codes.min(axis=0)],
                max=[int(x) for x in codes.max(axis=0)],
            ),
        ],
        bufferViews=[
            gl.BufferView(
                buffer=0,
                byteOffset=0,
                byteLength=len(indices),
                target=gl.ELEMENT_ARRAY_BUFFER,
            ),
            gl.BufferView(
                buffer=0,
                byteOffset=len(index_data),
                byteLength=len(position_data),
                byteStride=stride,
                target=gl.ARRAY_BUFFER,
            ),
        ],
        buffers=[gl.Buffer(byteLength=len(index_data) + len(position_data))],
    )
    gltf.set_binary_blob(index_data + position_data)
    data = b"".join(gltf.save_to_bytes())
    decoded = lo + step * codes.astype(np.float64)
    return Encoded(
        "glb",
        data,
        bits,
        decoded.astype(np.float64),
        faces.astype(np.int64),
        codes.astype(np.uint32),
    )


def encode(mesh: MeshLike, bits: int, *, format: str = "draco", **grid: Any) -> Encoded:
    """Encode in ``format``: ``"draco"``, ``"glb"`` (quantized glTF) or ``"ply"``."""
    if format == "draco":
        return encode_draco(mesh, bits, **grid)
    if format == "glb":
        return encode_quantized_glb(mesh, bits, **grid)
    if format == "ply":
        return encode_quantized_ply(mesh, bits, **grid)
    raise MeshbitsError(f"format must be 'draco', 'glb' or 'ply', got {format!r}")


def fixed_width_size_bits(format: str, bits: int, vertices: float, faces: float) -> float:
    """Size in bits of :func:`encode` in a fixed-width ``format`` (``"glb"`` or ``"ply"``)
    for a mesh of ``vertices`` referenced vertices and ``faces`` triangles.

    These formats store every vertex and face in a fixed number of bytes, so the size is
    ``header + V * vertex_bytes + F * face_bytes`` and depends on ``B`` only through the
    component type: glb positions take 4 bytes (``B <= 8``) or 8 (``B <= 16``) per vertex
    and its indices 2 bytes per corner below 65,536 vertices, else 4; ply takes 12 bytes
    per vertex (float32) and 13 per face. The header is measured by encoding a
    tetrahedron in the format; the JSON numbers of a real header (its box, translation and
    scale) make it up to about 100 bytes longer or shorter.
    """
    bits = _check_bits(bits, FORMAT_MAX_BITS.get(format, 0) or 1)
    if format not in ("glb", "ply"):
        raise MeshbitsError(f"format must be 'glb' or 'ply' (fixed width), got {format!r}")
    vertex_bytes, face_bytes = _fixed_width_record(format, bits, vertices)
    return 8.0 * (_fixed_width_header(format, bits) + vertices * vertex_bytes + faces * face_bytes)


def _fixed_width_record(format: str, bits: int, vertices: float) -> tuple[int, int]:
    if format == "ply":
        return 12, 13
    return (4 if bits <= 8 else 8), 3 * (2 if vertices < 65536 else 4)


@functools.lru_cache(maxsize=64)
def _fixed_width_header(format: str, bits: int) -> int:
    tetrahedron = (
        np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]),
        np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]),
    )
    encoded = encode(tetrahedron, bits, format=format)
    vertex_bytes, face_bytes = _fixed_width_record(format, bits, 4)
    payload = 4 * vertex_bytes + len(_padded(b"\0" * (4 * face_bytes)))
    if format == "ply":
        payload = 4 * vertex_bytes + 4 * face_bytes
    return encoded.size_bits // 8 - payload


@dataclass(frozen=True)
class SizeModelFit:
    """Least-squares fit of ``F = (3 alpha B + T) V`` (paper Eq. 1) to measured sizes.

    Attributes
    ----------
    alpha : float
        Compression factor on coordinates (dimensionless).
    connectivity_bits : float
        T, bits per vertex for everything that is not coordinates (bits).
    relative_rms : float
        RMS of (predicted - measured) / measured over the samples.
    samples : int
    """

    alpha: float
    connectivity_bits: float
    relative_rms: float
    samples: int

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def fit_size_model(
    bits: Sequence[float], vertices: Sequence[float], size_bits: Sequence[float]
) -> SizeModelFit:
    """Fit alpha and T of Eq. 1 to measured sizes, weighting each sample by 1/size so the
    fit minimises relative error, under the model's constraint T >= 0. Needs samples at
    two or more distinct B."""
    b = np.asarray(bits, dtype=np.float64)
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(size_bits, dtype=np.float64)
    if not (b.shape == v.shape == f.shape) or b.ndim != 1:
        raise MeshbitsError("bits, vertices and size_bits must be 1-D and of equal length")
    if len(np.unique(b)) < 2:
        raise MeshbitsError("fitting alpha and T needs sizes measured at two or more bit depths")
    design = np.column_stack([3 * b * v, v]) / f[:, None]
    (alpha, t), *_ = np.linalg.lstsq(design, np.ones_like(f), rcond=None)
    if t < 0:
        # The model needs T >= 0: the best fit then lies on T = 0.
        t = 0.0
        alpha = float(design[:, 0].sum() / (design[:, 0] ** 2).sum())
    predicted = (3 * alpha * b + t) * v
    rms = float(np.sqrt(np.mean(((predicted - f) / f) ** 2)))
    return SizeModelFit(float(alpha), float(t), rms, len(f))
