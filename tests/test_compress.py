"""The paper's Sec. 7 loop end to end, on real meshes, and its command line."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
import pytest
import trimesh
from conftest import load

import meshbits
from meshbits.cli import main
from meshbits.codecs import encode, encode_draco
from meshbits.compress import compress
from meshbits.formats.drc import decode_draco
from meshbits.hausdorff import default_samples
from meshbits.simplify import simplify

DATA = Path(__file__).parent / "data"
SPOT = meshbits.load_mesh(meshbits.example_mesh_path())


@pytest.mark.parametrize(
    ("name", "relative_error"),
    [("spot", 0.002), ("spot", 0.01), ("bunny.ply", 0.003), ("horse.ply", 0.002)],
)
def test_error_budget_is_met_and_checked_independently(name, relative_error):
    mesh = SPOT if name == "spot" else load(name)
    result = compress(mesh, error=relative_error, relative=True)
    budget = relative_error * result.complexity.grid_size
    assert result.budget == pytest.approx(budget)
    assert result.met, result.message
    assert result.error <= budget
    # Independent check: decode the real file and measure again with another seed and
    # more samples.
    decoded = decode_draco(result.data)
    again = meshbits.hausdorff(mesh, decoded, seed=12345, samples=200_000)
    assert again.distance <= 1.05 * budget
    # No larger than the original quantized to the fewest bits that meet the budget.
    grid = meshbits.cube_grid(mesh[0].min(axis=0), mesh[0].max(axis=0))
    for bits in range(6, 20):
        whole = encode_draco(mesh, bits, origin=grid[0], grid_size=grid[1])
        if meshbits.hausdorff(mesh, (whole.vertices, whole.faces)).distance <= budget:
            break
    assert result.size_bytes <= whole.size_bytes


@pytest.mark.parametrize(("name", "size_bytes"), [("spot", 6_000), ("bunny.ply", 20_000)])
def test_size_budget_is_met_by_the_real_file(name, size_bytes):
    mesh = SPOT if name == "spot" else load(name)
    result = compress(mesh, size=8 * size_bytes)
    assert result.met, result.message
    assert len(result.data) <= size_bytes
    assert len(result.data) >= 0.6 * size_bytes  # the budget is used, not wasted
    vertices, faces = decode_draco(result.data)
    np.testing.assert_array_equal(vertices, result.vertices)
    samples = default_samples(len(mesh[1]))
    again = meshbits.hausdorff(mesh, (vertices, faces), samples=samples, statistics=False)
    # Bounding the error evaluates more points than the samples, which can only raise it.
    assert again.distance * (1 - 1e-12) <= result.error <= result.error_upper
    # Without certification: same seed, same samples, the same number, up to the rounding
    # of measuring the original's stored samples in the output's frame. (The answers can
    # differ: with certification the least certified bound decides.)
    sampled = compress(mesh, size=8 * size_bytes, certify=False)
    assert sampled.error_upper is None and len(sampled.data) <= size_bytes
    mine = meshbits.hausdorff(mesh, decode_draco(sampled.data), samples=samples, statistics=False)
    assert sampled.error == pytest.approx(mine.distance, rel=1e-12)


def test_vertex_budget_uses_the_models_bits():
    result = compress(SPOT, vertices=1000)
    assert abs(len(result.vertices) - 1000) <= 50
    assert result.bits == result.plan.whole_bits
    assert len(result.iterations) == 1 and result.met


def test_certified_error_budget():
    result = compress(SPOT, error=0.003, relative=True, certify=True)
    assert result.met
    assert result.error <= result.error_upper <= result.budget
    # The certified bound holds against a dense independent measurement.
    dense = meshbits.hausdorff(SPOT, (result.vertices, result.faces), samples=300_000, seed=99)
    assert dense.distance <= result.error_upper


@pytest.mark.parametrize("budget", [{"size": 8 * 6_000}, {"vertices": 800}])
def test_size_and_vertex_answers_carry_a_certified_error_bound(budget):
    """Their printed error was the sampled one only, below the true distance (the bunny at
    --vertices 5000: 3.95e-4 printed, 4.63e-4 certified)."""
    result = compress(SPOT, **budget)
    assert result.met and result.error_upper is not None
    assert result.error <= result.error_upper <= 1.05 * result.error
    dense = meshbits.hausdorff(SPOT, (result.vertices, result.faces), samples=300_000, seed=99)
    assert dense.distance <= result.error_upper
    fast = compress(SPOT, **budget, certify=False)
    assert fast.error_upper is None and fast.size_bits == result.size_bits
    expected_bytes = budget["size"] / 8 if "size" in budget else None
    assert result.to_dict()["budget_bytes"] == expected_bytes
    if "size" in budget:
        # The answer is the least error, bounds compared with bounds: no other result
        # that fits claims less, sampled (a lower bound) or certified.
        fits = [m for m in result.iterations if m.met]
        assert all(result.error_upper <= m.decisive_error for m in fits)


def test_a_size_budgets_meshopt_levels_lock_their_strays():
    """A vertex-driven meshopt level locked nothing: the bunny at 20 kB came out at
    3.85e-4 (certified <= 3.88e-4) where a level with its strays locked measures 2.6e-4."""
    bunny = load("bunny.ply")
    result = compress(bunny, size=8 * 20_000)
    assert result.met and result.size_bytes <= 20_000
    assert result.error_upper < 3.0e-4


def test_unreachable_budget_says_so():
    result = compress(SPOT, size=8 * 30, max_iterations=3)
    assert not result.met
    assert "could not meet" in result.message
    assert len(result.iterations) <= 3


def test_lods_pick_the_level_closest_to_the_plan():
    levels = [simplify(SPOT, n).mesh for n in (300, 1000, 2500)]
    result = compress(SPOT, vertices=900, lods=levels)
    assert result.level == 1
    planned = result.iterations[0].planned_vertices
    counts = [len(level[0]) for level in levels]
    assert result.level == int(np.argmin(np.abs(np.log(counts) - np.log(planned))))


def test_codes_rebuild_the_output():
    result = compress(SPOT, error=0.005, relative=True)
    rebuilt = result.origin + result.codes * result.step
    assert np.abs(rebuilt - result.vertices).max() < 0.01 * result.step
    assert result.codes.max() <= 2**result.bits - 1


@pytest.mark.parametrize("suffix", [".obj", ".stl", ".off", ".glb", ".ply"])
def test_mesh_formats_in_and_soups_welded(tmp_path, suffix):
    path = tmp_path / f"spot{suffix}"
    trimesh.Trimesh(*SPOT, process=False).export(path)
    mesh = meshbits.load_mesh(path)
    if suffix == ".stl":
        assert len(mesh[0]) == 3 * len(mesh[1])  # a triangle soup
    result = compress(mesh, error=0.004, relative=True)
    assert result.met and len(result.vertices) < len(SPOT[0])
    assert result.complexity.k == pytest.approx(meshbits.shape_complexity(SPOT).k, rel=1e-6)


def test_scene_with_two_meshes_is_concatenated(tmp_path):
    box = trimesh.creation.box()
    sphere = trimesh.creation.icosphere(subdivisions=2)
    sphere.apply_translation([3, 0, 0])
    path = tmp_path / "scene.glb"
    trimesh.Scene([box, sphere]).export(path)
    vertices, faces = meshbits.load_mesh(path)
    assert len(faces) == len(box.faces) + len(sphere.faces)
    assert vertices[:, 0].max() == pytest.approx(4.0)  # the sphere's transform is applied


def test_ply_format():
    result = compress(SPOT, error=0.005, relative=True, format="ply")
    assert result.format == "ply" and result.data.startswith(b"ply\n")


@pytest.mark.parametrize("budget", [{"error": 0.002, "relative": True}, {"size": 8 * 20_000}])
@pytest.mark.parametrize("format", ["ply", "glb"])
def test_a_fixed_width_format_stores_the_most_bits_its_bytes_hold(format, budget):
    """PLY stores float32 whatever B, a quantized GLB 8 or 16 bits: at the same bytes the
    most bits of that width give the least error. The search encoded the bunny at B = 11
    (error budget) or B = 10 (size budget) in both, as it would for Draco; at 0.002 S
    the horse's PLY was 202,071 bytes at B = 9 and is 147,693 at B = 24."""
    bunny = load("bunny_res3.ply")
    result = compress(bunny, format=format, **budget)
    assert result.met
    if format == "ply":
        assert result.bits == result.max_bits
    else:
        assert result.bits in (8, 16)
    # The file is the chosen level at that B: a lower B of the same width gives the
    # same bytes and an error no smaller.
    lower = 14 if format == "glb" and result.bits == 16 else result.bits - 4
    same = encode((result.vertices, result.faces), lower, format=format)
    assert abs(same.size_bits - result.size_bits) <= 8 * 16


