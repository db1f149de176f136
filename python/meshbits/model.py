"""The analytic bit-allocation model (King & Rossignac 1999, Sec. 3-6).

Given the shape complexity ``K`` of a mesh and one constraint (a file size ``F``, an error
``E`` or a vertex count ``V``), find the bits per coordinate ``B`` and the vertex count
``V`` that minimise the predicted error for the size, or the size for the error.

One concept: the paper's analytic model, its error and size functions and the optimal
allocations (:class:`Allocation`) solved from them; nothing here reads a mesh or a file.

Units: sizes in bits; errors are lengths in the unit of the grid size ``S`` (the side of
the quantization cube), which every error function and plan requires as ``grid_size``:
pass the mesh's ``ShapeComplexity.grid_size`` for errors in mesh units (as ``compress``
and ``hausdorff`` take them), or 1.0 for errors as fractions of ``S`` (what
``relative=True`` means elsewhere). ``K`` is dimensionless (grid-normalised,
``ShapeComplexity.k``). The size model ``F = (3 alpha B + T) V`` defaults to Draco's
fitted ``alpha = 0.595, T = 0`` (``compress``'s default too); the paper's is
``alpha = 1, T = 4``.
The derivation, with the paper's equation numbers and the places where its print is
wrong, and the reference numbers, are in ``docs/model.md``.

The error model (Eq. 2, 3, 7, 10, 11)::

    E_Q(B)  = (sqrt(3)/2) S 2^-B
    theta   = sqrt(2 C / V_S),  C = 4 pi / sqrt(3),  V_S = 4 pi V / K
    E_T(V)  = S (1 - sqrt((1 + 2 cos theta) / 3))
    E(B, V) = E_Q(B) + E_T(V),   F(B, V) = (3 alpha B + T) V

Two solution methods: ``"exact"`` solves the exact optimality condition (Eq. 4, written
out as Eq. 12) on the constraint curve by bracketed bisection to machine precision;
``"asymptotic"`` uses the large-``V/K`` forms (Eq. 13-15, 17-19), which contain the
constant ``B0``. ``B0`` therefore only affects the asymptotic method.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from .constants import (
    DRACO_ALPHA,
    DRACO_CONNECTIVITY_BITS,
    MODEL_MIN_BITS,
    MODEL_MIN_SPHERE_VERTICES,
    MODEL_MIN_VERTICES,
    PAPER_B0,
)
from .errors import MeshbitsError

__all__ = [
    "DERIVED_B0",
    "METHODS",
    "PAPER_B0",
    "SPHERE_C",
    "Allocation",
    "error",
    "file_size",
    "guaranteed_bits",
    "optimal_bits",
    "plan_for_error",
    "plan_for_size",
    "plan_for_vertices",
    "quantization_error",
    "size_model_parameters",
    "sphere_vertices",
    "tessellation_error",
    "vertices_for_error",
]

SQRT3 = math.sqrt(3.0)
LN2 = math.log(2.0)
#: ``C = 4 pi / sqrt(3)`` of Eq. 11: a sphere with ``V_S`` vertices has ``theta^2 = 2C/V_S``.
SPHERE_C = 4.0 * math.pi / SQRT3
#: ``B0 = log2(4.5 ln 2) = 1.6412`` bits: the constant of Eq. 13-15 derived from the
#: paper's definitions (the paper prints 1.838, :data:`PAPER_B0`).
DERIVED_B0 = math.log2(4.5 * LN2)
#: Solution methods of the ``plan_for_*`` functions.
METHODS = ("exact", "asymptotic")

#: Beyond ``theta = 2 pi / 3`` (``V_S < 3.31``) ``1 + 2 cos theta < 0``: Eq. 10 has no
#: meaning, and ``E_T`` is held at its value there, ``S``.
_THETA_MAX = 2.0 * math.pi / 3.0
#: ``log2(3 sqrt(3) ln 2)``: the constant of the exact ridge equation (Eq. 12).
_RIDGE_CONST = math.log2(3.0 * SQRT3 * LN2)


# --- input checks ------------------------------------------------------------------------


def _real_array(name: str, value: Any) -> np.ndarray:
    if value is None or isinstance(value, (str, bytes, bool, np.bool_)):
        raise TypeError(f"{name} must be a real number or an array of them, got {value!r}")
    array = np.asarray(value)
    if array.dtype.kind not in "iuf":
        raise TypeError(f"{name} must hold real numbers, got dtype {array.dtype}")
    return array.astype(np.float64)


def _require(
    name: str, array: np.ndarray, ok: Callable[[np.ndarray], np.ndarray], what: str
) -> np.ndarray:
    """Raise ValueError naming ``name`` unless ``ok(array)`` holds everywhere."""
    with np.errstate(invalid="ignore"):
        bad = ~(ok(array) & np.isfinite(array))
    if np.any(bad):
        first = float(array[bad].flat[0])
        where = f" ({int(bad.sum())} of {array.size} values)" if array.ndim else ""
        raise MeshbitsError(f"{name} must be {what}, got {first!r}{where}")
    return array


def _positive(name: str, value: Any) -> np.ndarray:
    return _require(name, _real_array(name, value), lambda a: a > 0, "positive and finite")


def _nonnegative(name: str, value: Any) -> np.ndarray:
    return _require(name, _real_array(name, value), lambda a: a >= 0, "finite and >= 0")


def _alpha(value: Any) -> np.ndarray:
    return _require("alpha", _real_array("alpha", value), lambda a: (a > 0) & (a <= 1), "in (0, 1]")


def _scalar(array: np.ndarray, name: str) -> float:
    if array.ndim != 0:
        raise TypeError(f"{name} must be a single number here, got an array of shape {array.shape}")
    return float(array)


def size_model_parameters(alpha: Any, connectivity_bits: Any) -> tuple[float, float]:
    """The size model's ``alpha`` (coded bits per coordinate bit, in (0, 1]) and
    connectivity ``T`` (bits per vertex, >= 0), each checked as a single finite number;
    raises :class:`MeshbitsError` (a bad value) or ``TypeError`` (an array)."""
    return (
        _scalar(_alpha(alpha), "alpha"),
        _scalar(_nonnegative("connectivity_bits", connectivity_bits), "connectivity_bits"),
    )


def _out(result: np.ndarray) -> float | np.ndarray:
    """A Python float for scalar input, the array otherwise."""
    return float(result) if np.ndim(result) == 0 else result


def _resolve_b0(b0: float | str) -> float:
    if isinstance(b0, str):
        if b0 == "derived":
            return DERIVED_B0
        if b0 == "paper":
            return PAPER_B0
        raise MeshbitsError(f"b0 must be 'derived', 'paper' or a number, got {b0!r}")
    if isinstance(b0, bool) or not isinstance(b0, numbers.Real):
        raise TypeError(f"b0 must be 'derived', 'paper' or a number, got {b0!r}")
    if not math.isfinite(float(b0)):
        raise MeshbitsError(f"b0 must be finite, got {b0!r}")
    return float(b0)


def _check_method(method: str) -> None:
    if method not in METHODS:
        raise MeshbitsError(f"method must be one of {METHODS}, got {method!r}")


# --- the model, unchecked kernels --------------------------------------------------------


def _theta(vertices: Any, k: Any) -> Any:
    """``theta = sqrt(2C / V_S)`` with ``V_S = 4 pi V / K`` (Eq. 7, 11): ``sqrt(2K/(sqrt3 V))``."""
    return np.sqrt(2.0 * k / (SQRT3 * vertices))


def _tessellation_relative(theta: Any) -> Any:
    """``E_T / S = 1 - sqrt(h)``, ``h = (1 + 2 cos theta)/3`` (Eq. 10), without cancellation.

    ``1 - h = (4/3) sin^2(theta/2)``, so ``1 - sqrt(h) = (4/3) sin^2(theta/2) / (1 + sqrt h)``;
    the direct form loses about half its digits by ``V_S = 1e8``. Held at 1 beyond
    ``theta = 2 pi / 3``, where ``h`` would be negative.
    """
    s2 = np.sin(0.5 * np.minimum(theta, _THETA_MAX)) ** 2
    h = np.maximum(1.0 - (4.0 / 3.0) * s2, 0.0)
    return np.where(theta >= _THETA_MAX, 1.0, (4.0 / 3.0) * s2 / (1.0 + np.sqrt(h)))


def _theta_for_relative_error(e_t: Any) -> Any:
    """Inverse of :func:`_tessellation_relative` on ``0 <= e_t <= 1``.

    ``sqrt(h) = 1 - e`` gives ``sin^2(theta/2) = (3/4)(1 - (1 - e)^2) = (3/4) e (2 - e)``.
    """
    return 2.0 * np.arcsin(np.sqrt(np.clip(0.75 * e_t * (2.0 - e_t), 0.0, 0.75)))


def _quantization_relative(bits: Any) -> Any:
    """``E_Q / S = (sqrt(3)/2) 2^-B`` (Eq. 2)."""
    return 0.5 * SQRT3 * np.exp2(-bits)


def _ridge_exact(theta: Any) -> Any:
    """Right side of Eq. 12 as a function of theta (bits).

    ``log2(3 sqrt(3) ln 2) + log2(h)/2 - log2(theta) - log2(sin theta)``: ``+inf`` at
    ``theta = 0``, ``-inf`` from ``theta = 2 pi / 3`` on (``h = 0``).
    """
    theta = np.asarray(theta, dtype=np.float64)
    t = np.clip(theta, np.finfo(np.float64).tiny, _THETA_MAX)
    with np.errstate(divide="ignore"):
        log_h = np.log1p(np.maximum(-(4.0 / 3.0) * np.sin(0.5 * t) ** 2, -1.0))
        out = _RIDGE_CONST + 0.5 * log_h / LN2 - np.log2(t) - np.log2(np.sin(t))
    out = np.where(theta >= _THETA_MAX, -np.inf, out)
    return np.where(theta <= 0.0, np.inf, out)


def _ridge_asymptotic(vertices: Any, k: Any, b0: float) -> Any:
    """Right side of Eq. 13: ``log2(V/K) + B0`` (bits); ``+inf`` where ``V/K`` overflows."""
    with np.errstate(over="ignore"):
        return np.log2(vertices / k) + b0


def _ridge_left(bits: Any, tau: Any) -> Any:
    """Left side of Eq. 12, 13: ``B - log2(B + T/(3 alpha))`` (bits)."""
    return bits - np.log2(bits + tau)


def _bits_floor(tau: Any) -> Any:
    """Lowest B searched: ``MODEL_MIN_BITS``, and ``1/ln 2 - tau`` below which the left side
    of Eq. 12 decreases (so the root above it is the one meant)."""
    return np.maximum(MODEL_MIN_BITS, 1.0 / LN2 - tau)


def _root_increasing(f: Callable[[np.ndarray], np.ndarray], lo: Any) -> np.ndarray:
    """Root of an increasing ``f`` on ``[lo, inf)``, elementwise, by bisection.

    Where ``f(lo) >= 0`` the answer is ``lo`` (the constrained optimum sits on the bound).
    The bracket ``[lo, lo + w]`` doubles ``w`` until ``f`` turns positive, then is halved
    until its ends are adjacent floats; ``f`` may return ``-inf``/``+inf``, never NaN.
    """
    lo0 = np.array(lo, dtype=np.float64)
    at_bound = f(lo0) >= 0.0
    lo = lo0.copy()
    width = np.ones_like(lo0)
    hi = lo + width
    unbounded = np.zeros_like(at_bound)
    for _ in range(200):
        need = (f(hi) <= 0.0) & ~at_bound
        if not need.any():
            break
        lo = np.where(need, hi, lo)
        width = np.where(need, 2.0 * width, width)
        hi = np.where(need, lo + width, hi)
    else:
        # f stays <= 0 up to 2**200: where K / V underflows, theta is 0 and the right side
        # of Eq. 12 +inf. No root: +inf, which the callers refuse.
        unbounded = need
    for _ in range(2200):
        mid = 0.5 * (lo + hi)
        if np.all(unbounded | (mid <= lo) | (mid >= hi)):
            break
        positive = f(mid) > 0.0
        hi = np.where(positive, mid, hi)
        lo = np.where(positive, lo, mid)
    return np.where(at_bound, lo0, np.where(unbounded, np.inf, hi))


#: Largest B a plan may have: 2**-B underflows float64 from about 1,075 bits on, where the
#: model's errors mean nothing.
MODEL_MAX_BITS = 1100.0


def _check_plan_bits(bits: float, budget: str) -> float:
    """``bits``, or a refusal naming the budget when it lies beyond the model's range."""
    if not (math.isfinite(bits) and bits <= MODEL_MAX_BITS):
        raise MeshbitsError(
            f"no plan for {budget}: the optimal B would be {bits:.4g} bits per coordinate, "
            f"beyond the model's numeric range ({MODEL_MAX_BITS:g} bits); K, S or the budget "
            "is extreme"
        )
    return bits


