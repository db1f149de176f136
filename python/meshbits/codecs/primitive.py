"""One glTF primitive encoded, whatever the codec: what a decoder gets back and what the
glTF writer needs (:class:`PrimitiveEncoding`), the one signature every primitive encoder
has (:class:`PrimitiveEncoder`), and the accessor fields and byte conversions the
encoders share."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from ..formats.gltf.spec import WIDTH_TYPES
from .attributes import AttributeBits

__all__ = [
    "PrimitiveEncoder",
    "PrimitiveEncoding",
    "accessor_fields",
    "index_component",
    "unit_u8",
    "weights_u8",
]


@dataclass
class PrimitiveEncoding:
    """One primitive encoded: its bytes, what a decoder gets back, and what the writer
    needs.

    Attributes
    ----------
    size_bits : int
        Bits of the compressed data.
    vertices, faces : ndarray
        The decoded positions (float64) and triangles: what is measured.
    accessors : dict
        ``name -> accessor fields`` (count, componentType, type, normalized, min/max).
    draco : bytes or None
        The Draco buffer, with ``draco_ids`` (glTF name -> Draco attribute id).
    streams : list of dict
        meshopt: per stream (``name``, ``data`` compressed, ``raw`` length, ``stride``,
        ``count``, ``mode``, ``filter``).
    dequantize : tuple or None
        meshopt: ``(origin, step)`` mapping integer position codes to mesh units.
    target_accessors : list of dict
        meshopt: each morph target's ``name -> accessor fields``.
    target_deltas : list of ndarray
        meshopt: each morph target's decoded ``POSITION`` displacements (mesh units, in
        the order of ``vertices``; zeros for a target without positions).
    morph_bound : float or None
        With morph targets: a certified bound (mesh units) on how far any vertex of the
        decoded primitive is from the input's at any weights in [0, 1] per target
        (:func:`meshbits.codecs.morph_targets.morph_bound`), which bounds the Hausdorff
        distance of the morphed meshes (same triangles, vertices moved at most that).
    """

    size_bits: int
    vertices: np.ndarray = field(repr=False)
    faces: np.ndarray = field(repr=False)
    accessors: dict[str, dict[str, Any]] = field(repr=False)
    draco: bytes | None = field(default=None, repr=False)
    draco_ids: dict[str, int] = field(default_factory=dict)
    streams: list[dict[str, Any]] = field(default_factory=list, repr=False)
    dequantize: tuple[np.ndarray, float] | None = None
    bits: int | None = None
    target_accessors: list[dict[str, dict[str, Any]]] = field(default_factory=list, repr=False)
    target_deltas: list[np.ndarray] = field(default_factory=list, repr=False)
    morph_bound: float | None = None

    @property
    def data(self) -> bytes:
        return self.draco or b"".join(s["data"] for s in self.streams)


class PrimitiveEncoder(Protocol):
    """A primitive encoder (:func:`meshbits.codecs.draco.encode_draco_primitive`,
    :func:`meshbits.codecs.quantized.encode_meshopt_primitive`): ``vertices`` (n, 3) and
    ``faces`` (m, 3) with their per-vertex ``attributes`` (glTF names), positions quantized
    to ``bits`` per coordinate on the cube grid at ``origin`` with side ``grid_size`` (mesh
    units), the other attributes at ``attribute_bits``."""

    def __call__(
        self,
        vertices: np.ndarray,
        faces: np.ndarray,
        attributes: dict[str, np.ndarray] | None,
        bits: int,
        origin: np.ndarray,
        grid_size: float,
        attribute_bits: AttributeBits,
        /,
    ) -> PrimitiveEncoding: ...


def index_component(count: int) -> int:
    """The glTF component type of indices into ``count`` vertices: unsigned shorts below
    65,536, else unsigned ints."""
    return 5123 if count < 65536 else 5125


def _float32_number(value: float) -> float:
    """A float32 value as the shortest decimal that reads back to it in float32 (at most
    9 digits, where its double expansion takes up to 17: an accessor's ``min`` and ``max``
    are float32 values)."""
    return float(str(np.float32(value)))


def accessor_fields(
    values: np.ndarray, component: int, normalized: bool, bounds: bool
) -> dict[str, Any]:
    """An accessor's glTF fields for ``values`` stored as ``component``: count,
    componentType, type, ``normalized`` when set, and with ``bounds`` the ``min`` and
    ``max`` (float32 values as their shortest decimals)."""
    width = values.shape[1] if values.ndim == 2 else 1
    out: dict[str, Any] = {
        "count": len(values),
        "componentType": component,
        "type": WIDTH_TYPES[width],
    }
    if normalized:
        out["normalized"] = True
    if bounds and len(values):
        cast = _float32_number if component == 5126 else int
        out["min"] = [cast(x) for x in np.min(values, axis=0).reshape(-1)]
        out["max"] = [cast(x) for x in np.max(values, axis=0).reshape(-1)]
    return out


def unit_u8(values: np.ndarray) -> np.ndarray:
    """Values in [0, 1] as normalized bytes (rounded, clipped)."""
    return np.clip(np.round(np.asarray(values) * 255.0), 0, 255).astype(np.uint8)


def weights_u8(weights: np.ndarray) -> np.ndarray:
    """Skin weights as bytes summing to 255 (the largest takes the rounding)."""
    w = unit_u8(weights).astype(np.int64)
    rows = np.arange(len(w))
    largest = np.argmax(w, axis=1)
    w[rows, largest] += 255 - w.sum(axis=1)
    return np.clip(w, 0, 255).astype(np.uint8)