def test_reproducible_with_a_seed():
    a = compress(SPOT, error=0.003, relative=True, seed=7)
    b = compress(SPOT, error=0.003, relative=True, seed=7)
    assert a.data == b.data and a.error == b.error


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({}, "exactly one"),
        ({"size": 1e5, "error": 0.1}, "exactly one"),
        ({"error": -1.0}, "positive"),
        ({"error": 0.1, "format": "gif"}, "format"),
        ({"error": 0.1, "max_iterations": 0}, "max_iterations"),
    ],
)
def test_bad_arguments(kwargs, match):
    with pytest.raises(ValueError, match=match):
        compress(SPOT, **kwargs)


# --- command line -----------------------------------------------------------------------


def test_compress_cli_json_and_output(tmp_path, capsys):
    out = tmp_path / "spot.drc"
    code = main(
        [
            "compress",
            str(meshbits.example_mesh_path()),
            "--error",
            "0.004",
            "--relative",
            "-o",
            str(out),
            "--json",
            "--quiet",
        ]
    )
    assert code == 0
    report = json.loads(capsys.readouterr().out)
    for key in (
        "met",
        "bits",
        "vertices",
        "faces",
        "error",
        "size_bytes",
        "plan",
        "iterations",
        "budget",
        "constraint",
        "output",
        "seconds",
    ):
        assert key in report
    assert out.stat().st_size == report["size_bytes"]
    assert report["error"] <= report["budget"]


