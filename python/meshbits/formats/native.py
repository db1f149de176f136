"""The Rust readers: PLY, STL and OBJ files read through a memory map, in parallel,
straight into the arrays the kernels take (``float64 (n, 3)`` vertices, ``uint32 (m, 3)``
faces), with no int64 or other intermediate copy (see docs/large.md).

A file the Rust reader does not read exactly as trimesh would (a layout it does not
handle, or damage of any kind: a short or long row, a NaN coordinate, an index out of
range) is left to the general path of :func:`meshbits.formats.open.load_mesh` (the header
checks, then trimesh), whose messages then name the problem: :func:`read_native` returns
``None`` for it and logs the reason at debug level (logger ``meshbits.formats``).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import _core
from ..errors import MeshFileError

__all__ = ["NATIVE_FORMATS", "MeshRead", "read_native"]

#: The formats the Rust readers read (uncompressed files only).
NATIVE_FORMATS = ("ply", "stl", "obj")

LOG = logging.getLogger("meshbits.formats")


@dataclass(frozen=True, eq=False)
class MeshRead:
    """A mesh file as :func:`meshbits.formats.open.read_mesh` read it.

    Attributes
    ----------
    vertices : ndarray
        ``float64 (n, 3)``, the file's coordinates widened exactly, in file order (an
        STL's three corners per triangle, as trimesh reads it; the kernels weld).
    faces : ndarray
        ``uint32 (m, 3)`` vertex indices from 0; a polygon's fan in its place.
    reader : str
        ``"meshbits"`` (the Rust reader) or ``"trimesh"`` (the general reader, which
        reads the other formats and the files the Rust reader leaves to it).
    polygons : int or None
        Faces of more than three corners, fan-triangulated (``a b c d`` gives ``a b c``
        and ``a c d``); ``None`` when trimesh read the file (it does not say).
    polygon_triangles : int or None
        The triangles those polygons became.
    skipped_elements : int or None
        OBJ line (``l``) and point (``p``) elements left out.
    """

    vertices: np.ndarray
    faces: np.ndarray
    reader: str
    polygons: int | None = None
    polygon_triangles: int | None = None
    skipped_elements: int | None = None


def read_native(path: Path, file_type: str) -> MeshRead | None:
    """Read ``path`` (of format ``file_type``, one of :data:`NATIVE_FORMATS`, not
    compressed) with the Rust reader; ``None`` when the file is left to the general
    reader.

    Raises
    ------
    MeshFileError
        The file cannot be opened or mapped (naming the file and the system's reason).
    """
    try:
        outcome = _core.read_mesh(str(path), file_type)
    except OSError as err:
        raise MeshFileError(f"cannot read {path}: {err.strerror or err}") from None
    if isinstance(outcome, str):
        LOG.debug("%s: left to the general reader (%s)", path, outcome)
        return None
    vertices, faces, counts = outcome
    return MeshRead(vertices, faces, "meshbits", **counts)
