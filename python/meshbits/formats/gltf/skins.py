"""Skins in a rebuilt document: a skinned mesh's positions stored as integer codes ``c``
in a frame ``D: c -> origin + step * c`` (mesh units) have ``D`` folded into the inverse
bind matrices of the skins that pose it (``IBM_j @ D``, float32), since a skinned mesh
ignores its node's transform (glTF 2.0, 3.7.3); gltfpack's ``writeJointBindMatrices``
does the same with its one scene-wide grid.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ...errors import MeshbitsError
from .document import Document

__all__ = ["folded_matrices", "inverse_bind_matrices", "skin_frames"]

#: A frame: ``(origin (3,), step)`` placing stored positions in mesh units.
Frame = tuple[np.ndarray, float]


def inverse_bind_matrices(document: Document, skin: int) -> np.ndarray:
    """A skin's inverse bind matrices, ``(joints, 4, 4)`` float64 (identities when the
    skin has none)."""
    spec = document.json["skins"][skin]
    joints = len(spec.get("joints", []))
    if spec.get("inverseBindMatrices") is None:
        return np.broadcast_to(np.eye(4), (joints, 4, 4)).copy()
    values = document.accessor(spec["inverseBindMatrices"]).astype(np.float64)
    # Accessors store matrices column by column.
    return values.reshape(-1, 4, 4).transpose(0, 2, 1)[:joints]


def folded_matrices(ibm: np.ndarray, origin: np.ndarray, step: float) -> np.ndarray:
    """``IBM_j @ D`` for every joint (float64), ``D`` the dequantization
    ``c -> origin + step * c``."""
    d = np.eye(4)
    d[:3, :3] *= step
    d[:3, 3] = origin
    return ibm @ d


def skin_frames(document: Document, frames: dict[int, Frame]) -> dict[int, Frame]:
    """The frames of skinned meshes taken out of ``frames`` (``mesh -> frame``) and
    returned by skin (``skin -> frame``): every node showing such a mesh has a skin, and
    every mesh a skin poses has the same frame (the scene planned them so: one grid per
    skin). Refused otherwise, in one line (a planning error, not the input's)."""
    by_skin: dict[int, Frame] = {}
    skinned: set[int] = set()
    plain: set[int] = set()
    for node in document.json.get("nodes", []):
        mesh = node.get("mesh")
        if mesh is None:
            continue
        (skinned if node.get("skin") is not None else plain).add(int(mesh))
    for mesh in skinned & set(frames):
        if mesh in plain:
            raise MeshbitsError(f"mesh {mesh} is shown with and without a skin: no one frame")
    for node in document.json.get("nodes", []):
        mesh, skin = node.get("mesh"), node.get("skin")
        if mesh is None or skin is None:
            continue
        frame = frames.get(int(mesh))
        known = by_skin.get(int(skin))
        if frame is None:
            if known is not None:
                raise MeshbitsError(f"skin {skin} poses meshes with and without a frame")
            continue
        if known is not None and not _same(known, frame):
            raise MeshbitsError(f"skin {skin} poses meshes stored on different grids")
        by_skin[int(skin)] = frame
    for mesh in skinned:
        frames.pop(mesh, None)
    return by_skin


def _same(a: Frame, b: Frame) -> bool:
    return bool(np.array_equal(a[0], b[0])) and a[1] == b[1]


def folded_matrix_bytes(
    document: Document, skin: int, frame: Frame
) -> tuple[bytes, dict[str, Any]]:
    """The bytes (float32, column-major MAT4) of a skin's inverse bind matrices with
    ``frame`` folded in, and their accessor's fields (no bufferView yet)."""
    folded = folded_matrices(inverse_bind_matrices(document, skin), *frame)
    stored = np.ascontiguousarray(folded.transpose(0, 2, 1).astype(np.float32))
    accessor = {"componentType": 5126, "count": len(stored), "type": "MAT4"}
    return stored.tobytes(), accessor