def test_compress_cli_writes_a_draco_glb_that_trimesh_reads(tmp_path, capsys):
    out = tmp_path / "spot.glb"
    argv = ["compress", str(meshbits.example_mesh_path()), "--error", "0.005", "--relative"]
    assert main([*argv, "-o", str(out), "--quiet", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    loaded = trimesh.load(out, force="mesh", process=False)  # decoded by trimesh's Draco
    assert len(loaded.vertices) == report["primitives"][0]["vertices"]
    assert report["codec"] == "draco" and report["met"]


def test_compress_cli_size_budget_on_a_glb(tmp_path, capsys):
    out = tmp_path / "spot.glb"
    argv = ["compress", str(meshbits.example_mesh_path()), "--size", "20KB", "-o", str(out)]
    assert main([*argv, "--json", "--quiet"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["met"] and out.stat().st_size == report["size_bytes"] <= 20_000


def test_quantized_glb_format_in_the_api():
    result = compress(SPOT, size=8 * 20_000, format="glb")
    assert result.format == "glb" and result.met and result.bits <= 16
    loaded = trimesh.load(trimesh.util.wrap_as_stream(result.data), file_type="glb", force="mesh")
    assert len(loaded.vertices) == len(result.vertices)


def test_compress_cli_exit_1_when_unmet(capsys):
    code = main(
        [
            "compress",
            str(meshbits.example_mesh_path()),
            "--size",
            "30B",
            "--json",
            "--quiet",
            "--max-iterations",
            "2",
        ]
    )
    assert code == 1
    assert json.loads(capsys.readouterr().out)["met"] is False


@pytest.mark.parametrize(
    "argv",
    [
        ["compress", str(DATA / "missing.ply"), "--error", "0.1"],
        ["compress", str(DATA / "bunny.ply"), "--size", "100"],
        ["compress", str(DATA / "bunny.ply"), "--size", "100KB", "-o", "x.obj"],
        ["compress", str(DATA / "bunny.ply"), "--error", "0.1", "-o", "x.gif"],
        ["compress", str(DATA / "bunny.ply"), "--vertices", "100", "--relative"],
    ],
)
def test_compress_cli_bad_input_exit_2(argv, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("meshbits compress: error:") and err.count("\n") == 1


def test_demo(capsys):
    assert main(["demo"]) == 0
    out = capsys.readouterr().out
    assert "spot.ply" in out and "met the error budget" in out


def test_calibrate_cli(capsys):
    assert (
        main(
            [
                "calibrate",
                str(meshbits.example_mesh_path()),
                "--vertices",
                "400",
                "1200",
                "--bits",
                "8",
                "12",
                "--json",
            ]
        )
        == 0
    )
    report = json.loads(capsys.readouterr().out)
    assert 0 < report["alpha"] <= 2 and report["samples"] == 4


# --- found by the fuzz campaign (benches/fuzz.py) ------------------------------------------

OPEN_TETRA = (
    np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]),
    np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2]]),
)


