"""Tests of ``meshbits plan`` (meshbits.cli.plan): the model's plan for a mesh file, as a
table or JSON, and its one-line refusals; the plans themselves are tested in test_model.py
and test_planning.py."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import meshbits
from meshbits import model
from meshbits.cli import main

DATA = Path(__file__).parent / "data"
MESH = str(DATA / "bunny_res4.ply")


def _json(capsys, argv):
    assert main([*argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_cli_plan_json(capsys):
    ref = meshbits.shape_complexity(meshbits.load_mesh(MESH))
    out = _json(
        capsys, ["plan", MESH, "--size", "10KB", "--alpha", "0.5", "--connectivity-bits", "3"]
    )
    expected = model.plan_for_size(
        80_000.0, ref.k, grid_size=ref.grid_size, alpha=0.5, connectivity_bits=3.0
    )
    assert out == {
        "mesh": MESH,
        "length_unit": "mesh units",
        "mesh_vertices": out["mesh_vertices"],
        "mesh_faces": out["mesh_faces"],
        "estimator": "circumsphere",
        **expected.to_dict(),
        "size_unit": "bits",
        "file_size_bytes": expected.file_size / 8,
        "whole_file_size_bytes": expected.whole_file_size / 8,
        "budget_unit": "bits",
    }
    assert out["mesh_vertices"] > 0 and out["k"] == ref.k

    rel = _json(capsys, ["plan", MESH, "--error", "0.002", "--relative"])
    assert rel["constraint"] == "error" and rel["budget_unit"] == "mesh units"
    assert rel["budget"] == pytest.approx(0.002 * ref.grid_size)
    assert rel["error"] == pytest.approx(0.002 * ref.grid_size, rel=1e-9)
    absolute = _json(capsys, ["plan", MESH, "--error", str(0.002 * ref.grid_size)])
    assert absolute["bits"] == pytest.approx(rel["bits"], abs=1e-9)

    ver = _json(
        capsys,
        [
            "plan",
            MESH,
            "--vertices",
            "500",
            "--method",
            "asymptotic",
            "--b0",
            "paper",
            "--estimator",
            "hybrid",
        ],
    )
    assert ver["constraint"] == "vertices" and ver["b0"] == 1.838
    assert ver["budget_unit"] == "vertices"
    assert ver["estimator"] == "hybrid"


def test_cli_plan_table(capsys):
    assert main(["plan", MESH, "--size", "4KiB"]) == 0
    out = capsys.readouterr().out
    assert "continuous" in out and "whole bits" in out and "E_T" in out
    ref = meshbits.shape_complexity(meshbits.load_mesh(MESH))
    whole = model.plan_for_size(32768.0, ref.k, grid_size=ref.grid_size)  # Draco's fit
    assert f"quantize to {whole.whole_bits} bits" in out


def test_plan_and_compress_share_one_size_model(capsys):
    """`meshbits plan` printed alpha = 1, T = 4 (the paper's) while compress started from
    Draco's fit: on bunny --size 20KB plan said V = 4,324, compress delivered 6,763."""
    from meshbits.constants import DRACO_ALPHA, DRACO_CONNECTIVITY_BITS

    out = _json(capsys, ["plan", MESH, "--size", "6KB"])
    assert (out["alpha"], out["connectivity_bits"]) == (DRACO_ALPHA, DRACO_CONNECTIVITY_BITS)
    result = meshbits.compress(meshbits.load_mesh(MESH), size=48_000, max_iterations=1)
    assert result.plan is not None
    assert result.plan.whole_bits == out["whole_bits"]
    assert result.plan.whole_vertices == pytest.approx(out["whole_vertices"], rel=1e-12)
    paper = _json(
        capsys, ["plan", MESH, "--size", "6KB", "--alpha", "1", "--connectivity-bits", "4"]
    )
    assert paper["whole_vertices"] < out["whole_vertices"]


@pytest.mark.parametrize("fmt", ["ply", "glb"])
def test_plan_for_a_fixed_width_format_predicts_the_bytes_compress_writes(capsys, fmt):
    """glb and ply store positions in fixed-width fields: the plan's size for its V is the
    size of the file compress writes at that V, within the header's few digits."""
    out = _json(capsys, ["plan", MESH, "--format", fmt, "--size", "6KB"])
    assert out["bits"] == meshbits.constants.FORMAT_MAX_BITS[fmt]
    assert out["file_size"] == pytest.approx(48_000, rel=1e-6)
    result = meshbits.compress(
        meshbits.load_mesh(MESH), vertices=round(out["vertices"]), format=fmt
    )
    assert result.size_bits == pytest.approx(out["file_size"], rel=0.06)  # V within 5%
    absolute = _json(capsys, ["plan", MESH, "--format", fmt, "--error", "0.004", "--relative"])
    assert absolute["error"] == pytest.approx(0.004 * out["grid_size"], rel=1e-9)
    assert main(["plan", MESH, "--format", fmt, "--size", "6KB", "--alpha", "0.5"]) == 2
    assert "model Draco" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--size", "100kb"], "ambiguous"),
        (["--size", "100"], "needs a unit"),
        (["--size", "4bit"], "tetrahedron"),
        (["--error", "2", "--relative"], "below the grid size"),
        (["--error", "-1"], "length '-1' must be positive and finite"),
        (["--vertices", "2"], "at least 4 vertices"),
        (["--size", "10KB", "--alpha", "2"], "alpha"),
        (["--size", "10KB", "--relative"], "--relative applies to --error only"),
    ],
)
def test_cli_plan_bad_input_exits_2(capsys, argv, message):
    assert main(["plan", MESH, *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1


def test_cli_plan_missing_mesh_exits_2(capsys, tmp_path):
    assert main(["plan", str(tmp_path / "nope.ply"), "--size", "10KB"]) == 2
    assert capsys.readouterr().err.startswith("meshbits plan: error:")


def test_cli_plan_needs_one_budget(capsys):
    assert main(["plan", MESH, "--size", "10KB", "--error", "0.1"]) == 2
    err = capsys.readouterr().err
    assert "not allowed with argument" in err and len(err.strip().splitlines()) == 1


def test_cli_plan_flat_mesh_exits_2(capsys, tmp_path):
    path = tmp_path / "square.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n")
    assert main(["plan", str(path), "--size", "10KB"]) == 2
    assert "no plan" in capsys.readouterr().err