# --- public elementwise functions --------------------------------------------------------


def file_size(
    bits: Any,
    vertices: Any,
    *,
    alpha: Any = DRACO_ALPHA,
    connectivity_bits: Any = DRACO_CONNECTIVITY_BITS,
) -> float | np.ndarray:
    """File size ``F = (3 alpha B + T) V`` in bits (paper Eq. 1).

    Parameters
    ----------
    bits : float or array_like
        ``B``, bits per vertex coordinate (>= 0).
    vertices : float or array_like
        ``V``, vertex count (>= 0).
    alpha : float or array_like
        Compression factor on coordinates, in ``(0, 1]`` (1: none, the paper's; 1/3: a
        good predictive coder). Default: Draco's fitted 0.595.
    connectivity_bits : float or array_like
        ``T``, connectivity bits per vertex (>= 0; the paper's 4 is 2 bits per triangle).
        Default: Draco's fitted 0.

    Returns
    -------
    float or ndarray of float64
        ``F`` in bits, broadcast over the inputs.
    """
    b = _nonnegative("bits", bits)
    v = _nonnegative("vertices", vertices)
    a = _alpha(alpha)
    t = _nonnegative("connectivity_bits", connectivity_bits)
    return _out((3.0 * a * b + t) * v)


def quantization_error(bits: Any, grid_size: Any) -> float | np.ndarray:
    """Quantization error ``E_Q = (sqrt(3)/2) S 2^-B`` (paper Eq. 2).

    The farthest a point moves when snapped to a cube grid of side ``S`` with ``2^B`` cells
    per axis (the model's form; a grid of ``2^B`` *codes* has ``2^B - 1`` cells and bound
    ``(sqrt(3)/2) S / (2^B - 1)``, see :func:`guaranteed_bits`).

    Parameters
    ----------
    bits : float or array_like
        ``B``, bits per coordinate (>= 0).
    grid_size : float or array_like
        ``S`` (length, > 0), required: every error in and out is a length in its unit.
        Pass the mesh's ``ShapeComplexity.grid_size`` for errors in mesh units, or 1.0 for
        errors as fractions of ``S``.

    Returns
    -------
    float or ndarray of float64
        ``E_Q`` in the length unit of ``S``.
    """
    b = _nonnegative("bits", bits)
    s = _positive("grid_size", grid_size)
    return _out(s * _quantization_relative(b))