def test_an_output_with_no_error_at_all_ends_the_loop():
    """A mesh the first pass reproduces exactly measured an error of 0: the next target,
    budget / 0, raised ZeroDivisionError (exit 3 at the command line)."""
    result = compress(OPEN_TETRA, error=0.01, relative=True)
    assert result.met and result.error == 0.0


@pytest.mark.parametrize(
    ("options", "error", "match"),
    [
        ({"vertices": 50, "max_iterations": None}, TypeError, "max_iterations"),
        # was "'<' not supported between instances of 'NoneType' and 'int'"
        ({"size": 1 + 2j}, TypeError, "size budget"),
        # was "float() argument must be a string or a real number, not 'complex'"
        ({"error": 10**400}, meshbits.MeshbitsError, "error budget"),
        # was OverflowError
        ({"size": 16000, "alpha": "x"}, TypeError, "alpha"),
        # was "can't multiply sequence by non-int of type 'float'"
        ({"size": 16000, "connectivity_bits": "x"}, TypeError, "connectivity_bits"),
        # was "unsupported operand type(s) for +: 'float' and 'str'"
    ],
)
def test_bad_options_are_refused_naming_them(options, error, match):
    with pytest.raises(error, match=match):
        compress(OPEN_TETRA, **options)


def test_simplify_never_asks_for_as_many_faces_as_it_has():
    """Two triangles to 4 vertices asked fast-simplification for 4 faces out of 2: its
    ValueError "target_count must be less than the number of faces" escaped."""
    vertices = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [5, 5, 5], [6, 5, 5], [5, 6, 5]])
    out_vertices, out_faces = simplify(
        (vertices, np.array([[0, 1, 2], [3, 4, 5]])), 4, method="fast-simplification"
    ).mesh
    assert len(out_faces) >= 1 and len(out_vertices) <= 6


@pytest.mark.parametrize(
    ("target", "error"),
    [
        (None, meshbits.MeshbitsError),
        (np.array([1.0, 2.0]), TypeError),
        (10**400, meshbits.MeshbitsError),
    ],
)
def test_simplify_refuses_a_target_that_is_not_a_number(target, error):
    """int(target) raised TypeError without the argument's name, or OverflowError."""
    with pytest.raises(error, match="vertices"):
        simplify(OPEN_TETRA, target)


def tangle() -> tuple[np.ndarray, np.ndarray]:
    """Suzanne's faces as polygons of 255 consecutive vertices, fan-triangulated (as
    trimesh reads such a PLY or OBJ): 244,904 faces on 507 vertices, 483 per vertex."""
    vertices, faces = load("suzanne.ply")
    n = len(vertices)
    fans = [[a, (a + k) % n, (a + k + 1) % n] for a in faces[:, 0] for k in range(1, 254)]
    return vertices, np.array(fans)


def test_simplify_refuses_a_tangle_that_would_take_hours():
    """fast-simplification ran for over 10 minutes on the tangle."""
    start = time.perf_counter()
    with pytest.raises(meshbits.MeshbitsError, match="483 per vertex"):
        simplify(tangle(), 50, method="fast-simplification")
    assert time.perf_counter() - start < 60.0  # a hang guard, not a speed target


def test_compress_refuses_a_tangle_that_would_take_minutes():
    """With an error budget the plan kept every vertex, so nothing was simplified, but
    each of 3 passes measured the Hausdorff distance over the 244,904 overlapping faces:
    170 to 210 s at the command line."""
    start = time.perf_counter()
    with pytest.raises(meshbits.MeshbitsError, match="485 per vertex"):  # 2 welded
        compress(tangle(), error=0.01, relative=True)
    assert time.perf_counter() - start < 60.0  # a hang guard, not a speed target


