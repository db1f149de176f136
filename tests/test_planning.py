"""Tests of meshbits.planning: the plans of fixed-width outputs (glb without a codec, PLY),
against the size function of meshbits.codecs searched by brute force over V."""

from __future__ import annotations

import math

import pytest

import meshbits
from meshbits import model
from meshbits.budget import Budget
from meshbits.codecs import fixed_width_size_bits
from meshbits.constants import FORMAT_MAX_BITS, MODEL_MIN_VERTICES
from meshbits.planning import FixedWidthSizes, plan_fixed_width


@pytest.mark.parametrize("fmt", ["ply", "glb"])
def test_a_fixed_width_plan_spends_a_size_on_vertices(fmt):
    sizes = FixedWidthSizes(fmt, 2.0)
    plan = plan_fixed_width(Budget.from_options(size=48_000), 10.0, 1.0, fmt, 2.0)
    assert plan.bits == FORMAT_MAX_BITS[fmt] and plan.constraint == "size"
    assert plan.file_size == pytest.approx(48_000, rel=1e-9) and plan.file_size <= 48_000
    assert plan.file_size == fixed_width_size_bits(fmt, plan.bits, plan.vertices, 2 * plan.vertices)
    assert plan.error == plan.quantization_error + plan.tessellation_error
    with pytest.raises(meshbits.MeshbitsError, match="cannot hold a tetrahedron"):
        sizes.vertices_for_size(sizes.size_bits(MODEL_MIN_VERTICES) - 1)


def test_a_fixed_width_plan_for_an_error_meets_it():
    plan = plan_fixed_width(Budget.from_options(error=0.01, relative=True), 10.0, 2.0, "ply", 2.0)
    assert plan.budget == 0.02 and plan.error == pytest.approx(0.02, rel=1e-9)
    with pytest.raises(meshbits.MeshbitsError, match="not below the grid size"):
        plan_fixed_width(Budget.from_options(error=3.0), 10.0, 2.0, "ply", 2.0)
    with pytest.raises(meshbits.MeshbitsError, match="quantization error"):
        plan_fixed_width(Budget.from_options(error=1e-12), 10.0, 2.0, "ply", 2.0)


def _most_vertices_within(fmt: str, faces_per_vertex: float, size_bits: float) -> int:
    """The largest whole V whose file fits in ``size_bits``: every V tried in turn."""
    bits = FORMAT_MAX_BITS[fmt]
    best = None
    for vertices in range(math.ceil(MODEL_MIN_VERTICES), 100_000):
        if fixed_width_size_bits(fmt, bits, vertices, vertices * faces_per_vertex) > size_bits:
            break
        best = vertices
    assert best is not None and vertices < 99_999, "the scan must end past the budget"
    return best


@pytest.mark.parametrize("fmt", ["ply", "glb"])
@pytest.mark.parametrize(
    ("size_bits", "faces_per_vertex"), [(48_000, 2.0), (1_000_003, 1.97), (123_456, 1.5)]
)
def test_a_fixed_width_size_plan_is_the_most_whole_vertices_that_fit(
    fmt, size_bits, faces_per_vertex
):
    plan = plan_fixed_width(Budget.from_options(size=size_bits), 3.0, 1.0, fmt, faces_per_vertex)
    assert math.floor(plan.vertices) == _most_vertices_within(fmt, faces_per_vertex, size_bits)
    sizes = FixedWidthSizes(fmt, faces_per_vertex)
    assert sizes.bits == FORMAT_MAX_BITS[fmt]
    assert sizes.size_bits(plan.vertices) <= size_bits


@pytest.mark.parametrize("fmt", ["ply", "glb"])
def test_a_fixed_width_vertex_plan_keeps_the_count_and_costs_its_size(fmt):
    plan = plan_fixed_width(Budget.from_options(vertices=500), 10.0, 2.0, fmt, 2.0)
    assert plan.vertices == 500 and plan.bits == FORMAT_MAX_BITS[fmt]
    assert plan.file_size == fixed_width_size_bits(fmt, plan.bits, 500, 1000)
    assert plan.quantization_error == pytest.approx((math.sqrt(3) / 2) * 2.0 * 2.0**-plan.bits)
    assert plan.tessellation_error == float(model.tessellation_error(500, 10.0, 2.0))


def test_a_fixed_width_plan_needs_a_fixed_width_format():
    with pytest.raises(meshbits.MeshbitsError, match="format must be one of"):
        plan_fixed_width(Budget.from_options(size=48_000), 10.0, 1.0, "draco", 2.0)
