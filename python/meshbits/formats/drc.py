"""Draco files (``.drc``): a mesh compressed with Draco, as ``meshbits compress -o x.drc``
writes it, read back through the Draco codec (DracoPy); :func:`decode_draco` is also how
the Draco encoders of :mod:`meshbits.codecs.draco` see what they wrote."""

from __future__ import annotations

import numpy as np

from ..errors import MeshFileError

__all__ = ["decode_draco", "read_drc"]


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


def read_drc(data: bytes, name: object) -> tuple[np.ndarray, np.ndarray]:
    """A Draco file's mesh, ``(vertices float64 (n, 3), faces int64 (m, 3))``; a file
    that is not a triangle mesh is refused naming ``name``."""
    try:
        return decode_draco(data)
    except MeshFileError as err:
        raise MeshFileError(f"{name}: {err}") from None