def sphere_vertices(vertices: Any, k: Any) -> float | np.ndarray:
    """``V_S = 4 pi V / K`` (paper Eq. 7): the vertex count of the sphere whose tessellation
    error equals that of a shape of complexity ``K`` with ``V`` vertices.

    Parameters
    ----------
    vertices : float or array_like
        ``V`` (> 0).
    k : float or array_like
        ``K``, grid-normalised shape complexity (dimensionless, > 0; a sphere gives
        ``2 pi``).
    """
    v = _positive("vertices", vertices)
    kk = _positive("k", k)
    return _out(4.0 * math.pi * v / kk)


def tessellation_error(vertices: Any, k: Any, grid_size: Any) -> float | np.ndarray:
    """Tessellation error ``E_T`` of ``V`` vertices on a shape of complexity ``K``.

    Eq. 10 on a sphere of radius ``S`` with ``V_S = 4 pi V / K`` vertices (Eq. 7)::

        E_T = S (1 - sqrt((1 + 2 cos theta) / 3)),   theta = sqrt(2 C / V_S)

    computed as ``S (4/3) sin^2(theta/2) / (1 + sqrt((1 + 2 cos theta)/3))`` (no
    cancellation at large ``V_S``). Asymptotically ``E_T = S K / (3 sqrt(3) V)``.

    The formula holds for small theta (``V_S >= 12``). Below ``V_S = 3.31`` (theta over
    ``2 pi / 3``) it has no meaning and the value is held at ``S``, which keeps ``E_T``
    non-increasing in ``V``.

    Parameters
    ----------
    vertices : float or array_like
        ``V`` (> 0).
    k : float or array_like
        ``K``, grid-normalised shape complexity (dimensionless, > 0).
    grid_size : float or array_like
        ``S`` (length, > 0), required: every error in and out is a length in its unit.
        Pass the mesh's ``ShapeComplexity.grid_size`` for errors in mesh units, or 1.0 for
        errors as fractions of ``S``.

    Returns
    -------
    float or ndarray of float64
        ``E_T`` in the length unit of ``S``.
    """
    v = _positive("vertices", vertices)
    kk = _positive("k", k)
    s = _positive("grid_size", grid_size)
    return _out(s * _tessellation_relative(_theta(v, kk)))


