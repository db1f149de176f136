"""Shape complexity K against a numpy reference, analytic cases and the paper's Table 1."""

from __future__ import annotations

import math

import numpy as np
import pytest
import reference
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

import meshbits
from meshbits import shape_complexity

COUNTS = (
    "edges",
    "interior_edges",
    "boundary_edges",
    "nonmanifold_edges",
    "flat_edges",
    "ill_conditioned_edges",
    "degenerate_edges",
    "merged_vertices",
    "degenerate_faces",
)


def assert_matches_reference(vertices, faces, estimator="circumsphere", merge=True):
    got = shape_complexity(vertices, faces, estimator=estimator, merge_vertices=merge)
    want = reference.shape_complexity(vertices, faces, estimator, merge)
    for name in COUNTS:
        assert getattr(got, name) == want[name], name
    assert got.k_raw == pytest.approx(want["k_raw"], rel=1e-9, abs=1e-300)
    assert got.k == pytest.approx(want["k"], rel=1e-9, abs=1e-300)
    assert got.area == pytest.approx(want["area"], rel=1e-12)
    return got


def icosphere(subdivisions: int, radius: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    sphere = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    return np.asarray(sphere.vertices), np.asarray(sphere.faces)


@st.composite
def random_meshes(draw, max_vertices: int = 30, max_faces: int = 60):
    n = draw(st.integers(4, max_vertices))
    m = draw(st.integers(1, max_faces))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    vertices = rng.normal(size=(n, 3))
    faces = rng.integers(0, n, size=(m, 3))
    return vertices, faces


# --- the numpy reference ---------------------------------------------------------------


@settings(max_examples=150, deadline=None)
@given(random_meshes(), st.sampled_from(["circumsphere", "dihedral", "hybrid"]))
def test_random_meshes_match_reference(mesh, estimator):
    vertices, faces = mesh
    # Random meshes repeat indices and share edges among many faces; a draw whose every
    # face is degenerate must be refused by both.
    try:
        reference.shape_complexity(vertices, faces)
    except ValueError:
        with pytest.raises(ValueError, match="zero surface area"):
            shape_complexity(vertices, faces)
        return
    assert_matches_reference(vertices, faces, estimator)


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 3), st.floats(1e-3, 0.2), st.integers(0, 2**32 - 1))
def test_perturbed_spheres_match_reference(subdivisions, noise, seed):
    vertices, faces = icosphere(subdivisions)
    vertices = vertices + np.random.default_rng(seed).normal(scale=noise, size=vertices.shape)
    for estimator in ("circumsphere", "dihedral", "hybrid"):
        assert_matches_reference(vertices, faces, estimator)


@pytest.mark.parametrize("estimator", ["circumsphere", "dihedral", "hybrid"])
def test_real_meshes_match_reference(real_mesh, estimator):
    _, vertices, faces = real_mesh
    assert_matches_reference(vertices, faces, estimator)


def test_real_mesh_float32_input_matches_float64(real_mesh):
    _, vertices, faces = real_mesh
    single = shape_complexity(vertices.astype(np.float32), faces)
    double = shape_complexity(vertices, faces)
    assert single == double  # the files hold float32 values: exactly representable


# --- the analytic sphere ----------------------------------------------------------------


def test_icosphere_k_area_rises_toward_sqrt_4pi():
    values = [shape_complexity(*icosphere(s)).k_area for s in range(1, 6)]
    # Every radius is 1 and the p(e) add up to the area A, so k_area = sqrt(A) exactly.
    for s, value in zip(range(1, 6), values, strict=True):
        assert value == pytest.approx(math.sqrt(trimesh.creation.icosphere(s).area), rel=1e-12)
    assert values[1] == pytest.approx(3.511, abs=1e-3)  # 320 faces
    assert values[2] == pytest.approx(3.537, abs=1e-3)  # 1280 faces
    assert all(np.diff(values) > 0)
    assert all(v < math.sqrt(4 * math.pi) for v in values)
    assert values[-1] == pytest.approx(math.sqrt(4 * math.pi), rel=1e-3)


def test_icosphere_k_tends_to_two_pi_and_every_radius_is_the_sphere():
    radius = 2.5
    vertices, faces = icosphere(5, radius)
    result = shape_complexity(vertices, faces, per_edge=True)
    assert result.k == pytest.approx(2 * math.pi, rel=2e-3)
    np.testing.assert_allclose(result.edge_radius, radius, rtol=1e-9)
    assert result.boundary_edges == result.nonmanifold_edges == result.flat_edges == 0


