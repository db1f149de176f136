"""Tests of meshbits.units: sizes and lengths as people type them (``"100KB"``, ``"1mm"``)."""

from __future__ import annotations

import pytest

import meshbits
from meshbits.units import LENGTH_UNITS, length_unit_of

# --- sizes (bits) ------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "bits"),
    [
        ("100KB", 800_000.0),
        ("100kB", 800_000.0),
        ("2MiB", 16 * 2**20),
        ("2 MiB", 16 * 2**20),
        ("80kbit", 80_000.0),
        ("1.5 kbits", 1_500.0),
        ("1e3 bytes", 8_000.0),
        ("12B", 96.0),
        ("1GB", 8e9),
        ("3 bits", 3.0),
        (".5KiB", 4096.0),
    ],
)
def test_parse_size(text, bits):
    assert meshbits.parse_size(text) == bits


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("100", "needs a unit"),
        ("100kb", "ambiguous"),
        ("100 b", "ambiguous"),
        ("100XB", "unknown prefix"),
        ("0KB", "positive"),
        ("-5KB", "cannot read"),
        ("KB", "cannot read"),
        ("1e999KB", "positive and finite"),
    ],
)
def test_parse_size_refuses(text, match):
    with pytest.raises(ValueError, match=match):
        meshbits.parse_size(text)


# --- lengths (meters when a unit is typed) ----------------------------------------------


@pytest.mark.parametrize(
    ("text", "length"),
    [("0.002", 0.002), ("1mm", 0.001), (" 0.5 cm", 0.005), ("2in", 0.0508), ("1e-3M", 0.001)],
)
def test_parse_length(text, length):
    assert meshbits.parse_length(text) == pytest.approx(length, rel=1e-12)


@pytest.mark.parametrize("text", ["", "mm", "-1mm", "0", "1 parsec", "nan", "inf m"])
def test_parse_length_refuses(text):
    with pytest.raises(meshbits.MeshbitsError, match="length"):
        meshbits.parse_length(text)


def test_length_units_are_meters_and_glTF_files_are_in_meters():
    assert LENGTH_UNITS["m"] == 1.0 and LENGTH_UNITS["mm"] == 1e-3 and LENGTH_UNITS["in"] == 0.0254
    for unit, meters in LENGTH_UNITS.items():
        assert meshbits.parse_length(f"1{unit}") == pytest.approx(meters, rel=1e-12)
    assert length_unit_of("scene.GLB") == "m" and length_unit_of("a/b.gltf") == "m"
    assert length_unit_of("bunny.ply") == "mesh units" and length_unit_of("x.obj") == "mesh units"
