"""Bits per attribute: how finely a primitive's attributes other than its positions are
quantized, each from its own tolerance: normals and tangents (octahedral, within an
angle), texture coordinates (within half a texel of the largest texture bound to them),
colours and skin weights (a byte a component). Also meshoptimizer's simplification
weights, which price each attribute's tolerance against the position error budget."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = [
    "COLOR_BITS",
    "DEFAULT_UV_BITS",
    "NORMAL_TOLERANCE_DEGREES",
    "WEIGHT_BITS",
    "AttributeBits",
    "attribute_weights",
    "in_unit_square",
    "normal_bits",
    "uv_bits",
]

#: Largest angle (degrees) between a normal or tangent and its quantized value.
NORMAL_TOLERANCE_DEGREES = 1.0

#: UV bits when no texture tells the texel size: gltfpack's default.
DEFAULT_UV_BITS = 12

#: Bits of colours and skin weights (one byte a component).
COLOR_BITS = WEIGHT_BITS = 8


def _octahedral_round_trip(vectors: np.ndarray, bits: int) -> np.ndarray:
    """Unit vectors through the octahedral map quantized to signed ``bits``-bit
    components, and back."""
    v = vectors / np.maximum(np.abs(vectors).sum(axis=1, keepdims=True), 1e-30)
    x, y, z = v[:, 0], v[:, 1], v[:, 2]
    folded_x = np.where(z < 0, (1 - np.abs(y)) * np.sign(np.where(x == 0, 1, x)), x)
    folded_y = np.where(z < 0, (1 - np.abs(x)) * np.sign(np.where(y == 0, 1, y)), y)
    scale = float(2 ** (bits - 1) - 1)
    qx, qy = np.round(folded_x * scale) / scale, np.round(folded_y * scale) / scale
    qz = 1 - np.abs(qx) - np.abs(qy)
    t = np.maximum(-qz, 0)
    qx = qx - np.sign(qx) * t
    qy = qy - np.sign(qy) * t
    out = np.stack([qx, qy, qz], axis=1)
    return out / np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-30)


def normal_bits(vectors: np.ndarray, tolerance_degrees: float = NORMAL_TOLERANCE_DEGREES) -> int:
    """The fewest octahedral bits (4 to 16) that keep every unit vector within
    ``tolerance_degrees`` of itself."""
    v = np.asarray(vectors, dtype=np.float64)[:, :3]
    length = np.linalg.norm(v, axis=1)
    v = v[length > 1e-12] / length[length > 1e-12, None]
    if len(v) == 0:
        return 8
    limit = math.cos(math.radians(tolerance_degrees))
    for bits in range(4, 17):
        if np.min(np.sum(v * _octahedral_round_trip(v, bits), axis=1)) >= limit:
            return bits
    return 16


def uv_bits(uv: np.ndarray, texels: int | None) -> int:
    """Bits for texture coordinates: the fewest that keep them within half a texel of the
    largest texture bound to them (``texels`` its largest side), 8 to 16, over their range,
    or over [0, 1] when they lie in it (meshopt stores them there as normalized shorts);
    :data:`DEFAULT_UV_BITS` without a texture."""
    if not texels or len(uv) == 0:
        return DEFAULT_UV_BITS
    extent = 1.0 if in_unit_square(uv) else float(np.ptp(uv, axis=0).max())
    if extent <= 0:
        return 8
    return int(min(max(math.ceil(math.log2(extent * texels + 1)), 8), 16))


def in_unit_square(uv: np.ndarray, slack: float = 0.0) -> bool:
    """Whether texture coordinates lie in [0, 1] (within ``slack``: simplification
    interpolates them)."""
    return len(uv) > 0 and uv.min() >= -slack and uv.max() <= 1.0 + slack


@dataclass(frozen=True)
class AttributeBits:
    """Bits of a primitive's other attributes: ``normal`` (octahedral, normals and
    tangents), ``uv`` per texture-coordinate set, ``color``, ``weight``."""

    normal: int
    uv: dict[str, int]
    color: int = COLOR_BITS
    weight: int = WEIGHT_BITS

    def finer(self, other: AttributeBits) -> AttributeBits:
        """The bits that keep both primitives of a shared geometry within their
        tolerances: the larger of each."""
        uv = {
            name: max(self.uv.get(name, 0), other.uv.get(name, 0)) for name in {*self.uv, *other.uv}
        }
        return AttributeBits(
            normal=max(self.normal, other.normal),
            uv=uv,
            color=max(self.color, other.color),
            weight=max(self.weight, other.weight),
        )


def attribute_weights(names: list[str], budget: float, bits: AttributeBits) -> dict[str, float]:
    """meshoptimizer's attribute weights: an attribute off by its own tolerance costs like
    a position off by the error budget."""
    weights = {}
    for name in names:
        if name in ("NORMAL", "TANGENT"):
            weights[name] = budget / math.sin(math.radians(NORMAL_TOLERANCE_DEGREES) * 4)
        elif name.startswith("TEXCOORD_"):
            weights[name] = budget * 2 ** bits.uv.get(name, DEFAULT_UV_BITS) / 4
        elif name.startswith("COLOR_"):
            weights[name] = budget * 32
        else:
            weights[name] = 0.0
    return weights
