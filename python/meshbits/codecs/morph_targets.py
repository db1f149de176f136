"""Morph targets under ``KHR_mesh_quantization``: each target's displacements rounded and
stored as its streams (:func:`target_rows`), and the certified bound on how far the
morphed primitive moves at any weights (:func:`morph_bound`).

A morphed vertex is ``v + sum_i w_i d_i`` (glTF 2.0, 3.7.2.2). Positions are stored on a
grid of step ``s`` (integer codes, or float32 values on it); position displacements are
rounded to whole steps, as gltfpack does, and stored in the units of the positions: signed
bytes or shorts of steps (the node or skin scales them with the positions), or float32.
Normal and tangent displacements are rounded to the normals' bits, as normalized signed
bytes or shorts when they lie within [-1, 1], float32 otherwise. Other target attributes
(``TEXCOORD_n``, ``COLOR_n``) are stored as float32 as they were.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..formats.gltf.spec import COMPONENT_TYPES
from .primitive import accessor_fields

__all__ = ["EXACT_CORNERS_UP_TO", "TargetRows", "morph_bound", "target_rows"]

#: With at most this many targets, :func:`morph_bound` takes the largest error over every
#: corner of the weight cube (2^T of them); with more, the triangle inequality's sum.
EXACT_CORNERS_UP_TO = 10

#: One stream to write: ``(attribute name, rows to store, accessor fields)``.
TargetRows = tuple[str, np.ndarray, dict[str, Any]]


def _position_rows(
    deltas: np.ndarray, step: float, integer: bool
) -> tuple[np.ndarray, dict[str, Any], np.ndarray]:
    """Position displacements rounded to whole steps: the rows stored, their accessor
    fields (with min and max, which glTF requires of a target's positions), and the
    displacements a reader gets back (mesh units)."""
    steps = np.round(deltas / step) if step > 0 else np.zeros_like(deltas)
    largest = float(np.abs(steps).max()) if steps.size else 0.0
    if integer and largest <= 32767:
        dtype = np.int8 if largest <= 127 else np.int16
        stored = steps.astype(dtype)
        fields = accessor_fields(stored, COMPONENT_TYPES[np.dtype(dtype)], False, True)
        return stored, fields, stored.astype(np.float64) * step
    # Float32: in steps when the positions are integer codes (beyond a short's range),
    # else in mesh units.
    values = steps if integer else steps * step
    stored = values.astype(np.float32)
    decoded = stored.astype(np.float64) * (step if integer else 1.0)
    return stored, accessor_fields(stored, 5126, False, True), decoded


def _direction_rows(deltas: np.ndarray, bits: int) -> tuple[np.ndarray, dict[str, Any]]:
    """Normal or tangent displacements rounded to ``bits`` (steps of ``1 / (2^(bits-1) -
    1)``): normalized signed bytes (up to 8 bits) or shorts within [-1, 1], else
    float32."""
    levels = 2 ** (bits - 1) - 1
    steps = np.round(deltas[:, :3] * levels)
    if steps.size == 0 or np.abs(steps).max() <= levels:
        if bits <= 8:
            stored = steps.astype(np.int8)
        else:
            stored = np.round(steps * (32767 / levels)).astype(np.int16)
        return stored, accessor_fields(stored, COMPONENT_TYPES[stored.dtype], True, False)
    stored = (steps / levels).astype(np.float32)
    return stored, accessor_fields(stored, 5126, False, False)


def target_rows(
    targets: list[dict[str, np.ndarray]],
    order: np.ndarray,
    step: float,
    integer: bool,
    normal_bits: int,
) -> tuple[list[list[TargetRows]], list[np.ndarray]]:
    """Every target's streams to write (its vertices taken in ``order``), and each
    target's decoded position displacements (mesh units, zeros without ``POSITION``)."""
    rows: list[list[TargetRows]] = []
    decoded: list[np.ndarray] = []
    for target in targets:
        streams: list[TargetRows] = []
        moved = np.zeros((len(order), 3))
        for name, values in target.items():
            values = np.asarray(values, dtype=np.float64)[order]
            if name == "POSITION":
                stored, fields, moved = _position_rows(values, step, integer)
            elif name in ("NORMAL", "TANGENT"):
                stored, fields = _direction_rows(values, normal_bits)
            else:
                stored = values.astype(np.float32)
                fields = accessor_fields(stored, 5126, False, False)
            streams.append((name, stored, fields))
        rows.append(streams)
        decoded.append(moved)
    return rows, decoded


def morph_bound(base_error: np.ndarray, delta_errors: list[np.ndarray], chunk: int = 4096) -> float:
    """The largest distance between a decoded and an input vertex at any weights in
    [0, 1] per target: the error ``e_0 + sum_i w_i e_i`` (``base_error`` e_0 and
    ``delta_errors`` e_i, ``(n, 3)`` each) is affine in the weights, so its length is
    largest at a corner of the weight cube; with up to :data:`EXACT_CORNERS_UP_TO`
    targets every corner is measured, beyond, ``|e_0| + sum_i |e_i|`` bounds it. The two
    meshes have the same triangles, so this bounds their Hausdorff distance at those
    weights."""
    base = np.asarray(base_error, dtype=np.float64)
    if not delta_errors:
        return float(np.linalg.norm(base, axis=1).max(initial=0.0))
    errors = np.stack([np.asarray(e, dtype=np.float64) for e in delta_errors])
    if len(errors) > EXACT_CORNERS_UP_TO:
        total = np.linalg.norm(base, axis=1) + np.linalg.norm(errors, axis=2).sum(axis=0)
        return float(total.max(initial=0.0))
    corners = (np.arange(2 ** len(errors))[:, None] >> np.arange(len(errors))) & 1
    largest = 0.0
    moving = np.flatnonzero(np.abs(errors).max(axis=(0, 2)) > 0)
    still = np.setdiff1d(np.arange(len(base)), moving)
    if len(still):
        largest = float(np.linalg.norm(base[still], axis=1).max())
    for start in range(0, len(moving), chunk):
        rows = moving[start : start + chunk]
        # (corners, rows, 3): e_0 plus the errors of the targets at weight 1.
        error = base[rows][None] + np.einsum("ct,trk->crk", corners, errors[:, rows])
        largest = max(largest, float(np.linalg.norm(error, axis=2).max()))
    return largest