def error(bits: Any, vertices: Any, k: Any, grid_size: Any) -> float | np.ndarray:
    """Predicted error ``E = E_Q(B) + E_T(V)`` (paper Eq. 3, the bound taken as equality).

    Parameters are those of :func:`quantization_error` and :func:`tessellation_error`;
    the result is in the length unit of ``S``.
    """
    return _out(
        np.asarray(quantization_error(bits, grid_size))
        + np.asarray(tessellation_error(vertices, k, grid_size))
    )


def vertices_for_error(error: Any, k: Any, grid_size: Any) -> float | np.ndarray:
    """Vertex count whose tessellation error is ``error``: the exact inverse of
    :func:`tessellation_error` (paper Eq. 17, 18).

    ``sqrt(h) = 1 - E_T/S`` gives ``sin^2(theta/2) = (3/4) e (2 - e)`` with ``e = E_T/S``,
    and ``V = 2 K / (sqrt(3) theta^2)``. Asymptotically (Eq. 18) ``V = K S / (3 sqrt(3) E_T)``.

    Parameters
    ----------
    error : float or array_like
        ``E_T``, in the length unit of ``S``; ``0 < E_T < S``.
    k : float or array_like
        ``K``, grid-normalised shape complexity (dimensionless, > 0).
    grid_size : float or array_like
        ``S`` (length, > 0), required: every error in and out is a length in its unit.
        Pass the mesh's ``ShapeComplexity.grid_size`` for errors in mesh units, or 1.0 for
        errors as fractions of ``S``.

    Returns
    -------
    float or ndarray of float64
        ``V`` (not rounded).

    Raises
    ------
    ValueError
        If ``error`` is not in ``(0, S)``, or ``k`` or ``grid_size`` is not positive.
    """
    e = _positive("error", error)
    kk = _positive("k", k)
    s = _positive("grid_size", grid_size)
    rel = e / s
    _require("error", rel, lambda r: r < 1.0, "below the grid size S (error / S < 1)")
    return _out(2.0 * kk / (SQRT3 * _theta_for_relative_error(rel) ** 2))