@pytest.mark.parametrize("estimator", ["dihedral", "hybrid"])
def test_other_estimators_converge_on_the_sphere(estimator):
    result = shape_complexity(*icosphere(5), estimator=estimator)
    assert result.k_area == pytest.approx(math.sqrt(4 * math.pi), rel=2e-3)


# --- invariances ------------------------------------------------------------------------


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


@settings(max_examples=60, deadline=None)
@given(
    st.integers(0, 2**32 - 1),
    st.floats(1e-3, 1e3),
    st.sampled_from(["circumsphere", "dihedral", "hybrid"]),
)
def test_invariances(seed, scale, estimator):
    rng = np.random.default_rng(seed)
    vertices, faces = icosphere(2)
    vertices = vertices * rng.uniform(0.5, 1.5, size=3) + rng.normal(
        scale=0.05, size=vertices.shape
    )
    base = shape_complexity(vertices, faces, estimator=estimator)

    moved = scale * vertices @ random_rotation(rng).T + rng.normal(scale=10.0, size=3)
    transformed = shape_complexity(moved, faces, estimator=estimator)
    assert transformed.k_area == pytest.approx(base.k_area, rel=1e-9)
    assert transformed.k_raw == pytest.approx(scale * base.k_raw, rel=1e-9)

    perm = rng.permutation(len(vertices))
    inverse = np.argsort(perm)
    face_order = rng.permutation(len(faces))
    shuffled_faces = inverse[faces][face_order]
    flip = rng.random(len(faces)) < 0.5
    shuffled_faces[flip] = shuffled_faces[flip][:, ::-1]
    shuffled = shape_complexity(vertices[perm], shuffled_faces, estimator=estimator)
    assert shuffled.k_raw == pytest.approx(base.k_raw, rel=1e-12)
    assert shuffled.k == pytest.approx(base.k, rel=1e-12)
    for name in COUNTS:
        assert getattr(shuffled, name) == getattr(base, name)


def test_result_does_not_depend_on_thread_count(bunny):
    with meshbits.threads(1):
        one = shape_complexity(*bunny, per_edge=True)
    with meshbits.threads(2):
        two = shape_complexity(*bunny, per_edge=True)
    assert one.k_raw == two.k_raw  # bit-identical, not approximately equal
    np.testing.assert_array_equal(one.edge_contribution, two.edge_contribution)


# --- known cases worked out by hand -----------------------------------------------------


def test_regular_tetrahedron():
    side = 2.0
    vertices = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], dtype=float)
    vertices *= side / math.sqrt(8)  # edge length of the cube-corner tetrahedron is sqrt(8)
    faces = np.array([[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]])
    result = shape_complexity(vertices, faces, per_edge=True)
    # Every edge sees all four vertices: r = circumradius = side * sqrt(6) / 4, and
    # p(e) = 2 * (sqrt(3)/4 side^2) / 3, so K_raw = 6 p / r = 2 sqrt(2) side.
    np.testing.assert_allclose(result.edge_radius, side * math.sqrt(6) / 4, rtol=1e-12)
    assert result.k_raw == pytest.approx(2 * math.sqrt(2) * side, rel=1e-12)
    assert result.edges == result.interior_edges == 6


def cube(side: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    box = trimesh.creation.box(extents=(side, side, side))
    return np.asarray(box.vertices), np.asarray(box.faces)


@pytest.mark.parametrize("estimator", ["circumsphere", "hybrid"])
def test_cube_diagonals_are_flat_and_edges_lie_on_the_circumsphere(estimator):
    side = 3.0
    result = shape_complexity(*cube(side), estimator=estimator, per_edge=True)
    assert result.edges == 18
    assert result.flat_edges == 6
    kinds = result.edge_kind
    np.testing.assert_allclose(result.edge_radius[kinds == 0], math.sqrt(3) / 2 * side, rtol=1e-12)
    assert np.all(np.isinf(result.edge_radius[kinds == 1]))
    # 12 cube edges, each with p(e) = side^2 / 3 and r = sqrt(3)/2 side.
    assert result.k_raw == pytest.approx(8 * side / math.sqrt(3), rel=1e-12)
    assert result.k == pytest.approx(8 / math.sqrt(3), rel=1e-12)


def test_cube_dihedral():
    side = 3.0
    result = shape_complexity(*cube(side), estimator="dihedral")
    # 12 edges bent by pi/2, each contributing (pi/2) * side / 2.
    assert result.k_raw == pytest.approx(12 * (math.pi / 2) * side / 2, rel=1e-12)


def flat_grid(n: int, noise: float = 0.0, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    x, y = np.meshgrid(np.arange(n + 1, dtype=float), np.arange(n + 1, dtype=float))
    z = np.random.default_rng(seed).normal(scale=noise, size=x.shape) if noise else 0 * x
    vertices = np.column_stack([x.ravel(), y.ravel(), z.ravel()])
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, 1:], idx[1:, :-1]
    faces = np.concatenate(
        [np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)]
    )
    return vertices, faces


