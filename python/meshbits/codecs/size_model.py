"""The size model of a mesh encoder: the paper's file size ``F = (3 alpha B + T) V``
(Eq. 1) is only as good as its alpha and T; :func:`fit_size_model` fits them to measured
encodings, so that later plans predict real bytes."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from ..errors import MeshbitsError

__all__ = ["SizeModelFit", "fit_size_model"]


@dataclass(frozen=True)
class SizeModelFit:
    """Least-squares fit of ``F = (3 alpha B + T) V`` (paper Eq. 1) to measured sizes.

    Attributes
    ----------
    alpha : float
        Compression factor on coordinates (dimensionless).
    connectivity_bits : float
        T, bits per vertex for everything that is not coordinates (bits).
    relative_rms : float
        RMS of (predicted - measured) / measured over the samples.
    samples : int
    """

    alpha: float
    connectivity_bits: float
    relative_rms: float
    samples: int

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def fit_size_model(
    bits: Sequence[float], vertices: Sequence[float], size_bits: Sequence[float]
) -> SizeModelFit:
    """Fit alpha and T of Eq. 1 to measured sizes, weighting each sample by 1/size so the
    fit minimises relative error, under the model's constraint T >= 0. Needs samples at
    two or more distinct B."""
    b = np.asarray(bits, dtype=np.float64)
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(size_bits, dtype=np.float64)
    if not (b.shape == v.shape == f.shape) or b.ndim != 1:
        raise MeshbitsError("bits, vertices and size_bits must be 1-D and of equal length")
    if len(np.unique(b)) < 2:
        raise MeshbitsError("fitting alpha and T needs sizes measured at two or more bit depths")
    design = np.column_stack([3 * b * v, v]) / f[:, None]
    (alpha, t), *_ = np.linalg.lstsq(design, np.ones_like(f), rcond=None)
    if t < 0:
        # The model needs T >= 0: the best fit then lies on T = 0.
        t = 0.0
        alpha = float(design[:, 0].sum() / (design[:, 0] ** 2).sum())
    predicted = (3 * alpha * b + t) * v
    rms = float(np.sqrt(np.mean(((predicted - f) / f) ** 2)))
    return SizeModelFit(float(alpha), float(t), rms, len(f))
