"""Draco files (``.drc``): a mesh compressed with Draco, as ``meshbits compress -o x.drc``
writes it, read back through the Draco codec (DracoPy)."""

from __future__ import annotations

import numpy as np

from ..encode import decode_draco
from ..errors import MeshFileError

__all__ = ["read_drc"]


def read_drc(data: bytes, name: object) -> tuple[np.ndarray, np.ndarray]:
    """A Draco file's mesh, ``(vertices float64 (n, 3), faces int64 (m, 3))``; a file
    that is not a triangle mesh is refused naming ``name``."""
    try:
        return decode_draco(data)
    except MeshFileError as err:
        raise MeshFileError(f"{name}: {err}") from None
