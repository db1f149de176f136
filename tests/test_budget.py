"""The budget value (meshbits.budget): one budget checked once, resolved against S."""

from __future__ import annotations

import math

import pytest

import meshbits
from meshbits.budget import Budget


def test_one_budget_is_checked_once_and_resolved_against_s():
    relative = Budget.from_options(error=0.01, relative=True)
    assert (relative.kind, relative.value, relative.relative) == ("error", 0.01, True)
    assert relative.resolve(2.0) == 0.02
    assert relative.describe() == "0.01 x S" and relative.text == "0.01 x S"
    size = Budget.from_options(size=160_000, relative=True)  # relative ignored for a size
    assert size.relative is False and size.resolve(2.0) == 160_000
    assert size.to_dict() == {"budget_text": "20000 bytes", "budget_unit": "bits"}
    vertices = Budget.from_options(vertices=500)
    assert vertices.describe() == "500 vertices" and vertices.unit == "vertices"
    metres = Budget.from_options(error=0.002, length_unit="m", text="--error 2mm")
    assert metres.to_dict() == {"budget_text": "--error 2mm", "budget_unit": "m"}


@pytest.mark.parametrize(
    ("options", "error", "message"),
    [
        ({}, meshbits.MeshbitsError, r"exactly one of size, error, vertices \(got none\)"),
        ({"size": 1, "error": 1}, meshbits.MeshbitsError, r"got \['size', 'error'\]"),
        ({"error": -1}, meshbits.MeshbitsError, "positive finite number, got -1"),
        ({"error": math.nan}, meshbits.MeshbitsError, "positive finite number, got nan"),
        ({"size": 10**400}, meshbits.MeshbitsError, "positive finite number"),
        ({"error": "1mm"}, TypeError, "parse_length"),
        ({"vertices": True}, TypeError, "a vertex count"),
    ],
)
def test_a_bad_budget_is_refused_in_one_line(options, error, message):
    with pytest.raises(error, match=message):
        Budget.from_options(**options)


def test_text_budgets_and_a_stray_relative_where_an_entry_point_asks():
    kinds = ("error", "size")
    size = Budget.from_options(size="4KB", kinds=kinds, parse_text=True)
    assert size.value == 32_000
    error = Budget.from_options(error="5cm", kinds=kinds, parse_text=True)
    assert error.value == pytest.approx(0.05)
    with pytest.raises(meshbits.MeshbitsError, match="has a unit"):
        Budget.from_options(error="5cm", relative=True, kinds=kinds, parse_text=True)
    with pytest.raises(meshbits.MeshbitsError, match="relative applies to an error budget"):
        Budget.from_options(size="4KB", relative=True, parse_text=True, refuse_stray_relative=True)
    with pytest.raises(meshbits.MeshbitsError, match=r"exactly one of error, size \(got none\)"):
        Budget.from_options(vertices=5, kinds=kinds)