def test_exactly_flat_grid_has_zero_k():
    result = shape_complexity(*flat_grid(10))
    assert result.k_raw == 0.0
    assert result.flat_edges == result.interior_edges
    assert result.boundary_edges == 40


def test_noisy_flat_grid_is_ill_conditioned_and_hybrid_reads_it_flat():
    n = 10
    vertices, faces = flat_grid(n, noise=1e-9)
    circ = shape_complexity(vertices, faces, estimator="circumsphere")
    hybrid = shape_complexity(vertices, faces, estimator="hybrid")
    # The n*n square diagonals are co-circular: their noisy spheres have r ~ side, which
    # is the paper's estimator's known weakness (a flat grid reads as curved).
    assert circ.ill_conditioned_edges == n * n
    assert circ.k > 1.0
    assert hybrid.ill_conditioned_edges == n * n
    assert hybrid.k < 1e-6


def test_square_split_in_two_is_flat():
    vertices = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=float)
    result = shape_complexity(vertices, [[0, 1, 2], [0, 2, 3]])
    assert (result.flat_edges, result.boundary_edges, result.k_raw) == (1, 4, 0.0)


def test_boundary_and_nonmanifold_counts():
    vertices = np.array(
        [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0.2], [0.3, 0.2, 1.0]], dtype=float
    )
    one = shape_complexity(vertices, [[0, 1, 2]])
    assert (one.edges, one.boundary_edges, one.interior_edges, one.k_raw) == (3, 3, 0, 0.0)
    fan = shape_complexity(vertices, [[0, 1, 2], [1, 0, 3], [0, 1, 4]])
    assert (fan.edges, fan.nonmanifold_edges, fan.boundary_edges) == (7, 1, 6)
    assert fan.interior_edges == 0 and fan.k_raw == 0.0


def test_triangle_soup_before_and_after_welding():
    vertices, faces = icosphere(2)
    soup_vertices = vertices[faces].reshape(-1, 3)
    soup_faces = np.arange(len(soup_vertices)).reshape(-1, 3)
    welded = shape_complexity(soup_vertices, soup_faces)
    unwelded = shape_complexity(soup_vertices, soup_faces, merge_vertices=False)
    original = shape_complexity(vertices, faces)
    assert unwelded.k_raw == 0.0 and unwelded.boundary_edges == unwelded.edges == 3 * len(faces)
    assert welded.merged_vertices == len(soup_vertices) - len(vertices)
    assert welded.k_raw == pytest.approx(original.k_raw, rel=1e-12)
    assert welded.edges == original.edges


def test_degenerate_faces_and_unreferenced_vertices_are_harmless():
    vertices, faces = icosphere(2)
    far_away = np.vstack([vertices, [[100.0, 100.0, 100.0]]])
    with_junk = np.vstack([faces, [[0, 0, 1], [2, 2, 2]]])
    base = shape_complexity(vertices, faces)
    result = shape_complexity(far_away, with_junk)
    assert result.degenerate_faces == 2
    assert result.k_raw == base.k_raw
    assert result.grid_size == base.grid_size  # unreferenced vertex is not in the box


def test_zero_area_triangle_makes_degenerate_edges():
    vertices = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [1, 1, 0.5]], dtype=float)
    result = shape_complexity(vertices, [[0, 1, 2], [0, 2, 3]])
    assert result.degenerate_edges == 1
    assert np.isfinite(result.k_raw)


def test_per_edge_arrays_are_consistent(bunny):
    result = shape_complexity(*bunny, per_edge=True)
    assert result.edge_vertices.shape == (result.edges, 2)
    assert result.edge_contribution.sum() == pytest.approx(result.k_raw, rel=1e-12)
    kinds = np.bincount(result.edge_kind, minlength=6)
    assert kinds[1] == result.flat_edges and kinds[2] == result.ill_conditioned_edges
    assert kinds[3] == result.boundary_edges and kinds[4] == result.nonmanifold_edges
    interior = result.edge_kind <= 2
    assert np.all(np.isnan(result.edge_radius[~interior]))
    assert result.edge_weight[interior].sum() <= result.area * (1 + 1e-12)
    assert set(result.to_dict()) >= {"k", "k_area", "k_raw", "grid_size", "area", *COUNTS}
    assert "edge_radius" in result.to_dict(arrays=True)