def optimal_bits(
    vertices: Any,
    k: Any,
    *,
    alpha: Any = DRACO_ALPHA,
    connectivity_bits: Any = DRACO_CONNECTIVITY_BITS,
    exact: bool = True,
    b0: float | str = "derived",
) -> float | np.ndarray:
    """The ridge ``B(V)``: bits per coordinate that are optimal for ``V`` vertices.

    At the optimum of the error for a given file size (or of the size for a given error)
    the gradient of ``E`` is normal to the iso-``F`` curve (Eq. 4), which reads::

        B - log2(B + T/(3 alpha)) = log2(3 sqrt(3) ln 2) + log2(h)/2 - log2(theta)
                                    - log2(sin theta)                          (Eq. 12)
        B - log2(B + T/(3 alpha)) = log2(V/K) + B0             (large V/K, Eq. 13)

    with ``theta = sqrt(2 K / (sqrt(3) V))`` and ``h = (1 + 2 cos theta)/3``. The root is
    taken on ``B >= max(1, 1/ln 2 - T/(3 alpha))``, where the left side increases; where
    the right side is below the left side's value there (tiny ``V/K``, far outside the
    model's domain), the result is that lower bound.

    Parameters
    ----------
    vertices : float or array_like
        ``V`` (> 0).
    k : float or array_like
        ``K``, grid-normalised shape complexity (dimensionless, > 0).
    alpha : float or array_like
        Coordinate compression factor in ``(0, 1]`` (default Draco's fitted 0.595).
    connectivity_bits : float or array_like
        ``T`` (bits per vertex, >= 0; default Draco's fitted 0).
    exact : bool
        Solve Eq. 12 (default) or the asymptotic Eq. 13.
    b0 : {"derived", "paper"} or float
        ``B0`` of Eq. 13 in bits, used only when ``exact=False``: ``"derived"`` is
        ``log2(4.5 ln 2) = 1.6412``, ``"paper"`` the paper's printed 1.838.

    Returns
    -------
    float or ndarray of float64
        ``B`` in bits (continuous), broadcast over the inputs.
    """
    v = _positive("vertices", vertices)
    kk = _positive("k", k)
    a = _alpha(alpha)
    t = _nonnegative("connectivity_bits", connectivity_bits)
    b0_value = _resolve_b0(b0)
    v, kk, a, t = np.broadcast_arrays(v, kk, a, t)
    tau = t / (3.0 * a)
    right = _ridge_exact(_theta(v, kk)) if exact else _ridge_asymptotic(v, kk, b0_value)
    bits = _root_increasing(lambda b: _ridge_left(b, tau) - right, _bits_floor(tau))
    infinite = ~np.isfinite(bits)
    if infinite.any():
        raise MeshbitsError(
            f"no optimal B for V = {float(v[infinite].flat[0]):g} and K = "
            f"{float(kk[infinite].flat[0]):g}: V / K is beyond the model's numeric range"
        )
    return _out(bits)


def guaranteed_bits(error: Any, grid_size: Any) -> int | np.ndarray:
    """Smallest ``B`` whose quantization alone never moves a point more than ``error``.

    A grid of ``2^B`` codes per axis over a cube of side ``S`` has cells of side
    ``S / (2^B - 1)``; rounding moves a point by at most ``(sqrt(3)/2) S / (2^B - 1)``.
    That is at most ``E`` exactly when ``B >= log2(sqrt(3) S / (2 E) + 1)``, so::

        B = max(1, ceil(log2(sqrt(3) S / (2 E) + 1)))

    (checked against the bound itself, so rounding in ``log2`` cannot cost a bit). This is
    a hard worst-case bound, unlike the model's optimum, which balances an *estimate* of the
    tessellation error.

    Parameters
    ----------
    error : float or array_like
        ``E``, the largest allowed displacement (length unit of ``S``, > 0).
    grid_size : float or array_like
        ``S`` (length, > 0), required: every error in and out is a length in its unit.
        Pass the mesh's ``ShapeComplexity.grid_size`` for errors in mesh units, or 1.0 for
        errors as fractions of ``S``.

    Returns
    -------
    int or ndarray of int64
        Bits per coordinate.
    """
    e = _positive("error", error)
    s = _positive("grid_size", grid_size)
    e, s = np.broadcast_arrays(e, s)
    with np.errstate(over="ignore"):
        ratio = SQRT3 * s / (2.0 * e)
        _require("error", ratio, lambda r: r < 2.0**1000, "at least 2^-1000 times the grid size")
        bits = np.maximum(np.ceil(np.log2(ratio + 1.0)), 1.0)

    def meets(b: np.ndarray) -> np.ndarray:
        return 0.5 * SQRT3 * s / (np.exp2(b) - 1.0) <= e

    bits = np.where(meets(bits), bits, bits + 1.0)
    lower = np.maximum(bits - 1.0, 1.0)
    bits = np.where(meets(lower), lower, bits)
    out = bits.astype(np.int64)
    return int(out) if out.ndim == 0 else out


# --- plans -------------------------------------------------------------------------------


