"""meshbits.plot: image sizes, per-vertex colours through the colour map, the CLI, and a
fast run of benches/validate_paper.py checking its own invariants."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

matplotlib = pytest.importorskip("matplotlib")
from matplotlib import image as mpimg  # noqa: E402

import meshbits  # noqa: E402
from meshbits import plot  # noqa: E402
from meshbits.cli import main  # noqa: E402

DATA = Path(__file__).parent / "data"
BENCH = Path(__file__).parent.parent / "benches" / "validate_paper.py"


def load(name: str) -> tuple[np.ndarray, np.ndarray]:
    mesh = trimesh.load(DATA / name, process=False, force="mesh")
    return np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int64)


def test_error_surface_png_has_requested_size(tmp_path):
    path = tmp_path / "fig1.png"
    fig = plot.error_surface(
        50.0, vertices=(100, 1e5), bits=(4, 18), path=path, size_px=(640, 480), resolution=60
    )
    image = mpimg.imread(path)
    assert image.shape[:2] == (480, 640)
    # Not a blank canvas: the filled contours give many distinct colours.
    assert len(np.unique(image.reshape(-1, image.shape[2]), axis=0)) > 50
    # The ridge drawn is the model's optimal B(V).
    ax = fig.axes[0]
    (ridge,) = [line for line in ax.get_lines() if line.get_label().startswith("optimal")]
    v, b = ridge.get_data()
    np.testing.assert_allclose(
        b,
        meshbits.model.optimal_bits(v, 50.0),
        rtol=1e-12,  # Draco's fit, the default
    )
    assert np.all(np.diff(b) > 0)  # more vertices deserve more bits


@pytest.mark.parametrize(
    "kwargs",
    [{"vertices": (100, 10)}, {"vertices": (1, 100)}, {"bits": (5, 5)}, {"resolution": 2}],
)
def test_error_surface_rejects_bad_ranges(kwargs):
    with pytest.raises(ValueError):
        plot.error_surface(10.0, **kwargs)


def test_error_surface_rejects_bad_k():
    with pytest.raises(ValueError, match="k must be positive"):
        plot.error_surface(0.0)


def test_error_map_colours_follow_the_colour_map(tmp_path):
    vertices, faces = load("bunny_res4.ply")
    rng = np.random.default_rng(3)
    distances = rng.uniform(0.0, 2.5e-3, len(vertices))
    distances[5] = 0.0
    vmax = 2e-3  # some distances above it: clipped to the top colour
    out = plot.error_map(
        (vertices, faces),
        distances,
        tmp_path / "map.ply",
        colorbar_path=tmp_path / "bar.png",
        cmap="magma",
        vmax=vmax,
    )
    back = trimesh.load(out.path, process=False, force="mesh")
    np.testing.assert_array_equal(back.faces, faces)
    np.testing.assert_allclose(back.vertices, vertices, rtol=0, atol=1e-6)
    colors = np.asarray(back.visual.vertex_colors)
    # Independent reference: the colour map on the normalised distances, as bytes.
    cmap = matplotlib.colormaps["magma"]
    expected = np.rint(cmap(np.clip(distances / vmax, 0, 1)) * 255).astype(np.uint8)
    np.testing.assert_array_equal(colors, expected)
    np.testing.assert_array_equal(colors[5], np.rint(np.array(cmap(0.0)) * 255))
    assert out.vmin == 0.0 and out.vmax == vmax
    bar = mpimg.imread(out.colorbar_path)
    assert bar.shape[:2] == (600, 160)


def test_error_map_default_vmax_is_the_largest_distance(tmp_path):
    vertices, faces = load("bunny_res4.ply")
    distances = np.linspace(0.0, 1.0, len(vertices))
    out = plot.error_map((vertices, faces), distances, tmp_path / "m.ply")
    assert out.vmax == 1.0 and out.colorbar_path is None
    top = np.rint(np.array(matplotlib.colormaps["viridis"](1.0)) * 255)
    np.testing.assert_array_equal(out.colors[-1], top)


def test_error_map_rejects_bad_distances(tmp_path):
    vertices, faces = load("bunny_res4.ply")
    with pytest.raises(ValueError, match="one value per vertex"):
        plot.error_map((vertices, faces), np.zeros(3), tmp_path / "x.ply")
    bad = np.zeros(len(vertices))
    bad[0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        plot.error_map((vertices, faces), bad, tmp_path / "x.ply")
    with pytest.raises(ValueError, match="non-negative"):
        plot.error_map((vertices, faces), -np.ones(len(vertices)), tmp_path / "x.ply")
    with pytest.raises(ValueError, match="colour map"):
        plot.error_map((vertices, faces), np.zeros(len(vertices)), tmp_path / "x.ply", cmap="nope")


def test_cli_plot_writes_png(tmp_path, capsys):
    out = tmp_path / "fig.png"
    assert main(["plot", str(DATA / "bunny_res4.ply"), "-o", str(out), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert mpimg.imread(out).shape[:2] == (650, 900)
    k = meshbits.shape_complexity(load("bunny_res4.ply")).k
    assert report["k"] == pytest.approx(k)
    assert report["optimal_bits"] == pytest.approx(
        meshbits.plan_for_vertices(report["vertices"], k, grid_size=1.0).bits
    )


def test_cli_hausdorff_colors(tmp_path, capsys):
    a, b = DATA / "bunny_res4.ply", DATA / "bunny_res3.ply"
    out = tmp_path / "colored.ply"
    assert main(["hausdorff", str(a), str(b), "--colors", str(out), "--quiet", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    va, _ = load("bunny_res4.ply")
    reference = meshbits.ClosestPoints(load("bunny_res3.ply")).query(va).distances
    colors = np.asarray(trimesh.load(out, process=False, force="mesh").visual.vertex_colors)
    expected = np.rint(matplotlib.colormaps["viridis"](reference / reference.max()) * 255).astype(
        np.uint8
    )
    np.testing.assert_array_equal(colors, expected)
    assert report["colors"]["vmax"] == pytest.approx(reference.max())
    assert Path(report["colors"]["colorbar_path"]).is_file()
    # Vertices lie on a surface sampled by the Hausdorff estimate: never above its max.
    assert reference.max() <= report["a_to_b"]["max"] + 1e-12


# --- the fast validation -----------------------------------------------------------------


@pytest.fixture(scope="module")
def validate():
    if not BENCH.is_file():
        pytest.skip("benches/validate_paper.py is not in this checkout")
    sys.path.insert(0, str(BENCH.parent))  # the bench imports benches/_shared.py
    spec = importlib.util.spec_from_file_location("validate_paper", BENCH)
    module = importlib.util.module_from_spec(spec)
    sys.modules["validate_paper"] = module
    spec.loader.exec_module(module)
    return module


def test_sphere_measured_optimum_matches_the_model(validate):
    sphere = validate.sphere_experiment(
        np.geomspace(20, 2e5, 25).round(), np.arange(3, 22), triangles=24, seed=0
    )
    err = sphere.measured  # (B ascending, V ascending)
    # Measured error grows as B falls (fixed V) and as V falls (fixed B). Quantization
    # noise of a few triangles can lower one cell by chance, so cells 4 steps apart are
    # compared with a 10% margin, and the extremes strictly. Along V, only where the
    # model's tessellation error at the smaller V is at least its quantization error:
    # elsewhere the error is quantization noise, flat in V.
    assert np.all(err[:-4, :] >= 0.9 * err[4:, :])
    e_t = meshbits.model.tessellation_error(sphere.vertices[:-4], 4 * np.pi, grid_size=1.0)
    e_q = meshbits.model.quantization_error(sphere.bits, 2.0)
    matters = e_t[None, :] >= e_q[:, None]
    assert matters.sum() > 100
    assert np.all((err[:, :-4] >= 0.9 * err[:, 4:])[matters])
    assert err[0, -1] > 100 * err[-1, -1]  # B = 3 vs 21 at V = 2e5
    assert err[-1, 0] > 100 * err[-1, -1]  # V = 20 vs 2e5 at B = 21
    # Without quantization, the paper's midpoint error is exactly Eq. 10.
    v = sphere.vertices
    exact = [validate.paper_triangle_error(np.inf, x, sphere.theta0, sphere.z0) for x in v]
    np.testing.assert_allclose(
        exact, meshbits.model.tessellation_error(v, 4 * np.pi, grid_size=1.0), rtol=1e-9
    )
    budgets = np.geomspace(1e4, 1e7, 7)
    table = validate.sphere_optimum(sphere, budgets)
    # Stated tolerance (see docs/validation.md): the measured best whole B under a size
    # budget is at most 3 bits from the model's plan (the model's E_Q is a vertex's worst
    # case; a midpoint averages three vertices, so the measured optimum takes fewer
    # bits), and following the plan costs at most 10% more measured error than the
    # measured optimum.
    diff = table["measured_bits"] - table["predicted_bits"]
    assert np.all(np.abs(diff) <= 3)
    assert np.all(table["measured_at_predicted"] <= 1.10 * table["measured_error"])


def test_mesh_grid_invariants(validate):
    mesh = load("bunny_res4.ply")
    grid = validate.mesh_grid(mesh, [400, 200, 100], [3, 6, 9, 12], samples_per_face=10)
    assert list(grid.vertices) == sorted(grid.vertices, reverse=True)
    for err in (grid.mean_error, grid.max_error):
        # Fewer bits: more error at every level (10% margin: at high B the level's own
        # simplification error dominates and quantization is noise).
        assert np.all(err[:, :-1] >= 0.9 * err[:, 1:])
    # Fewer vertices: more error at the finest B: strictly for the mean; the maximum is
    # one bad collapse and may dip (10% margin).
    assert np.all(np.diff(grid.mean_error[:, -1]) > 0)
    assert np.all(grid.max_error[1:, -1] >= 0.9 * grid.max_error[:-1, -1])
    # Strictly, where each dominates.
    assert np.all(grid.mean_error[:, 0] > 2 * grid.mean_error[:, -1])
    assert grid.mean_error[-1, -1] > 2 * grid.mean_error[0, -1]
    assert np.all(grid.mean_error <= grid.max_error)
    # The unquantized levels follow the same order.
    assert np.all(np.diff(grid.simplified_mean) > 0)


def test_iso_error_labels_name_what_they_measure():
    """On the grid-normalised surface (grid_size 1) the iso-error curves are E / S and
    are labelled so (they read "E=1e-03" over a colour bar of E / S); with a grid size
    they are lengths, "E="; iso-size labels say bits."""
    import matplotlib.pyplot as plt

    for grid_size, name in [(1.0, "E/S="), (15.2, "E=")]:
        fig = plot.error_surface(10.0, grid_size=grid_size, resolution=32)
        labels = [t.get_text() for t in fig.axes[0].texts]
        plt.close(fig)
        errors = [t for t in labels if t.startswith(("E=", "E/S="))]
        assert errors and all(t.startswith(name) for t in errors), labels
        sizes = [t for t in labels if t.startswith("F=")]
        assert sizes and all(t.endswith(" bits") for t in sizes), labels
