"""Tests of meshbits.model: the analytic B/V/F/E solvers (paper Sec. 3-6).

References are written here independently of the module: the error model in plain numpy
(with its own cancellation-free algebra), constrained optima by a dense scan refined by
golden-section search in extended precision, inverses by scipy's brentq or by bisection, and
a direct quantization experiment.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.optimize import brentq

import meshbits
from meshbits import model

DOCS = Path(__file__).parent.parent / "docs" / "model.md"
SQ3 = math.sqrt(3.0)
LN2 = math.log(2.0)
C = 4.0 * math.pi / SQ3
#: theta = 2 pi / 3: the sphere model's edge, V_S = 2C / theta^2.
VS_EDGE = 2.0 * C / (2.0 * math.pi / 3.0) ** 2

FAST = settings(max_examples=40, deadline=None)


# --- independent reference model ---------------------------------------------------------


def _real(x):
    """x as a float array, keeping np.longdouble when given it."""
    return np.asarray(x, dtype=np.result_type(x, np.float64))


def ref_eq(bits):
    """E_Q / S (Eq. 2)."""
    return SQ3 / 2.0 * np.exp2(-_real(bits))


def ref_et(vertices, k):
    """E_T / S (Eq. 10 via Eq. 7, 11), 1 - sqrt(h) = (1 - h) / (1 + sqrt(h)); NaN past the edge."""
    v_s = 4.0 * np.pi * _real(vertices) / k
    theta = np.sqrt(2.0 * C / v_s)
    one_minus_h = 2.0 * (2.0 * np.sin(theta / 2.0) ** 2) / 3.0  # (2/3)(1 - cos theta)
    with np.errstate(invalid="ignore"):
        out = one_minus_h / (1.0 + np.sqrt(1.0 - one_minus_h))
    return np.where(theta < 2.0 * np.pi / 3.0, out, np.nan)


def ref_et_textbook(vertices, k):
    """The formula as printed, 1 - sqrt((1 + 2 cos theta)/3): fine for moderate V_S."""
    theta = np.sqrt(2.0 * C * k / (4.0 * np.pi * np.asarray(vertices, dtype=float)))
    return 1.0 - np.sqrt((1.0 + 2.0 * np.cos(theta)) / 3.0)


def ref_vertices_for(e_t, k):
    """V with ref_et(V) = e_t, by brentq on log V."""
    lo = math.log(VS_EDGE * k / (4.0 * math.pi)) + 1e-12
    hi = math.log(10.0 * k / e_t)
    lv = brentq(
        lambda x: math.log(ref_et(math.exp(x), k)) - math.log(e_t),
        lo,
        hi,
        xtol=1e-15,
        rtol=1e-15,
        maxiter=500,
    )
    return math.exp(lv)


def golden_min(fun, lo, hi, iterations=90):
    """Golden-section minimum of a unimodal ``fun`` on [lo, hi], in extended precision.

    The objectives are flat at their minimum: in float64 their rounding noise hides the
    minimiser to about 1e-7; np.longdouble (64-bit mantissa on x86-64) pushes that to ~1e-9.
    """
    lo, hi = np.longdouble(lo), np.longdouble(hi)
    g = (np.sqrt(np.longdouble(5)) - 1) / 2
    c, d = hi - g * (hi - lo), lo + g * (hi - lo)
    fc, fd = fun(c), fun(d)
    for _ in range(iterations):
        if fc < fd:
            hi, d, fd = d, c, fc
            c = hi - g * (hi - lo)
            fc = fun(c)
        else:
            lo, c, fc = c, d, fd
            d = lo + g * (hi - lo)
            fd = fun(d)
    return float((lo + hi) / 2)


def brute_size(f, k, alpha, t):
    """argmin over B of E(B, F / (3 alpha B + T)): dense scan, then golden section."""
    v_edge = VS_EDGE * k / (4.0 * math.pi)
    b_hi = min((f / v_edge - t) / (3.0 * alpha), 80.0)

    def err(b):
        return ref_eq(b) + ref_et(f / (3.0 * alpha * b + t), k)

    grid = np.linspace(1.0, b_hi, 20001)[:-1]
    i = int(np.nanargmin(err(grid)))
    return golden_min(err, grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)])


def ld_vertices_for(e_t, k):
    """V with ref_et(V) = e_t in extended precision: bisection on log V."""
    e_t = np.longdouble(e_t)
    lo = np.log(np.longdouble(VS_EDGE * k / (4.0 * math.pi))) + np.longdouble(1e-12)
    hi = np.log(10 * np.longdouble(k) / e_t)
    for _ in range(75):
        mid = (lo + hi) / 2
        if ref_et(np.exp(mid), k) > e_t:
            lo = mid
        else:
            hi = mid
    return np.exp((lo + hi) / 2)


def brute_error(e, k, alpha, t):
    """argmin over B of F(B, V(E - E_Q(B))): scan (V by brentq), then golden section."""
    b_feas = math.log2(SQ3 / 2.0 / e)

    def size(b):
        return (3.0 * alpha * b + t) * ref_vertices_for(e - float(ref_eq(b)), k)

    grid = np.arange(max(1.0, b_feas + 1e-6), b_feas + 40.0, 0.25)
    i = int(np.argmin([size(b) for b in grid]))
    return golden_min(
        lambda b: (3 * alpha * b + t) * ld_vertices_for(e - ref_eq(b), k),
        grid[max(i - 1, 0)],
        grid[min(i + 1, len(grid) - 1)],
    )


# --- strategies --------------------------------------------------------------------------

ks = st.floats(1.0, 1000.0)
log_sizes = st.floats(3.0, 10.0)
alphas = st.floats(1.0 / 3.0, 1.0)
conn = st.floats(0.0, 8.0)
log_errors = st.floats(-8.0, -1.0)


# --- reference numbers (docs/model.md) ---------------------------------------------------


@pytest.mark.parametrize(
    ("size", "bits", "vertices", "rel_error"),
    [
        (1e4, 7.6997, 369.0, 3.024e-2),
        (1e5, 11.0220, 2697.9, 3.983e-3),
        (1e6, 14.3439, 21262.2, 4.942e-4),
    ],
)
def test_reference_table_size(size, bits, vertices, rel_error):
    p = model.plan_for_size(size, 50.0, alpha=1.0, connectivity_bits=4.0, grid_size=1.0)
    assert p.bits == pytest.approx(bits, abs=1e-4)
    assert p.vertices == pytest.approx(vertices, rel=1e-3)
    assert p.error == pytest.approx(rel_error, rel=1e-3)
    assert p.file_size == pytest.approx(size, rel=1e-12)
    assert p.in_model_domain and p.domain_reason == ""
    assert p.method == "exact" and p.b0 is None


@pytest.mark.parametrize(
    ("err", "bits", "vertices", "size"),
    [(1e-2, 9.5287, 1090.1, 35521.0), (1e-3, 13.2300, 10575.7, 462056.0)],
)
def test_reference_table_error(err, bits, vertices, size):
    p = model.plan_for_error(err, 50.0, alpha=1.0, connectivity_bits=4.0, grid_size=1.0)
    assert p.bits == pytest.approx(bits, abs=1e-4)
    assert p.vertices == pytest.approx(vertices, rel=1e-3)
    assert p.file_size == pytest.approx(size, rel=1e-4)
    assert p.error == pytest.approx(err, rel=1e-12)


def test_grid_size_scales_errors_only():
    a = model.plan_for_error(1e-3, 50.0, grid_size=1.0, alpha=1.0, connectivity_bits=4.0)
    b = model.plan_for_error(1e-3 * 7.5, 50.0, grid_size=7.5, alpha=1.0, connectivity_bits=4.0)
    assert b.bits == pytest.approx(a.bits, rel=1e-12)
    assert b.vertices == pytest.approx(a.vertices, rel=1e-12)
    assert b.error == pytest.approx(7.5 * a.error, rel=1e-12)
    c = model.plan_for_size(1e5, 50.0, grid_size=7.5, alpha=1.0, connectivity_bits=4.0)
    d = model.plan_for_size(1e5, 50.0, grid_size=1.0, alpha=1.0, connectivity_bits=4.0)
    assert c.bits == d.bits and c.quantization_error == pytest.approx(7.5 * d.quantization_error)


# --- elementwise functions ---------------------------------------------------------------


def test_elementwise_formulas_and_broadcasting():
    b = np.array([0.0, 8.0, 12.5])
    v = np.array([[100.0], [1e3], [1e6]])
    assert model.file_size(10, 1000, alpha=0.5, connectivity_bits=2) == 17000.0
    assert np.allclose(model.file_size(b, v, alpha=1.0, connectivity_bits=4.0), (3 * b + 4) * v)
    assert np.allclose(model.quantization_error(b, 2.0), 2.0 * ref_eq(b))
    assert model.sphere_vertices(1000, 50) == pytest.approx(4 * math.pi * 20)
    assert np.allclose(model.tessellation_error(v, 50.0, 3.0), 3.0 * ref_et(v, 50.0))
    assert np.allclose(model.error(b, v, 50.0, grid_size=1.0), ref_eq(b) + ref_et(v, 50.0))
    assert isinstance(model.quantization_error(3, grid_size=1.0), float)
    assert model.tessellation_error(v, 50.0, grid_size=1.0).shape == (3, 1)
    assert model.error(b, v, 50.0, grid_size=1.0).shape == (3, 3)


def test_tessellation_error_is_stable_and_asymptotic():
    k = 37.0
    moderate = np.geomspace(20, 1e4, 50)
    assert np.allclose(
        model.tessellation_error(moderate, k, grid_size=1.0),
        ref_et_textbook(moderate, k),
        rtol=1e-9,
        atol=0,
    )
    huge = np.geomspace(1e6, 1e300, 60)
    # E_T = K / (3 sqrt(3) V) (1 + O(K/V)): exact to rounding once K/V is tiny
    assert np.allclose(
        model.tessellation_error(huge, k, grid_size=1.0), k / (3 * SQ3 * huge), rtol=1e-5
    )
    assert np.allclose(
        model.tessellation_error(huge[10:], k, grid_size=1.0), k / (3 * SQ3 * huge[10:]), rtol=1e-13
    )
    # a sphere of radius S has K = (4 pi S^2 / S) / S = 4 pi, so V_S = V: 12 vertices
    theta = math.sqrt(2 * C / 12)
    assert model.tessellation_error(12, 4 * math.pi, grid_size=1.0) == pytest.approx(
        1 - math.sqrt((1 + 2 * math.cos(theta)) / 3), rel=1e-12
    )
    # a sphere of radius S/2 (grid K = 2 pi): half the error of V_S = 2V vertices on radius S
    assert model.tessellation_error(500, 2 * math.pi, grid_size=1.0) == pytest.approx(
        0.5 * (1 - math.sqrt((1 + 2 * math.cos(math.sqrt(2 * C / 500))) / 3)), rel=1e-3
    )
    # beyond theta = 2 pi / 3 the formula has no meaning: held at S, non-increasing in V
    v = np.geomspace(0.01, 100, 400)
    e = model.tessellation_error(v, 100.0, 2.0)
    assert np.all(np.diff(e) <= 0) and e[0] == 2.0


@given(log_e=st.floats(-15.0, -1e-6), k=ks, s=st.floats(1e-3, 1e3))
@settings(max_examples=60, deadline=None)
def test_vertices_for_error_is_the_exact_inverse(log_e, k, s):
    e = 10.0**log_e
    v = model.vertices_for_error(e * s, k, s)
    assert model.tessellation_error(v, k, s) == pytest.approx(e * s, rel=1e-9)
    assert v == pytest.approx(ref_vertices_for(e, k), rel=1e-9)


def test_vertices_for_error_asymptotic_eq18():
    e = np.geomspace(1e-12, 1e-6, 7)
    assert np.allclose(
        model.vertices_for_error(e, 20.0, grid_size=1.0), 20.0 / (3 * SQ3 * e), rtol=1e-5
    )


def test_optimal_bits_solves_eq12_and_eq13():
    v = np.geomspace(100, 1e9, 30)
    k, alpha, t = 42.0, 0.6, 3.0
    tau = t / (3 * alpha)
    b = model.optimal_bits(v, k, alpha=alpha, connectivity_bits=t)
    theta = np.sqrt(2 * C * k / (4 * np.pi * v))
    h = (1 + 2 * np.cos(theta)) / 3
    rhs12 = np.log2(3 * SQ3 * LN2) + np.log2(h) / 2 - np.log2(theta) - np.log2(np.sin(theta))
    assert np.allclose(b - np.log2(b + tau), rhs12, atol=1e-9)
    b13 = model.optimal_bits(v, k, alpha=alpha, connectivity_bits=t, exact=False)
    assert np.allclose(b13 - np.log2(b13 + tau), np.log2(v / k) + math.log2(4.5 * LN2), atol=1e-12)
    b13p = model.optimal_bits(v, k, alpha=alpha, connectivity_bits=t, exact=False, b0="paper")
    assert np.allclose(b13p - np.log2(b13p + tau), np.log2(v / k) + 1.838, atol=1e-12)
    # vectorised equals elementwise, and the root is on the increasing branch
    assert all(
        model.optimal_bits(vi, k, alpha=alpha, connectivity_bits=t) == bi
        for vi, bi in zip(v[::7], b[::7], strict=True)
    )
    assert np.all(b + tau > 1 / LN2) and np.all(np.diff(b) > 0)


def test_b0_values():
    assert model.DERIVED_B0 == pytest.approx(1.6412, abs=1e-4)
    assert model.DERIVED_B0 == math.log2(4.5 * math.log(2))
    f, k = 1e6, 30.0
    for b0, value in (("derived", model.DERIVED_B0), ("paper", 1.838), (2.5, 2.5)):
        p = model.plan_for_size(
            f, k, alpha=0.5, method="asymptotic", b0=b0, grid_size=1.0, connectivity_bits=4.0
        )
        assert p.b0 == value
        assert p.bits == pytest.approx(math.log2(f / (3 * 0.5 * k)) + value, abs=1e-12)  # Eq. 14
        assert p.vertices == pytest.approx(f / (3 * 0.5 * p.bits + 4), rel=1e-12)  # Eq. 15
    # b0 does not enter the exact solution
    assert model.plan_for_size(
        f, k, b0="paper", grid_size=1.0, alpha=1.0, connectivity_bits=4.0
    ) == model.plan_for_size(f, k, grid_size=1.0, alpha=1.0, connectivity_bits=4.0)


def test_asymptotic_error_plan_is_the_fixed_point():
    e, alpha, t = 1e-4, 0.4, 6.0
    p = model.plan_for_error(
        e, 80.0, alpha=alpha, connectivity_bits=t, method="asymptotic", grid_size=1.0
    )
    tau = t / (3 * alpha)
    assert p.bits == pytest.approx(math.log2(SQ3 * (1 + LN2 * (p.bits + tau)) / (2 * e)), abs=1e-12)
    e_t = e - float(ref_eq(p.bits))
    assert p.vertices == pytest.approx(80.0 / (3 * SQ3 * e_t), rel=1e-12)  # Eq. 18


# --- the solvers against brute force -----------------------------------------------------


@given(k=ks, log_f=log_sizes, alpha=alphas, t=conn)
@FAST
def test_plan_for_size_matches_brute_force(k, log_f, alpha, t):
    f = 10.0**log_f
    p = model.plan_for_size(f, k, alpha=alpha, connectivity_bits=t, grid_size=1.0)
    assume(p.in_model_domain)
    assert p.bits == pytest.approx(brute_size(f, k, alpha, t), abs=1e-6)
    assert p.file_size == pytest.approx(f, rel=1e-12)
    assert p.error == pytest.approx(float(ref_eq(p.bits) + ref_et(p.vertices, k)), rel=1e-12)


@given(k=ks, log_e=log_errors, alpha=alphas, t=conn)
@FAST
def test_plan_for_error_matches_brute_force(k, log_e, alpha, t):
    e = 10.0**log_e
    p = model.plan_for_error(e, k, alpha=alpha, connectivity_bits=t, grid_size=1.0)
    assume(p.in_model_domain)
    assert p.bits == pytest.approx(brute_error(e, k, alpha, t), abs=1e-6)
    assert p.error == pytest.approx(e, rel=1e-9)
    assert p.file_size == pytest.approx((3 * alpha * p.bits + t) * p.vertices, rel=1e-12)


@given(k=ks, log_f=log_sizes, alpha=alphas, t=conn)
@FAST
def test_optimum_lies_on_the_ridge(k, log_f, alpha, t):
    p = model.plan_for_size(10.0**log_f, k, alpha=alpha, connectivity_bits=t, grid_size=1.0)
    assume(p.in_model_domain)
    b = model.optimal_bits(p.vertices, k, alpha=alpha, connectivity_bits=t)
    assert b == pytest.approx(p.bits, abs=1e-9)
    q = model.plan_for_vertices(p.vertices, k, alpha=alpha, connectivity_bits=t, grid_size=1.0)
    assert q.bits == pytest.approx(p.bits, abs=1e-9)
    assert q.file_size == pytest.approx(p.file_size, rel=1e-9)


@given(k=ks, log_f=log_sizes, alpha=alphas, t=conn, log_e=log_errors)
@FAST
def test_asymptotic_relations_at_the_optimum(k, log_f, alpha, t, log_e):
    tau = t / (3 * alpha)
    p = model.plan_for_size(10.0**log_f, k, alpha=alpha, connectivity_bits=t, grid_size=1.0)
    assume(p.in_model_domain)
    v_s = p.sphere_vertices
    # E_T = ln 2 (B + T/(3 alpha)) E_Q, up to O(1/V_S^2)
    ratio = p.tessellation_error / (LN2 * (p.bits + tau) * p.quantization_error)
    assert abs(ratio - 1) <= 2.0 / v_s**2 + 1e-11
    # and the asymptotic solution converges to the exact one at the same rate
    a = model.plan_for_size(
        10.0**log_f, k, alpha=alpha, connectivity_bits=t, method="asymptotic", grid_size=1.0
    )
    assert abs(a.bits - p.bits) <= 4.0 / v_s**2 + 1e-11
    q = model.plan_for_error(10.0**log_e, k, alpha=alpha, connectivity_bits=t, grid_size=1.0)
    r = model.plan_for_error(
        10.0**log_e, k, alpha=alpha, connectivity_bits=t, method="asymptotic", grid_size=1.0
    )
    if q.in_model_domain:
        assert abs(q.bits - r.bits) <= 4.0 / q.sphere_vertices**2 + 1e-11


# --- whole bits --------------------------------------------------------------------------


def _size_cost(p, b):
    v = p.budget / (3 * p.alpha * b + p.connectivity_bits)
    e = ref_et(v, p.k)
    return float(ref_eq(b) + (1.0 if np.isnan(e) else e))


def _error_cost(p, b):
    e_t = p.budget - float(ref_eq(b))
    if e_t <= 0:
        return math.inf
    return (3 * p.alpha * b + p.connectivity_bits) * model.vertices_for_error(
        e_t, p.k, grid_size=1.0
    )


def _neighbours(w):
    return [b for b in (w - 1, w + 1) if b >= 1]


@given(k=ks, log_f=log_sizes, alpha=alphas, t=conn)
@settings(max_examples=100, deadline=None)
def test_whole_bits_size_never_worse_than_neighbours(k, log_f, alpha, t):
    p = model.plan_for_size(10.0**log_f, k, alpha=alpha, connectivity_bits=t, grid_size=1.0)
    assume(p.in_model_domain)
    w = p.whole_bits
    assert w in (math.floor(p.bits), math.ceil(p.bits))
    assert p.whole_file_size == pytest.approx(p.budget, rel=1e-12)
    assert p.whole_error == pytest.approx(_size_cost(p, w), rel=1e-12)
    assert p.whole_error >= p.error * (1 - 1e-12)
    for b in _neighbours(w):
        assert _size_cost(p, w) <= _size_cost(p, b)


@given(k=ks, log_e=log_errors, alpha=alphas, t=conn)
@settings(max_examples=100, deadline=None)
def test_whole_bits_error_never_worse_than_neighbours(k, log_e, alpha, t):
    p = model.plan_for_error(10.0**log_e, k, alpha=alpha, connectivity_bits=t, grid_size=1.0)
    assume(p.in_model_domain)
    w = p.whole_bits
    assert w in (math.floor(p.bits), math.ceil(p.bits))
    assert p.whole_error == pytest.approx(p.budget, rel=1e-9)
    assert p.whole_file_size == pytest.approx(_error_cost(p, w), rel=1e-12)
    assert p.whole_file_size >= p.file_size * (1 - 1e-12)
    for b in _neighbours(w):
        assert _error_cost(p, w) <= _error_cost(p, b)


@given(k=ks, log_v=st.floats(1.5, 9.0), alpha=alphas, t=conn)
@settings(max_examples=100, deadline=None)
def test_whole_bits_vertices_never_worse_than_neighbours(k, log_v, alpha, t):
    p = model.plan_for_vertices(10.0**log_v, k, alpha=alpha, connectivity_bits=t, grid_size=1.0)
    assume(p.in_model_domain)
    price = LN2 * float(ref_eq(p.bits))  # the Lagrange multiplier times 3 alpha V

    def cost(b):
        return float(ref_eq(b)) + price * b

    assert p.whole_vertices == p.vertices
    for b in _neighbours(p.whole_bits):
        assert cost(p.whole_bits) <= cost(b)


# --- monotonicity ------------------------------------------------------------------------


@given(k=ks, log_f=log_sizes, grow=st.floats(1e-9, 10.0), alpha=alphas, t=conn)
@settings(max_examples=80, deadline=None)
def test_more_size_never_more_error(k, log_f, grow, alpha, t):
    f = 10.0**log_f
    kw = {"alpha": alpha, "connectivity_bits": t, "grid_size": 1.0}
    small, big = model.plan_for_size(f, k, **kw), model.plan_for_size(f * (1 + grow), k, **kw)
    assert big.error <= small.error * (1 + 1e-12)
    assert big.whole_error <= small.whole_error * (1 + 1e-12)
    assert big.bits >= small.bits - 1e-12


@given(k=ks, log_e=log_errors, grow=st.floats(1e-9, 5.0), alpha=alphas, t=conn)
@settings(max_examples=80, deadline=None)
def test_more_error_never_more_size(k, log_e, grow, alpha, t):
    e = 10.0**log_e
    kw = {"alpha": alpha, "connectivity_bits": t, "grid_size": 1.0}
    tight = model.plan_for_error(e, k, **kw)
    loose = model.plan_for_error(min(e * (1 + grow), 0.5), k, **kw)
    assert loose.file_size <= tight.file_size * (1 + 1e-12)
    assert loose.whole_file_size <= tight.whole_file_size * (1 + 1e-12)


@given(k=ks, grow=st.floats(1e-6, 10.0), log_e=log_errors, alpha=alphas, t=conn)
@settings(max_examples=80, deadline=None)
def test_larger_k_never_fewer_vertices(k, grow, log_e, alpha, t):
    e = 10.0**log_e
    kw = {"alpha": alpha, "connectivity_bits": t, "grid_size": 1.0}
    simple, complex_ = (
        model.plan_for_error(e, k, **kw),
        model.plan_for_error(e, k * (1 + grow), **kw),
    )
    assert complex_.vertices >= simple.vertices
    assert complex_.whole_vertices >= simple.whole_vertices
    # for an error budget the optimal B does not depend on K at all; V is proportional to K
    assert complex_.bits == pytest.approx(simple.bits, abs=1e-12)
    assert complex_.vertices == pytest.approx(simple.vertices * (1 + grow), rel=1e-9)


@given(k=ks, log_v=st.floats(1.0, 9.0), grow=st.floats(1e-6, 10.0), alpha=alphas, t=conn)
@settings(max_examples=60, deadline=None)
def test_more_vertices_more_bits_less_error(k, log_v, grow, alpha, t):
    v = max(10.0**log_v, 4.0)
    kw = {"alpha": alpha, "connectivity_bits": t, "grid_size": 1.0}
    few, many = (
        model.plan_for_vertices(v, k, **kw),
        model.plan_for_vertices(v * (1 + grow), k, **kw),
    )
    assert many.bits >= few.bits
    assert many.error <= few.error


# --- domain and bad input ----------------------------------------------------------------


def test_domain_flags():
    p = model.plan_for_size(1e4, 1000.0, grid_size=1.0, alpha=1.0, connectivity_bits=4.0)
    assert not p.in_model_domain
    assert "V_S" in p.domain_reason and "< 12" in p.domain_reason
    q = model.plan_for_vertices(4, 50.0, grid_size=1.0, alpha=1.0, connectivity_bits=4.0)
    assert not q.in_model_domain and "lowest allowed B" in q.domain_reason
    r = model.plan_for_error(0.5, 50.0, grid_size=1.0, alpha=1.0, connectivity_bits=4.0)
    assert not r.in_model_domain
    ok = model.plan_for_vertices(
        12 * 50 / (4 * math.pi) * 1.001, 50.0, grid_size=1.0, alpha=1.0, connectivity_bits=4.0
    )
    assert ok.in_model_domain and ok.sphere_vertices >= 12


def test_to_dict_is_json_ready():
    d = model.plan_for_size(1e5, 50.0, grid_size=1.0, alpha=1.0, connectivity_bits=4.0).to_dict()
    assert json.loads(json.dumps(d)) == d
    for key in (
        "bits",
        "vertices",
        "file_size",
        "error",
        "quantization_error",
        "tessellation_error",
        "whole_bits",
        "whole_vertices",
        "k",
        "grid_size",
        "alpha",
        "connectivity_bits",
        "b0",
        "method",
        "in_model_domain",
        "domain_reason",
    ):
        assert key in d
    assert isinstance(d["whole_bits"], int)


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (
            lambda: model.plan_for_size(
                27.9, 50.0, grid_size=1.0, alpha=1.0, connectivity_bits=4.0
            ),
            "cannot hold even a tetrahedron",
        ),
        (
            lambda: model.plan_for_size(11.9, 50.0, connectivity_bits=0, grid_size=1.0, alpha=1.0),
            "tetrahedron",
        ),
        (
            lambda: model.plan_for_size(0, 50.0, grid_size=1.0, alpha=1.0, connectivity_bits=4.0),
            "size_bits must be positive",
        ),
        (
            lambda: model.plan_for_error(
                0.0, 50.0, grid_size=1.0, alpha=1.0, connectivity_bits=4.0
            ),
            "error must be positive",
        ),
        (
            lambda: model.plan_for_error(
                -1e-3, 50.0, grid_size=1.0, alpha=1.0, connectivity_bits=4.0
            ),
            "error must be positive",
        ),
        (
            lambda: model.plan_for_error(
                1.0, 50.0, grid_size=1.0, alpha=1.0, connectivity_bits=4.0
            ),
            "below the grid size",
        ),
        (
            lambda: model.plan_for_error(
                3.0, 50.0, grid_size=2.0, alpha=1.0, connectivity_bits=4.0
            ),
            "below the grid size",
        ),
        (
            lambda: model.plan_for_error(
                math.nan, 50.0, grid_size=1.0, alpha=1.0, connectivity_bits=4.0
            ),
            "error must be positive and finite",
        ),
        (
            lambda: model.plan_for_size(1e5, 0.0, grid_size=1.0, alpha=1.0, connectivity_bits=4.0),
            "k must be positive",
        ),
        (
            lambda: model.plan_for_size(1e5, -3.0, grid_size=1.0, alpha=1.0, connectivity_bits=4.0),
            "k must be positive",
        ),
        (
            lambda: model.plan_for_size(
                1e5, math.inf, grid_size=1.0, alpha=1.0, connectivity_bits=4.0
            ),
            "k must be positive and finite",
        ),
        (
            lambda: model.plan_for_size(
                1e5, math.nan, grid_size=1.0, alpha=1.0, connectivity_bits=4.0
            ),
            "k must be positive and finite",
        ),
        (
            lambda: model.plan_for_size(1e5, 50.0, alpha=0.0, grid_size=1.0, connectivity_bits=4.0),
            r"alpha must be in \(0, 1\]",
        ),
        (
            lambda: model.plan_for_size(
                1e5, 50.0, alpha=1.01, grid_size=1.0, connectivity_bits=4.0
            ),
            r"alpha must be in \(0, 1\]",
        ),
        (
            lambda: model.plan_for_error(
                1e-3, 50.0, alpha=-1, grid_size=1.0, connectivity_bits=4.0
            ),
            "alpha",
        ),
        (
            lambda: model.plan_for_size(1e5, 50.0, connectivity_bits=-1, grid_size=1.0, alpha=1.0),
            "connectivity_bits",
        ),
        (
            lambda: model.plan_for_size(1e5, 50.0, grid_size=0, alpha=1.0, connectivity_bits=4.0),
            "grid_size",
        ),
        (
            lambda: model.plan_for_size(
                1e5, 50.0, method="newton", grid_size=1.0, alpha=1.0, connectivity_bits=4.0
            ),
            "method must be one of",
        ),
        (
            lambda: model.plan_for_size(
                1e5, 50.0, b0="guess", grid_size=1.0, alpha=1.0, connectivity_bits=4.0
            ),
            "b0 must be",
        ),
        (
            lambda: model.plan_for_size(
                1e5, 50.0, b0=math.inf, grid_size=1.0, alpha=1.0, connectivity_bits=4.0
            ),
            "b0 must be finite",
        ),
        (
            lambda: model.plan_for_vertices(
                3.5, 50.0, grid_size=1.0, alpha=1.0, connectivity_bits=4.0
            ),
            "at least 4 vertices",
        ),
        (lambda: model.vertices_for_error(1.0, 50.0, grid_size=1.0), "below the grid size"),
        (
            lambda: model.vertices_for_error([1e-3, 0.0], 50.0, grid_size=1.0),
            r"error must be .*1 of 2",
        ),
        (lambda: model.tessellation_error(0, 50.0, grid_size=1.0), "vertices must be positive"),
        (
            lambda: model.optimal_bits(100, [1.0, -1.0], alpha=1.0, connectivity_bits=4.0),
            "k must be positive",
        ),
        (lambda: model.guaranteed_bits(0.0, grid_size=1.0), "error must be positive"),
    ],
)
def test_bad_constraints_raise_value_error(call, match):
    with pytest.raises(ValueError, match=match):
        call()


@pytest.mark.parametrize(
    "call",
    [
        lambda: model.plan_for_size("1e5", 50.0, grid_size=1.0, alpha=1.0, connectivity_bits=4.0),
        lambda: model.plan_for_size(None, 50.0, grid_size=1.0, alpha=1.0, connectivity_bits=4.0),
        lambda: model.plan_for_size(
            [1e5, 1e6], 50.0, grid_size=1.0, alpha=1.0, connectivity_bits=4.0
        ),
        lambda: model.quantization_error(np.array(["a"]), grid_size=1.0),
        lambda: model.plan_for_size(
            1e5, 50.0, b0=None, grid_size=1.0, alpha=1.0, connectivity_bits=4.0
        ),
    ],
)
def test_bad_types_raise_type_error(call):
    with pytest.raises(TypeError):
        call()


# --- guaranteed bits ---------------------------------------------------------------------


def _worst_move(bits, s):
    return SQ3 / 2.0 * s / (2.0**bits - 1)


@given(log_e=st.floats(-9.0, 0.5), s=st.floats(1e-3, 1e3))
@settings(max_examples=100, deadline=None)
def test_guaranteed_bits_is_the_smallest_safe_b(log_e, s):
    e = 10.0**log_e * s
    b = model.guaranteed_bits(e, s)
    assert isinstance(b, int) and b >= 1
    assert _worst_move(b, s) <= e
    if b > 1:
        assert _worst_move(b - 1, s) > e
    assert b == max(1, math.ceil(math.log2(SQ3 * s / (2 * e) + 1))) or _worst_move(b, s) == e


def test_guaranteed_bits_exact_boundary_and_arrays():
    for b in (1, 2, 7, 12, 20):
        assert model.guaranteed_bits(_worst_move(b, 1.0), grid_size=1.0) == b
        assert model.guaranteed_bits(_worst_move(b, 1.0) * (1 - 1e-9), grid_size=1.0) == b + 1
    out = model.guaranteed_bits(np.array([2.0, 1.0, 1e-3, 1e-6]), 2.0)
    assert out.dtype == np.int64 and out.tolist() == [1, 2, 11, 21]


def test_guaranteed_bits_bounds_a_real_quantizer():
    rng = np.random.default_rng(5)
    lo, s = np.array([-1.0, 2.0, 0.5]), 3.0
    pts = lo + rng.random((20000, 3)) * s
    for e in (0.05, 1e-3, 2e-5):
        b = model.guaranteed_bits(e, s)
        n = 2**b - 1
        q = np.round((pts - lo) * n / s)
        moved = np.linalg.norm(lo + q * s / n - pts, axis=1).max()
        assert moved <= e
        # one bit fewer: the centre of a grid cell moves by the bound itself, over e
        n1 = 2 ** (b - 1) - 1
        centre = lo + 0.5 * s / n1
        q1 = np.round((centre - lo) * n1 / s + 1e-12)
        assert np.linalg.norm(lo + q1 * s / n1 - centre) > e


# --- public names ------------------------------------------------------------------------


def test_public_names():
    for name in (
        "Allocation",
        "guaranteed_bits",
        "plan_for_error",
        "plan_for_size",
        "plan_for_vertices",
        "model",
    ):
        assert name in meshbits.__all__ and hasattr(meshbits, name)
    assert meshbits.plan_for_size is model.plan_for_size
    for name in model.__all__:
        assert hasattr(model, name)


# --- docs --------------------------------------------------------------------------------


def test_docs_reference_table_is_what_the_code_prints(capsys):
    text = DOCS.read_text()
    code = re.search(r"```python\n(.*?)```", text, re.S).group(1)
    exec(compile(code, str(DOCS), "exec"), {})
    lines = [line for line in capsys.readouterr().out.splitlines() if line.strip()]
    assert len(lines) >= 8
    for line in lines:
        assert line in text, f"docs/model.md is out of date: {line!r} missing"


# --- refusals found by the fuzz campaign (benches/fuzz.py) --------------------------------


@pytest.mark.parametrize(
    ("plan", "args", "kwargs"),
    [
        # Each raised something else: TypeError from exp2 of a 30-digit int, RuntimeError
        # "could not bracket the root", OverflowError from floor(inf) after a warning.
        (model.plan_for_size, (1e30, 5e-324), {}),
        (model.plan_for_size, (1e300, 1e-300), {"method": "asymptotic"}),
        (model.plan_for_vertices, (1e30, 5e-324), {}),
        (model.plan_for_vertices, (1e300, 1e-300), {"method": "asymptotic"}),
        (model.plan_for_error, (5e-324, 10.0), {"grid_size": 1.5}),
    ],
)
def test_plans_beyond_the_float64_range_are_refused(plan, args, kwargs):
    with pytest.raises(meshbits.MeshbitsError, match="model's numeric range"):
        plan(*args, **{"grid_size": 1.0, **kwargs})


def test_plans_near_the_float64_range_still_answer():
    plan = model.plan_for_error(1e-300, 10.0, grid_size=1.0, alpha=1.0, connectivity_bits=4.0)
    assert 1000 < plan.bits < model.MODEL_MAX_BITS and math.isfinite(plan.vertices)


def test_the_size_model_parameters_are_checked_as_single_numbers():
    """compress and the plans check alpha and T the same way (model.size_model_parameters)."""
    assert model.size_model_parameters(0.5, 4) == (0.5, 4.0)
    with pytest.raises(meshbits.MeshbitsError, match="alpha must be in"):
        model.size_model_parameters(1.5, 4)
    with pytest.raises(meshbits.MeshbitsError, match="connectivity_bits must be finite"):
        model.size_model_parameters(0.5, -1)
    with pytest.raises(TypeError, match="alpha must be a single number"):
        model.size_model_parameters([0.5, 0.6], 4)