# --- the paper's Table 1 ----------------------------------------------------------------


def test_table1_bunny(bunny):
    # Paper: 54.39 (models scaled to equal area). Measured here: 54.616.
    assert shape_complexity(*bunny).k_area == pytest.approx(54.39, rel=0.01)


def test_table1_horse(horse):
    # Paper: 56.07. Measured here: 56.058.
    assert shape_complexity(*horse).k_area == pytest.approx(56.07, rel=0.01)


def test_trimesh_input(bunny):
    mesh = trimesh.Trimesh(*bunny, process=False)
    assert shape_complexity(mesh) == shape_complexity(*bunny)
    assert shape_complexity(bunny) == shape_complexity(*bunny)


def test_any_integer_dtype_and_fortran_order(bunny):
    vertices, faces = bunny
    base = shape_complexity(vertices, faces)
    for dtype in (
        np.int32,
        np.uint32,
        np.int64,
        np.uint64,
        np.int16 if len(vertices) < 2**15 else np.int64,
    ):
        assert shape_complexity(vertices, faces.astype(dtype)) == base
    assert shape_complexity(np.asfortranarray(vertices), np.asfortranarray(faces)) == base


# --- bad input --------------------------------------------------------------------------

TRIANGLE = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=float)


@pytest.mark.parametrize(
    ("vertices", "faces", "error", "match"),
    [
        (TRIANGLE * np.array([1, np.nan, 1]), [[0, 1, 2]], ValueError, "not finite"),
        (TRIANGLE + np.array([np.inf, 0, 0]), [[0, 1, 2]], ValueError, "not finite"),
        (TRIANGLE, [[0, 1, -1]], ValueError, "negative vertex index"),
        (TRIANGLE, [[0, 1, 3]], ValueError, "out of range"),
        (TRIANGLE[:, :2], [[0, 1, 2]], ValueError, r"shape \(n, 3\)"),
        (TRIANGLE, [[0, 1, 2, 0]], ValueError, r"shape \(m, 3\)"),
        (TRIANGLE, [0, 1, 2], ValueError, r"shape \(m, 3\)"),
        (TRIANGLE, [[0.0, 1.0, 2.0]], TypeError, "integer"),
        (TRIANGLE.astype(str), [[0, 1, 2]], TypeError, "real numbers"),
        (np.zeros((0, 3)), np.zeros((0, 3), dtype=int), ValueError, "empty"),
        (TRIANGLE, np.zeros((0, 3), dtype=int), ValueError, "empty"),
        (np.zeros((3, 3)), [[0, 1, 2]], ValueError, "zero surface area"),
        (TRIANGLE, [[0, 0, 1], [1, 1, 2]], ValueError, "zero surface area"),
    ],
)
def test_bad_input(vertices, faces, error, match):
    with pytest.raises(error, match=match):
        shape_complexity(vertices, faces)


def test_bad_estimator_and_non_mesh():
    with pytest.raises(ValueError, match="estimator"):
        shape_complexity(TRIANGLE, [[0, 1, 2]], estimator="curvy")
    with pytest.raises(TypeError, match=r"trimesh\.Trimesh"):
        shape_complexity("not a mesh")


# --- refusals found by the fuzz campaign (benches/fuzz.py) --------------------------------


@pytest.mark.parametrize("flag", ["merge_vertices", "per_edge"])
def test_flags_that_are_not_booleans_are_refused_naming_them(flag):
    """merge_vertices=2 raised the binding's "'int' object is not an instance of 'bool'",
    the argument named only in a note."""
    mesh = trimesh.creation.icosphere(subdivisions=1)
    with pytest.raises(TypeError) as caught:
        shape_complexity(mesh, **{flag: 2})
    assert flag in str(caught.value)


def test_a_mesh_wider_than_the_supported_extent_is_refused():
    """Squared lengths of a mesh spanning 1e308 overflowed: K was NaN, and `meshbits plan`
    stopped with an internal error."""
    v = np.array([[0.0, 0, 0], [1e308, 0, 0], [0, 1, 0], [0, 0, 1]])
    f = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    with pytest.raises(meshbits.MeshbitsError, match="more than the supported 1e36"):
        shape_complexity(v, f)
    v[1, 0] = 1.0
    assert shape_complexity(v * 1e35, f).k == pytest.approx(shape_complexity(v, f).k)