@dataclass(frozen=True)
class Allocation:
    """An optimal bit allocation: the continuous optimum and the best whole-bits plan.

    All errors are the exact model (Eq. 2, 10) evaluated at the plan's ``(B, V)``, in the
    length unit of :attr:`grid_size`; sizes are in bits. Vertex counts are not rounded.

    Attributes
    ----------
    constraint : str
        ``"size"``, ``"error"`` or ``"vertices"``.
    budget : float
        The constraint's value: bits, length, or a vertex count.
    method : str
        ``"exact"`` (Eq. 12 solved on the constraint curve) or ``"asymptotic"``
        (Eq. 13-15, 17-19).
    bits, vertices : float
        The continuous optimum ``B`` (bits per coordinate) and ``V``.
    file_size : float
        ``F = (3 alpha B + T) V`` (bits).
    error, quantization_error, tessellation_error : float
        ``E = E_Q + E_T``, ``E_Q``, ``E_T`` (length).
    sphere_vertices : float
        ``V_S = 4 pi V / K``.
    theta : float
        ``sqrt(2C / V_S)`` (radians): the angle between neighbouring vertices on the
        equivalent sphere.
    whole_bits : int
        The best whole number of bits (see the ``plan_for_*`` functions for the rule).
    whole_vertices, whole_file_size, whole_error, whole_quantization_error,
    whole_tessellation_error : float
        ``V`` recomputed for :attr:`whole_bits` under the constraint, and the resulting
        ``F``, ``E``, ``E_Q``, ``E_T``.
    k : float
        ``K``, grid-normalised (dimensionless).
    grid_size : float
        ``S`` (length).
    alpha, connectivity_bits : float
        ``alpha`` and ``T`` (bits per vertex).
    b0 : float or None
        ``B0`` (bits) of the asymptotic method; ``None`` for ``"exact"``, which does not
        use it.
    in_model_domain : bool
        False where the sphere model is not trusted: ``V_S < 12`` (theta not small),
        fewer than 4 vertices, or the optimum pressed against the lowest allowed ``B``.
    domain_reason : str
        Why :attr:`in_model_domain` is false (``""`` when true).
    """

    constraint: str
    budget: float
    method: str
    bits: float
    vertices: float
    file_size: float
    error: float
    quantization_error: float
    tessellation_error: float
    sphere_vertices: float
    theta: float
    whole_bits: int
    whole_vertices: float
    whole_file_size: float
    whole_error: float
    whole_quantization_error: float
    whole_tessellation_error: float
    k: float
    grid_size: float
    alpha: float
    connectivity_bits: float
    b0: float | None
    in_model_domain: bool
    domain_reason: str

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict of all fields."""
        return asdict(self)


@dataclass(frozen=True)
class _Setup:
    k: float
    grid_size: float
    alpha: float
    connectivity_bits: float
    tau: float
    method: str
    b0: float


def _setup(
    k: Any, grid_size: Any, alpha: Any, connectivity_bits: Any, method: str, b0: float | str
) -> _Setup:
    _check_method(method)
    a, t = size_model_parameters(alpha, connectivity_bits)
    return _Setup(
        k=_scalar(_positive("k", k), "k"),
        grid_size=_scalar(_positive("grid_size", grid_size), "grid_size"),
        alpha=a,
        connectivity_bits=t,
        tau=t / (3.0 * a),
        method=method,
        b0=_resolve_b0(b0),
    )


def _size_of(bits: float, vertices: float, p: _Setup) -> float:
    return (3.0 * p.alpha * bits + p.connectivity_bits) * vertices


def _relative_error(bits: float, vertices: float, p: _Setup) -> float:
    return float(_quantization_relative(bits) + _tessellation_relative(_theta(vertices, p.k)))


def _pick_whole(bits: float, cost: Callable[[float], float]) -> int:
    """``floor(bits)`` or ``ceil(bits)``, whichever has the smaller ``cost`` (floor on a tie)."""
    low, high = math.floor(bits), math.ceil(bits)
    return low if cost(low) <= cost(high) else high


def _allocation(
    constraint: str,
    budget: float,
    p: _Setup,
    bits: float,
    vertices: float,
    whole_bits: int,
    whole_vertices: float,
    at_bound: bool,
) -> Allocation:
    s = p.grid_size
    reasons = []
    plans = [("", vertices)]
    if whole_vertices != vertices:
        plans.append(("whole-bits plan: ", whole_vertices))
    for label, v in plans:
        v_s = 4.0 * math.pi * v / p.k
        if v_s < MODEL_MIN_SPHERE_VERTICES:
            reasons.append(
                f"{label}V_S = {v_s:.4g} < {MODEL_MIN_SPHERE_VERTICES:g}: theta = "
                f"{float(_theta(v, p.k)):.3g} rad is not small"
            )
        if v < MODEL_MIN_VERTICES:
            reasons.append(f"{label}V = {v:.4g} is fewer than {MODEL_MIN_VERTICES:g} vertices")
    if at_bound:
        reasons.append(
            f"the optimum is pressed against the lowest allowed B = {bits:.4g} bits: the "
            "constraint is too tight for the model"
        )
    e_q = float(_quantization_relative(bits))
    e_t = float(_tessellation_relative(_theta(vertices, p.k)))
    w_q = float(_quantization_relative(whole_bits))
    w_t = float(_tessellation_relative(_theta(whole_vertices, p.k)))
    return Allocation(
        constraint=constraint,
        budget=budget,
        method=p.method,
        bits=bits,
        vertices=vertices,
        file_size=_size_of(bits, vertices, p),
        error=s * (e_q + e_t),
        quantization_error=s * e_q,
        tessellation_error=s * e_t,
        sphere_vertices=4.0 * math.pi * vertices / p.k,
        theta=float(_theta(vertices, p.k)),
        whole_bits=int(whole_bits),
        whole_vertices=whole_vertices,
        whole_file_size=_size_of(whole_bits, whole_vertices, p),
        whole_error=s * (w_q + w_t),
        whole_quantization_error=s * w_q,
        whole_tessellation_error=s * w_t,
        k=p.k,
        grid_size=s,
        alpha=p.alpha,
        connectivity_bits=p.connectivity_bits,
        b0=p.b0 if p.method == "asymptotic" else None,
        in_model_domain=not reasons,
        domain_reason="; ".join(reasons),
    )


def plan_for_size(
    size_bits: Any,
    k: Any,
    *,
    grid_size: Any,
    alpha: Any = DRACO_ALPHA,
    connectivity_bits: Any = DRACO_CONNECTIVITY_BITS,
    method: str = "exact",
    b0: float | str = "derived",
) -> Allocation:
    """The ``B`` and ``V`` of least error for a file size ``F`` (paper Sec. 6, Eq. 14, 15).

    ``"exact"``: along ``V = F / (3 alpha B + T)`` the derivative of the exact ``E(B, V)``
    has the sign of ``B - log2(B + T/(3 alpha)) - R(V)``, with ``R`` the right side of
    Eq. 12; that is increasing in ``B`` (``E`` is unimodal along the curve), and its root
    is found by bisection to machine precision. ``"asymptotic"``:
    ``B = log2(F / (3 alpha K)) + B0`` (Eq. 14, the paper prints it without the 3),
    ``V = F / (3 alpha B + T)`` (Eq. 15).

    The whole-bits plan takes ``floor(B)`` or ``ceil(B)``, whichever gives the smaller
    exact ``E`` with ``V = F / (3 alpha B + T)`` recomputed (so its size is exactly ``F``).
    Because ``E`` is unimodal along the curve, no other whole ``B`` does better.

    Parameters
    ----------
    size_bits : float
        ``F``, the file size budget in bits (see :func:`meshbits.units.parse_size` for ``"100KB"``).
    k : float
        ``K``, grid-normalised shape complexity (dimensionless, > 0).
    grid_size : float
        ``S`` (length, > 0), required: every error in and out is a length in its unit.
        Pass the mesh's ``ShapeComplexity.grid_size`` for errors in mesh units, or 1.0 for
        errors as fractions of ``S``.
    alpha : float
        Coordinate compression factor in ``(0, 1]``. Default: Draco's fitted 0.595
        (``constants.DRACO_ALPHA``), the size model ``compress`` starts from; the paper's
        uncompressed coordinates are ``alpha=1``.
    connectivity_bits : float
        ``T`` (bits per vertex, >= 0). Default: Draco's fitted 0
        (``constants.DRACO_CONNECTIVITY_BITS``); the paper's is 4.
    method : {"exact", "asymptotic"}
    b0 : {"derived", "paper"} or float
        ``B0`` (bits) for ``method="asymptotic"``; ignored by ``"exact"``.

    Returns
    -------
    Allocation

    Raises
    ------
    ValueError
        If ``F`` cannot hold a tetrahedron (4 vertices at 1 bit per coordinate, that is
        ``4 (3 alpha + T)`` bits), or ``K``, ``S``, ``alpha``, ``T`` are out of range.
    """
    p = _setup(k, grid_size, alpha, connectivity_bits, method, b0)
    f = _scalar(_positive("size_bits", size_bits), "size_bits")
    smallest = MODEL_MIN_VERTICES * (3.0 * p.alpha * MODEL_MIN_BITS + p.connectivity_bits)
    if f < smallest:
        raise MeshbitsError(
            f"size_bits = {f:g} bits cannot hold even a tetrahedron: {MODEL_MIN_VERTICES:g} "
            f"vertices at {MODEL_MIN_BITS:g} bit per coordinate need {smallest:g} bits"
        )
    lo = float(_bits_floor(p.tau))

    def vertices_at(b: Any) -> Any:
        return f / (3.0 * p.alpha * (b + p.tau))

    def slope_sign(b: np.ndarray) -> np.ndarray:
        return _ridge_left(b, p.tau) - _ridge_exact(_theta(vertices_at(b), p.k))

    if method == "exact":
        bits = float(_root_increasing(slope_sign, lo))
    else:
        with np.errstate(over="ignore"):
            bits = float(np.log2(np.float64(f) / (3.0 * p.alpha * p.k))) + p.b0
    _check_plan_bits(bits, f"size_bits = {f:g} and K = {p.k:g}")
    at_bound = bits <= lo
    bits = max(bits, lo)
    whole = _pick_whole(bits, lambda b: _relative_error(b, vertices_at(b), p))
    return _allocation(
        "size", f, p, bits, float(vertices_at(bits)), whole, float(vertices_at(whole)), at_bound
    )


def plan_for_error(
    error: Any,
    k: Any,
    *,
    grid_size: Any,
    alpha: Any = DRACO_ALPHA,
    connectivity_bits: Any = DRACO_CONNECTIVITY_BITS,
    method: str = "exact",
    b0: float | str = "derived",
) -> Allocation:
    """The ``B`` and ``V`` of least file size for an error ``E`` (paper Sec. 6, Eq. 17-19).

    ``"exact"``: along ``E_Q(B) + E_T(V) = E`` (``V`` from the exact inverse of Eq. 10,
    :func:`vertices_for_error`) the optimum again satisfies Eq. 12; its two sides cross once
    for ``B`` above ``log2(sqrt(3) S / (2 E))`` (where ``E_Q = E``), found by bisection.
    ``"asymptotic"``: Eq. 13 with Eq. 18, ``B - log2(B + T/(3 alpha)) = -log2(3 sqrt(3) E_T
    / S) + B0`` with ``E_T = E - E_Q(B)``, then ``V = K S / (3 sqrt(3) E_T)``. With the
    derived ``B0`` this is the fixed point ``B = log2(sqrt(3) (1 + ln 2 (B + T/(3 alpha)))
    / (2 E / S))``. The optimal ``B`` depends on ``E / S``, ``alpha`` and ``T`` only, not on
    ``K``; ``V`` is proportional to ``K``.

    The whole-bits plan takes ``floor(B)`` or ``ceil(B)``, whichever gives the smaller
    exact ``F`` with ``V`` recomputed from the exact inverse so that ``E`` is met exactly
    (a ``B`` whose ``E_Q`` alone reaches ``E`` costs infinitely much).

    Parameters
    ----------
    error : float
        ``E``, the error budget in the length unit of ``S``; ``0 < E < S``.
    k, grid_size, alpha, connectivity_bits, method, b0
        As in :func:`plan_for_size`.

    Returns
    -------
    Allocation
        For ``"asymptotic"`` the reported ``E`` is the exact model at the asymptotic
        ``(B, V)``, so it differs slightly from the budget.

    Raises
    ------
    ValueError
        If ``E <= 0`` or ``E >= S``, or ``K``, ``S``, ``alpha``, ``T`` are out of range.
    """
    p = _setup(k, grid_size, alpha, connectivity_bits, method, b0)
    budget = _scalar(_positive("error", error), "error")
    e = budget / p.grid_size
    if e >= 1.0:
        raise MeshbitsError(
            f"error = {budget:g} must be below the grid size S = {p.grid_size:g} "
            "(a single vertex is within S of every point of the grid)"
        )
    with np.errstate(over="ignore", divide="ignore"):
        # E_Q(B) = E here: below it no V is enough.
        feasible = float(np.log2(0.5 * SQRT3 / np.float64(e)))
    _check_plan_bits(feasible, f"error = {budget:g} and S = {p.grid_size:g}")
    lo = max(float(_bits_floor(p.tau)), feasible)

    def tessellation_left(b: Any) -> Any:
        return np.maximum(e - _quantization_relative(b), 0.0)

    def slope_sign(b: np.ndarray) -> np.ndarray:
        e_t = tessellation_left(b)
        if method == "exact":
            right = _ridge_exact(_theta_for_relative_error(e_t))
        else:
            with np.errstate(divide="ignore"):
                right = -np.log2(3.0 * SQRT3 * e_t) + p.b0
        return _ridge_left(b, p.tau) - right

    def exact_vertices(b: Any) -> float:
        e_t = float(tessellation_left(b))
        if e_t <= 0.0:
            return math.inf
        return float(2.0 * p.k / (SQRT3 * _theta_for_relative_error(e_t) ** 2))

    bits = _check_plan_bits(
        float(_root_increasing(slope_sign, lo)), f"error = {budget:g} and K = {p.k:g}"
    )
    at_bound = bits <= lo and lo > feasible
    if method == "exact":
        vertices = exact_vertices(bits)
    else:
        vertices = p.k / (3.0 * SQRT3 * float(tessellation_left(bits)))
    whole = _pick_whole(bits, lambda b: _size_of(b, exact_vertices(b), p))
    return _allocation("error", budget, p, bits, vertices, whole, exact_vertices(whole), at_bound)


def plan_for_vertices(
    vertices: Any,
    k: Any,
    *,
    grid_size: Any,
    alpha: Any = DRACO_ALPHA,
    connectivity_bits: Any = DRACO_CONNECTIVITY_BITS,
    method: str = "exact",
    b0: float | str = "derived",
) -> Allocation:
    """The optimal ``B`` for ``V`` vertices: the ridge of :func:`optimal_bits` (Eq. 12, 13).

    ``B`` is the bits per coordinate for which ``(B, V)`` is the least-error point of its
    own file size ``F = (3 alpha B + T) V``.

    The whole-bits plan keeps ``V`` and takes ``floor(B)`` or ``ceil(B)``, whichever has the
    smaller ``E + lambda F``, where ``lambda = ln 2 E_Q(B) / (3 alpha V)`` is the price of
    a bit at the continuous optimum (the Lagrange multiplier of Eq. 4). For fixed ``V``
    that cost is ``E_Q(b) + ln 2 E_Q(B) b`` plus a constant, convex in ``b``, so no other
    whole ``b`` does better.

    Parameters
    ----------
    vertices : float
        ``V`` (>= 4).
    k, grid_size, alpha, connectivity_bits, method, b0
        As in :func:`plan_for_size`.

    Returns
    -------
    Allocation

    Raises
    ------
    ValueError
        If ``V < 4`` (no closed mesh), or ``K``, ``S``, ``alpha``, ``T`` are out of range.
    """
    p = _setup(k, grid_size, alpha, connectivity_bits, method, b0)
    v = _scalar(_positive("vertices", vertices), "vertices")
    if v < MODEL_MIN_VERTICES:
        raise MeshbitsError(
            f"vertices = {v:g}: a closed triangle mesh needs at least "
            f"{MODEL_MIN_VERTICES:g} vertices (a tetrahedron)"
        )
    lo = float(_bits_floor(p.tau))
    bits = float(
        optimal_bits(
            v,
            p.k,
            alpha=p.alpha,
            connectivity_bits=p.connectivity_bits,
            exact=method == "exact",
            b0=p.b0,
        )
    )
    _check_plan_bits(bits, f"vertices = {v:g} and K = {p.k:g}")
    price = LN2 * float(_quantization_relative(bits))
    whole = _pick_whole(bits, lambda b: float(_quantization_relative(b)) + price * b)
    return _allocation("vertices", v, p, bits, v, whole, v, bits <= lo)
