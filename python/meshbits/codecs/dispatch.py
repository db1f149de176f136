"""A mesh encoded in the format named: :func:`encode` hands it to that format's
encoder."""

from __future__ import annotations

from typing import Any

from ..errors import MeshbitsError
from ..mesh import MeshLike
from .draco import encode_draco
from .encoded import Encoded
from .fixed_width import encode_quantized_glb, encode_quantized_ply

__all__ = ["encode"]


def encode(mesh: MeshLike, bits: int, *, format: str = "draco", **grid: Any) -> Encoded:
    """Encode in ``format``: ``"draco"``, ``"glb"`` (quantized glTF) or ``"ply"``."""
    if format == "draco":
        return encode_draco(mesh, bits, **grid)
    if format == "glb":
        return encode_quantized_glb(mesh, bits, **grid)
    if format == "ply":
        return encode_quantized_ply(mesh, bits, **grid)
    raise MeshbitsError(f"format must be 'draco', 'glb' or 'ply', got {format!r}")
