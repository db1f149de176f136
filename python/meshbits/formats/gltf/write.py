"""Writing glTF files: a mesh as a text glTF with its buffer beside it, and where to put
the origin of positions stored in float32.

This is the writer of ``save_mesh``; the scene commands still write their documents with
the writer in :mod:`meshbits.scene`, which a later step moves here.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ...files import write_atomic

__all__ = ["FRAME_DISTANCE", "frame_centre", "gltf_files", "json_number", "write_gltf"]

#: A mesh whose box centre is farther from the origin than this many times its largest
#: side is stored relative to that centre (:func:`frame_centre`): there float32 rounds a
#: position by up to 1e-6 of the side, a sixteenth of a grid step at 18 bits.
FRAME_DISTANCE = 16.0


def frame_centre(points: np.ndarray) -> np.ndarray:
    """Where to put the origin of positions stored in float32 (mesh units): the centre of
    the points' box, rounded to the power of two at or above its largest side (a short
    number in the JSON; the positions stay within 1.5 sides of it), when that centre is
    farther from the origin than :data:`FRAME_DISTANCE` sides; else the origin itself."""
    if len(points) == 0:
        return np.zeros(3)
    lo, hi = points.min(axis=0), points.max(axis=0)
    extent = float((hi - lo).max())
    centre = (lo + hi) / 2
    if not np.abs(centre).max() > FRAME_DISTANCE * extent:
        return np.zeros(3)
    if extent > 0:
        unit = 2.0 ** math.ceil(math.log2(extent))
        centre = np.round(centre / unit) * unit
    return centre


def json_number(value: float) -> float | int:
    """A float64 as JSON writes it shortest and exactly: an integral value as an integer
    (``420000`` for ``420000.0``; ``0`` for ``-0.0``)."""
    value = float(value)
    if value.is_integer() and abs(value) < 2**53:
        return int(value)
    return value


def gltf_files(mesh: object, path: Path) -> dict[str, bytes]:
    """A trimesh mesh as a text glTF and its binary buffers, by file name: the buffers
    named after the output (``mesh.gltf`` -> ``mesh.bin``), so that two outputs in one
    folder never share one."""
    # trimesh is imported on first use: it takes longer to import than meshbits.
    from trimesh.exchange.gltf import export_gltf

    files = export_gltf(mesh, merge_buffers=True)
    document = json.loads(files.pop("model.gltf"))
    renamed = {}
    buffers = document.get("buffers", [])
    for index, buffer in enumerate(buffers):
        name = f"{path.stem}.bin" if len(buffers) == 1 else f"{path.stem}_{index}.bin"
        renamed[name] = files.pop(buffer["uri"])
        buffer["uri"] = name
    renamed[path.name] = json.dumps(document).encode()
    return renamed


def write_gltf(path: Path, mesh: object) -> Path:
    """Write a trimesh mesh as ``path`` (a ``.gltf``) and its buffers beside it, each
    atomically (:func:`gltf_files`); the buffers are written first."""
    files = gltf_files(mesh, path)
    document = files.pop(path.name)
    for name, data in files.items():
        write_atomic(path.with_name(name), data)
    return write_atomic(path, document)