def test_a_model_that_asks_for_every_vertex_still_gets_a_simplified_level_measured():
    """The fandisk (a CAD part) at 6.6e-4 mesh units: the paper's model asks for 34,600 of
    its 6,475 vertices, and compress returned the whole mesh at 13 bits (14,554 bytes);
    a level of half the vertices, measured first, shows fast-simplification far below
    the budget there (4.3e-5 at 3,239 vertices)."""
    fandisk = load("fandisk.ply")
    result = compress(fandisk, error=6.6e-4)
    assert result.met and result.error_upper <= 6.6e-4
    assert len(result.vertices) < 0.5 * len(fandisk[0])
    grid = meshbits.cube_grid(fandisk[0].min(axis=0), fandisk[0].max(axis=0))
    whole = encode_draco(fandisk, result.bits, origin=grid[0], grid_size=grid[1])
    assert result.size_bytes < 0.5 * whole.size_bytes


def test_an_error_budget_below_float32_precision_says_why_b_stops():
    """``--error 1e-9`` on a float32 mesh gave up at B = 24 without a word on why (Draco
    takes up to 30 bits)."""
    mesh = load("bunny_res4.ply")
    assert meshbits.precision_bits(mesh[0]) == 24
    result = meshbits.compress(mesh, error=1e-9, max_iterations=1)
    assert not result.met and result.bits == 24
    assert "(B stops at 24: over the grid size, the coordinates'" in result.message


def _flat_grid(n: int = 20) -> tuple[np.ndarray, np.ndarray]:
    """A unit square in the plane z = 0, as an n x n grid of vertices: K = 0."""
    x, y = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n))
    vertices = np.c_[x.ravel(), y.ravel(), np.zeros(n * n)]
    corner = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)).ravel()
    faces = np.r_[
        np.c_[corner, corner + 1, corner + n], np.c_[corner + 1, corner + n + 1, corner + n]
    ]
    return vertices, faces


def test_a_flat_mesh_is_compressed_not_refused():
    """K = 0 (every edge flat) was refused ("the model has no answer") where the scene
    path planned it with a small K: a flat mesh keeps its corners."""
    mesh = _flat_grid()
    assert meshbits.shape_complexity(mesh).k == 0
    result = meshbits.compress(mesh, error=0.001, relative=True)
    assert result.met and result.error_upper <= result.budget
    assert len(result.vertices) < len(mesh[0])
    assert np.all(result.vertices[:, 2] == 0)
    assert np.allclose(result.vertices.min(axis=0)[:2], 0) and np.allclose(
        result.vertices.max(axis=0)[:2], 1
    )
    result = meshbits.compress(mesh, size=8 * 500)
    assert result.met and result.size_bytes <= 500


def test_a_level_with_no_area_left_is_not_encoded():
    """A simplifier that collapsed the one real triangle to an edge made Draco refuse
    the level ("its only face is degenerate"), which stopped compress."""
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 2, 2], [3, 3, 3.0]])
    result = meshbits.compress((vertices, np.array([[0, 1, 2], [3, 4, 3]])), error=0.01)
    assert len(result.faces) >= 1


def test_a_budget_given_as_text_is_told_how_the_api_takes_it():
    mesh = load("bunny_res4.ply")
    with pytest.raises(TypeError, match=r"parse_size\('20KB'\)"):
        compress(mesh, size="20KB")
    with pytest.raises(TypeError, match=r"parse_length"):
        meshbits.compress_scene(DATA / "bunny_res4.ply", error="1mm")


def test_an_uncertified_met_error_budget_says_it_is_a_lower_bound():
    mesh = load("bunny_res4.ply")
    sampled = compress(mesh, error=0.01, relative=True, certify=False)
    certified = compress(mesh, error=0.01, relative=True)
    assert sampled.met and sampled.error_upper is None
    assert meshbits.results.SAMPLED_ONLY in sampled.message
    assert certified.met and meshbits.results.SAMPLED_ONLY not in certified.message
