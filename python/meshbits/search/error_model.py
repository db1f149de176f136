"""The error model of the search: what a (level, B) is predicted to measure, in closed
form, and what a measurement teaches the predictions.

- **Quantization error**: a mesh quantized to ``B`` bits on the cube grid of side ``S``
  measures ``E_Q(B) = c_Q S / (2^B - 1)`` from itself, ``c_Q`` =
  :data:`QUANTIZATION_FACTOR` (0.68-0.86 on the full-resolution bunny, horse, hand and
  fandisk at every ``B`` from 6 to 20; the bound is ``sqrt(3)/2 = 0.87``).
- **Combined error** of a level with tessellation error ``t`` quantized with ``E_Q = q``:
  ``max(t, q) (1 + delta min(t, q) / max(t, q))``, ``delta`` = :data:`COMBINE_DELTA`.
  The paper adds the two (``delta = 1``); measured, the larger one dominates (over 2,500
  (level, B) pairs of those four meshes, the measured error over this form has median
  0.98-1.00 and 90th percentile 1.02-1.06 with ``delta = 0.15``).
- **Tessellation error** of a level: inverted from its measurements once measured;
  before, meshoptimizer's own estimate times ``kappa``, the measured ratio of the nearest
  measured meshopt levels (:data:`KAPPA_PRIOR` before any: the ratio is 1.8-3 on the
  bunny, hand and horse, 2.6-6 on the CAD part fandisk).

Lengths are in mesh units, sizes in bits.
"""

from __future__ import annotations

import math

from .. import model
from ..constants import MODEL_MIN_BITS, MODEL_MIN_VERTICES

__all__ = [
    "COMBINE_DELTA",
    "KAPPA_PRIOR",
    "QUANTIZATION_FACTOR",
    "allowed_tessellation",
    "combined_error",
    "first_plan",
    "interaction",
    "interpolate",
    "learned",
    "paper_vertices",
    "quantization_error",
]

#: ``c_Q``: measured Hausdorff distance of a mesh to its own ``B``-bit quantization, in
#: steps ``S / (2^B - 1)`` (dimensionless).
QUANTIZATION_FACTOR = 0.81

#: ``delta`` of :func:`combined_error` (dimensionless).
COMBINE_DELTA = 0.15

#: Measured tessellation error over meshoptimizer's own estimate, before a level of the
#: mesh at hand is measured (dimensionless).
KAPPA_PRIOR = 2.5


def quantization_error(bits: int, grid_size: float) -> float:
    """``E_Q(B) = c_Q S / (2^B - 1)`` (length): see the module docs."""
    return QUANTIZATION_FACTOR * grid_size / (2.0**bits - 1.0)


def combined_error(tessellation: float, quantization: float, delta: float = COMBINE_DELTA) -> float:
    """Predicted Hausdorff error of a level with tessellation error ``t`` quantized with
    error ``q``: ``max(t, q) (1 + delta min/max)`` (length)."""
    high, low = max(tessellation, quantization), min(tessellation, quantization)
    return high if high <= 0 else high * (1.0 + delta * low / high)


def interaction(measured: float, tessellation: float, quantization: float) -> float:
    """The ``delta`` for which :func:`combined_error` gives ``measured``, within [0, 1]
    (0 when there is no smaller part to interact with)."""
    high, low = max(tessellation, quantization), min(tessellation, quantization)
    if low <= 0:
        return 0.0
    return float(min(max((measured - high) / low, 0.0), 1.0))


def allowed_tessellation(budget: float, quantization: float, delta: float = COMBINE_DELTA) -> float:
    """The largest ``t`` whose :func:`combined_error` with ``q`` stays within ``budget``;
    negative when quantization alone exceeds it."""
    if quantization >= budget:
        return -1.0
    if quantization * (1.0 + delta) >= budget:
        return (budget - quantization) / delta
    return budget - delta * quantization


def paper_vertices(k: float, grid_size: float, tessellation: float) -> float:
    """The paper's ``V = K S / (3 sqrt(3) E_T)`` (Eq. 18) at half the error (what
    meshoptimizer's levels measure on the bunny); symmetric, it also gives ``E_T`` from
    ``V``."""
    return 0.5 * k * grid_size / (3.0 * math.sqrt(3.0) * tessellation)


def first_plan(
    constraint: str,
    budget: float,
    k: float,
    *,
    grid_size: float,
    alpha: float,
    connectivity_bits: float,
) -> model.Allocation | None:
    """The paper's model's (B, V) for the budget, before any measurement; None when the
    model has no plan (a size budget below its smallest mesh, an error budget of a whole
    grid side or more)."""
    if constraint == "size":
        smallest = MODEL_MIN_VERTICES * (3.0 * alpha * MODEL_MIN_BITS + connectivity_bits)
        if budget < smallest:
            return None
        return model.plan_for_size(
            budget, k, grid_size=grid_size, alpha=alpha, connectivity_bits=connectivity_bits
        )
    if constraint == "error":
        if budget >= grid_size:
            return None
        return model.plan_for_error(
            budget, k, grid_size=grid_size, alpha=alpha, connectivity_bits=connectivity_bits
        )
    return model.plan_for_vertices(
        max(budget, MODEL_MIN_VERTICES),
        k,
        grid_size=grid_size,
        alpha=alpha,
        connectivity_bits=connectivity_bits,
    )


def learned(lower: float, upper: float | None, budget: float, deciding: bool) -> float:
    """The error the plans learn from a measurement (length). A bound refined only until
    it decides the budget says little about the error itself (it stops anywhere up to
    the budget, or at a loose value once a point beyond it is found): then the measured
    maximum (a lower bound), unless the bound exceeds the budget while that maximum does
    not (the refinement ran out of budget): the bound."""
    if upper is None:
        return lower
    if not deciding:
        return upper
    return upper if lower <= budget < upper else lower


def interpolate(points: list[tuple[float, float]], x: float, slope: float) -> float:
    """``y(x)`` through ``(x_i, y_i)`` (increasing together), linear in log-log between
    the two around ``x``, proportional to the nearest one beyond them, ``slope * x``
    without any."""
    below = [(xi, yi) for xi, yi in points if xi <= x]
    above = [(xi, yi) for xi, yi in points if xi > x]
    if below and above:
        (x0, y0), (x1, y1) = max(below), min(above)
        if y1 > y0 > 0 and x0 > 0:
            w = math.log(x / x0) / math.log(x1 / x0)
            return y0 * (y1 / y0) ** w
        return math.sqrt(y0 * y1) if y0 > 0 else y1
    if above:
        x1, y1 = min(above)
        return y1 * x / x1
    if below:
        x0, y0 = max(below)
        return y0 * x / x0 if x0 > 0 else y0
    return slope * x
