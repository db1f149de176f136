"""One mesh encoded: the result every mesh encoder returns (:class:`Encoded`), and the
checks they share, on the bits per coordinate and on the cube grid the positions are
quantized on (float32's range, in which Draco, glTF and PLY store positions)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import MeshbitsError
from ..files import write_atomic
from ..quantize import cube_grid
from ..results import ArrayResult

__all__ = ["FLOAT32_MAX", "Encoded", "check_bits", "encoding_grid"]


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


def encoding_grid(vertices: np.ndarray, origin: Any, grid_size: Any) -> tuple[np.ndarray, float]:
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


def check_bits(bits: int, high: int) -> int:
    """``bits`` as an int, refused unless it is an integer from 1 to ``high``."""
    if not isinstance(bits, (int, np.integer)) or not 1 <= bits <= high:
        raise MeshbitsError(f"bits must be an integer from 1 to {high}, got {bits!r}")
    return int(bits)
