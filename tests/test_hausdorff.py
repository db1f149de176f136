"""Closest points and the sampled Hausdorff distance, against independent references.

The reference is a brute-force point-to-triangle distance written here in numpy (plane
projection inside the triangle, clamped segment projections outside), checked against
every triangle of the mesh.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import meshbits
from meshbits.cli import main

DATA = Path(__file__).parent / "data"


# --- reference ---------------------------------------------------------------------------


def _segment_d2(p, x, y):
    d = y - x
    dd = (d * d).sum(-1)
    t = np.where(dd > 0, ((p - x) * d).sum(-1) / np.where(dd > 0, dd, 1.0), 0.0).clip(0, 1)
    q = x + t[..., None] * d
    return ((p - q) ** 2).sum(-1)


def brute_d2(points, vertices, faces):
    """Squared distance from every point to every triangle, shape (points, faces).

    Per triangle: the plane projection when it falls inside (edge functions against the
    normal), else the nearest of the three clamped segment projections. Triangles with
    ``(2 area / L**2)**2 <= 1e-16`` (``L`` the longest edge) count as their edges only,
    as documented in ``rust/closest.rs``.
    """
    p = np.asarray(points, dtype=float)[:, None, :]
    v = np.asarray(vertices, dtype=float)
    a, b, c = (v[np.asarray(faces)[:, k]][None] for k in range(3))
    best = np.minimum(np.minimum(_segment_d2(p, a, b), _segment_d2(p, b, c)), _segment_d2(p, c, a))
    n = np.cross(b - a, c - a)
    nn = (n * n).sum(-1)
    longest2 = np.maximum(
        np.maximum(((b - a) ** 2).sum(-1), ((c - a) ** 2).sum(-1)), ((c - b) ** 2).sum(-1)
    )
    regular = nn > 1e-16 * longest2**2
    h = ((p - a) * n).sum(-1) / np.where(regular, nn, 1.0)
    q = p - h[..., None] * n
    inside = regular
    for x, y in ((a, b), (b, c), (c, a)):
        inside = inside & ((np.cross(y - x, q - x) * n).sum(-1) >= 0)
    return np.where(inside, np.minimum(best, h * h * nn), best)


def tolerance(vertices, faces, points):
    """Absolute tolerance for a distance: rounding grows as ``scale**2 / (2 area)`` on
    thin triangles (see ``rust/closest.rs``)."""
    v = np.asarray(vertices, dtype=float)
    scale = 1.0 + np.abs(v).max() + np.abs(np.asarray(points)).max()
    a, b, c = (v[np.asarray(faces)[:, k]] for k in range(3))
    twice_area = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    longest = np.sqrt(
        np.max([((b - a) ** 2).sum(1), ((c - a) ** 2).sum(1), ((c - b) ** 2).sum(1)], axis=0)
    )
    regular = twice_area > 1e-8 * longest**2
    worst = (scale**2 / twice_area[regular]).max() if regular.any() else 1.0
    return 1e-13 * scale * max(1.0, worst)


def brute_distance(points, vertices, faces):
    return np.sqrt(brute_d2(points, vertices, faces).min(axis=1))


def square(n, z=0.0, size=1.0):
    """A square of side ``size`` in the plane ``z``, split into ``2 n**2`` triangles."""
    g = np.linspace(0, size, n + 1)
    x, y = np.meshgrid(g, g)
    v = np.column_stack([x.ravel(), y.ravel(), np.full(x.size, z)])
    k = (np.arange(n)[None, :] + (n + 1) * np.arange(n)[:, None]).ravel()
    f = np.concatenate(
        [np.column_stack([k, k + 1, k + n + 2]), np.column_stack([k, k + n + 2, k + n + 1])]
    )
    return v, f


def load(name):
    return meshbits.load_mesh(DATA / name)


def quantize(v, bits):
    lo = v.min(axis=0)
    size = (v.max(axis=0) - lo).max()
    k = 2**bits - 1
    return lo + np.round((v - lo) * k / size) * size / k


# --- strategies --------------------------------------------------------------------------

# Integer grid coordinates make degenerate triangles (repeated vertices, collinear
# corners) common and exactly degenerate.
grid_vertices = st.lists(st.tuples(*(st.integers(-3, 3),) * 3), min_size=3, max_size=9).map(
    lambda rows: np.array(rows, dtype=float) * 0.5
)
real_vertices = st.lists(
    st.tuples(*(st.floats(-2, 2, allow_nan=False, width=32),) * 3), min_size=3, max_size=9
).map(lambda rows: np.array(rows, dtype=float))


@st.composite
def meshes(draw, vertices=None):
    v = draw(vertices if vertices is not None else st.one_of(grid_vertices, real_vertices))
    n = len(v)
    faces = draw(st.lists(st.tuples(*(st.integers(0, n - 1),) * 3), min_size=1, max_size=10))
    return v, np.array(faces, dtype=np.int64)


@st.composite
def mesh_and_points(draw):
    v, f = draw(meshes())
    pts = [
        draw(st.tuples(*(st.floats(-4, 4, allow_nan=False),) * 3))
        for _ in range(draw(st.integers(1, 12)))
    ]
    pts = np.array(pts, dtype=float).reshape(-1, 3)
    # Points exactly on vertices, on edge midpoints, and at centroids.
    a, b, c = (v[f[:, k]] for k in range(3))
    extra = np.concatenate([v, (a + b) / 2, (b + c) / 2, (a + b + c) / 3])
    return v, f, np.concatenate([pts, extra])


FAST = settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])


# --- closest points ----------------------------------------------------------------------


@FAST
@given(mesh_and_points())
def test_closest_points_match_brute_force(case):
    v, f, pts = case
    result = meshbits.ClosestPoints((v, f)).query(pts)
    reference = brute_distance(pts, v, f)
    atol = tolerance(v, f, pts)
    np.testing.assert_allclose(result.distances, reference, rtol=0, atol=atol)
    # The closest point is at that distance, and lies on the reported face.
    np.testing.assert_allclose(
        np.linalg.norm(pts - result.points, axis=1), result.distances, atol=atol
    )
    on_face = np.array(
        [
            math.sqrt(brute_d2(q[None], v, f[[k]])[0, 0])
            for q, k in zip(result.points, result.faces, strict=True)
        ]
    )
    assert on_face.max() <= atol
    assert result.distances.dtype == np.float64 and result.faces.dtype == np.int64


@FAST
@given(mesh_and_points(), st.floats(0.0, 2.0))
def test_farther_than_matches_brute_force(case, fraction):
    """The early-exit verdict ``d > distance`` equals brute force's, away from ties."""
    v, f, pts = case
    reference = brute_distance(pts, v, f)
    distance = fraction * float(np.median(reference))
    far = meshbits.ClosestPoints((v, f)).farther_than(pts, distance)
    assert far.dtype == np.bool_ and far.shape == (len(pts),)
    clear = np.abs(reference - distance) > tolerance(v, f, pts)
    assert np.array_equal(far[clear], (reference > distance)[clear])


def test_farther_than_refuses_bad_distances():
    cp = meshbits.ClosestPoints(square(2))
    assert cp.farther_than(np.zeros((0, 3)), 0.1).shape == (0,)
    for bad in (-1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="distance must be finite"):
            cp.farther_than([[0.0, 0.0, 1.0]], bad)
    with pytest.raises(TypeError):
        cp.farther_than([[0.0, 0.0, 1.0]], "0.1")


def test_points_on_vertices_and_edges_are_at_distance_zero():
    v, f = square(3)
    cp = meshbits.ClosestPoints((v, f))
    a, b = v[f[:, 0]], v[f[:, 1]]
    pts = np.concatenate([v, (a + b) / 2])
    assert cp.query(pts).distances.max() <= 1e-15


def test_ties_go_to_the_smallest_face_index():
    v, f = square(1)
    doubled = np.concatenate([f[::-1], f])  # every triangle twice
    result = meshbits.ClosestPoints((v, doubled)).query([[0.9, 0.2, 1.0], [0.1, 0.8, -1.0]])
    assert result.faces.tolist() == [1, 0]  # triangle (0, 1, 3) is faces 1 and 2


def test_tree_validates_on_real_meshes():
    for name in ("bunny_res4.ply", "suzanne.ply", "fandisk.ply"):
        cp = meshbits.ClosestPoints(load(name))
        cp.validate()
        assert cp.n_faces == len(load(name)[1])
    for n in range(1, 40):
        v, f = square(1)
        cp = meshbits.ClosestPoints((v, np.resize(f, (n, 3))))
        cp.validate()


def test_closest_points_query_accepts_trimesh_and_empty_queries():
    mesh = trimesh.creation.icosphere(subdivisions=2)
    cp = meshbits.ClosestPoints(mesh)
    assert cp.query(np.zeros((0, 3))).distances.shape == (0,)
    far = cp.query([[0.0, 0.0, 5.0]])
    assert far.distances[0] == pytest.approx(4.0, abs=1e-15)  # (0, 0, 1) is a vertex
    assert "ClosestPoints(320 faces" in repr(cp)


# --- sampling ----------------------------------------------------------------------------


def test_surface_samples_skip_unreferenced_vertices_and_lie_on_faces():
    v, f = square(2)
    v = np.concatenate([v, [[50.0, 50.0, 50.0]]])  # unreferenced
    s = meshbits.surface_samples((v, f), samples=500, seed=3)
    assert s.n_vertex_samples == 9
    assert len(s.points) == 509
    assert (s.faces[:9] == -1).all() and (s.faces[9:] >= 0).all()
    assert np.abs(s.points[:, 2]).max() == 0.0
    assert s.points[:, :2].min() >= 0.0 and s.points[:, :2].max() <= 1.0
    # Each area sample lies on its own face.
    d = np.sqrt(brute_d2(s.points[9:], v, f)[np.arange(500), s.faces[9:]])
    assert d.max() <= 1e-15
    # Counts follow area: every face has the same area here.
    assert set(np.bincount(s.faces[9:], minlength=8).tolist()) <= {62, 63}


def test_surface_samples_are_seeded_and_thread_independent():
    mesh = load("bunny_res3.ply")
    with meshbits.threads(1):
        one = meshbits.surface_samples(mesh, samples=20_000, seed=5)
    with meshbits.threads(2):
        two = meshbits.surface_samples(mesh, samples=20_000, seed=5)
    other = meshbits.surface_samples(mesh, samples=20_000, seed=6)
    assert np.array_equal(one.points, two.points) and np.array_equal(one.faces, two.faces)
    assert not np.array_equal(one.points, other.points)
    assert meshbits.surface_samples(mesh).points.shape[0] == 1887 + 38_510


# --- hausdorff: brute force --------------------------------------------------------------


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(meshes(), meshes(), st.integers(0, 2**64 - 1))
def test_hausdorff_samples_match_brute_force(a, b, seed):
    r = meshbits.hausdorff(a, b, samples=40, seed=seed, bounds=True, return_samples=True)
    for d, (src, dst) in ((r.a_to_b, (a, b)), (r.b_to_a, (b, a))):
        ref = brute_distance(d.samples, *dst)
        atol = tolerance(*dst, d.samples)
        np.testing.assert_allclose(d.distances, ref, rtol=0, atol=atol)
        assert d.max == d.distances.max()
        assert np.array_equal(d.argmax, d.samples[np.argmax(d.distances)])
        assert abs(np.linalg.norm(d.argmax - d.argmax_closest) - d.max) <= atol
        # The statistics describe the surface: the area samples, not the vertices (the
        # vertices' when a degenerate mesh has no area samples).
        first = d.n_vertex_samples if d.n_samples > d.n_vertex_samples else 0
        area = ref[first:]
        np.testing.assert_allclose(d.mean, area.mean(), rtol=1e-12, atol=atol)
        np.testing.assert_allclose(d.rms, np.sqrt((area**2).mean()), rtol=1e-12, atol=atol)
        for q in (50, 95, 99):
            # numpy's linear interpolation, up to how its lerp is rounded (a few ulps).
            np.testing.assert_allclose(
                getattr(d, f"p{q}"),
                np.percentile(d.distances[first:], q),
                rtol=1e-13,
            )
        # Referenced vertices only, with their exact distances.
        used = np.unique(src[1])
        assert d.n_vertex_samples == len(used)
        np.testing.assert_allclose(
            d.vertex_distances[used], brute_distance(src[0][used], *dst), atol=atol
        )
        assert np.isnan(np.delete(d.vertex_distances, used)).all()
        # The bound holds on a denser, independent sample of the source.
        dense = meshbits.surface_samples(src, samples=3000, seed=seed ^ 1).points
        assert brute_distance(dense, *dst).max() <= d.upper + atol
    assert r.distance == max(r.a_to_b.max, r.b_to_a.max)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(meshes(), meshes())
def test_refinement_reaches_the_tolerance_on_random_meshes(a, b):
    scale = max(np.ptp(a[0], axis=0).max(), np.ptp(b[0], axis=0).max(), 1e-3)
    tol = 1e-3 * scale
    r = meshbits.hausdorff(a, b, samples=20, tolerance=tol, statistics=False)
    for d, (src, dst) in ((r.a_to_b, (a, b)), (r.b_to_a, (b, a))):
        assert d.converged is True
        assert d.max <= d.upper <= d.max + tol
        dense = meshbits.surface_samples(src, samples=3000, seed=9).points
        assert brute_distance(dense, *dst).max() <= d.upper + 1e-12 * (1 + scale)
    assert r.upper - r.distance <= tol


def test_max_only_gives_the_same_maximum_and_bound():
    a, b = load("bunny_res4.ply"), load("bunny_res3.ply")
    full = meshbits.hausdorff(a, b, samples=30_000, bounds=True)
    fast = meshbits.hausdorff(a, b, samples=30_000, bounds=True, statistics=False)
    for x, y in ((full.a_to_b, fast.a_to_b), (full.b_to_a, fast.b_to_a)):
        assert x.max == y.max and x.upper == y.upper
        assert np.array_equal(x.argmax, y.argmax) and np.array_equal(
            x.argmax_closest, y.argmax_closest
        )
        assert x.mean is not None and y.mean is None and y.p99 is None
    assert full.upper == fast.upper and full.distance == fast.distance


def test_a_relative_tolerance_certifies_within_that_fraction_of_each_maximum():
    """Each direction refined until its bound is within 1% of its own sampled maximum:
    far tighter than the unrefined bound, and inside a tight absolute refinement's."""
    a, b = load("bunny_res4.ply"), load("bunny_res3.ply")
    loose = meshbits.hausdorff(a, b, samples=5_000, bounds=True, statistics=False)
    r = meshbits.hausdorff(a, b, samples=5_000, relative_tolerance=0.01, statistics=False)
    assert r.relative_tolerance == 0.01 and r.tolerance is None
    for d in (r.a_to_b, r.b_to_a):
        assert d.converged
        assert d.max <= d.upper <= 1.01 * d.max
    assert r.upper < loose.upper
    tight = meshbits.hausdorff(a, b, samples=5_000, tolerance=1e-7 * r.distance)
    assert tight.distance <= r.upper and r.distance <= tight.upper
    with pytest.raises(meshbits.MeshbitsError, match="not both"):
        meshbits.hausdorff(a, b, tolerance=1e-3, relative_tolerance=0.01)
    with pytest.raises(meshbits.MeshbitsError, match="relative_tolerance must be positive"):
        meshbits.hausdorff(a, b, relative_tolerance=0.0)
    same = meshbits.hausdorff(a, a, samples=1_000, relative_tolerance=0.01)
    size = np.ptp(a[0], axis=0).max()
    assert same.distance <= 1e-15 * size and same.a_to_b.converged and same.b_to_a.converged
    assert same.upper <= 1e-8 * size


# --- hausdorff: analytic cases -----------------------------------------------------------


def test_mesh_against_itself_is_zero():
    mesh = load("bunny_res3.ply")
    size = np.ptp(mesh[0], axis=0).max()
    r = meshbits.hausdorff(mesh, mesh, tolerance=1e-4 * size)
    assert r.distance <= 1e-12 * size
    assert r.upper <= 1e-4 * size + 1e-12 * size
    assert r.a_to_b.mean <= 1e-14 * size


def test_translate_along_the_normal_of_a_flat_patch():
    v, f = square(6)
    t = 0.37
    r = meshbits.hausdorff((v, f), (v + np.array([0, 0, t]), f), bounds=True, tolerance=1e-9)
    assert abs(r.distance - t) <= 1e-14
    assert r.a_to_b.upper - t <= 1e-9 and r.a_to_b.converged
    for d in (r.a_to_b, r.b_to_a):
        assert d.p50 == pytest.approx(t, abs=1e-14) and d.rms == pytest.approx(t, abs=1e-14)


def test_parallel_unit_squares_at_distance_d():
    d = 0.25
    a, b = square(5), square(8, z=d)
    r = meshbits.hausdorff(a, b, tolerance=1e-6)
    assert abs(r.distance - d) <= 1e-14
    assert r.distance <= r.upper <= d + 1e-6
    assert r.a_to_b.converged and r.b_to_a.converged


def test_bump_lower_true_upper():
    # Flat unit square A against B, the same square with its centre vertex raised by 0.2.
    a = square(2)
    bv, bf = square(2)
    bv = bv.copy()
    bv[4, 2] = 0.2
    # The centre of A is nearest to the faces through the line x - y = +-0.5 and the apex:
    # normal (0.2, -0.2, 0.5), offset 0.1.
    at_centre = 0.1 / math.sqrt(0.33)
    # A dense grid on A bounds h(A, B) from below, and from above within its spacing.
    g = np.linspace(0, 1, 301)
    grid = np.column_stack([np.repeat(g, g.size), np.tile(g, g.size), np.zeros(g.size**2)])
    dense = brute_distance(grid, bv, bf).max()
    assert dense == pytest.approx(at_centre, abs=1e-15)
    truth_low, truth_high = dense, dense + (g[1] - g[0]) / math.sqrt(2)
    r = meshbits.hausdorff(a, (bv, bf), samples=200, bounds=True)
    assert r.a_to_b.max <= truth_high and truth_low <= r.a_to_b.upper
    assert r.b_to_a.max == pytest.approx(0.2, abs=1e-15)  # the apex is a vertex sample
    assert r.b_to_a.upper >= 0.2
    refined = meshbits.hausdorff(a, (bv, bf), samples=200, tolerance=1e-7)
    d = refined.a_to_b
    assert d.max <= truth_high and truth_low <= d.upper <= d.max + 1e-7
    assert d.converged and r.a_to_b.upper - r.a_to_b.max > 1e-3


def test_icosphere_against_a_fine_sphere_approaches_the_sagitta():
    coarse = trimesh.creation.icosphere(subdivisions=2)
    fine = trimesh.creation.icosphere(subdivisions=6)

    def sagitta(mesh):  # 1 - distance from the centre to the farthest-in face plane
        n = mesh.face_normals
        return 1.0 - np.abs((n * mesh.vertices[mesh.faces[:, 0]]).sum(1)).min()

    s, s_fine = sagitta(coarse), sagitta(fine)
    r = meshbits.hausdorff(coarse, fine, samples=200_000, statistics=False, tolerance=1e-6)
    # Points of the fine sphere stand at most s_fine below the true sphere.
    assert s - s_fine - 1e-6 <= r.distance <= r.upper <= s + 1e-6
    assert abs(r.distance - s) <= 2 * s_fine


def test_refine_budget_stops_and_reports():
    a, b = load("bunny_res4.ply"), load("bunny_res3.ply")
    r = meshbits.hausdorff(a, b, samples=1000, tolerance=1e-9, refine_budget=3000, statistics=False)
    assert r.a_to_b.converged is False or r.b_to_a.converged is False
    for d in (r.a_to_b, r.b_to_a):
        assert d.refined_points <= 3000 and d.upper >= d.max


# --- determinism and frames --------------------------------------------------------------


@pytest.mark.parametrize("statistics", [True, False])
def test_bit_identical_on_one_and_two_threads(statistics):
    a, b = load("bunny_res3.ply"), load("bunny.ply")
    kw = dict(samples=50_000, seed=11, statistics=statistics, tolerance=2e-5)
    with meshbits.threads(1):
        one = meshbits.hausdorff(a, b, return_samples=statistics, **kw)
    with meshbits.threads(2):
        two = meshbits.hausdorff(a, b, return_samples=statistics, **kw)
    assert json.dumps(one.to_dict()) == json.dumps(two.to_dict())
    if statistics:
        for x, y in ((one.a_to_b, two.a_to_b), (one.b_to_a, two.b_to_a)):
            assert np.array_equal(x.distances, y.distances)
            assert np.array_equal(x.vertex_distances, y.vertex_distances, equal_nan=True)
    pts = meshbits.surface_samples(a, seed=1).points
    with meshbits.threads(1):
        q1 = meshbits.ClosestPoints(b).query(pts)
    with meshbits.threads(2):
        q2 = meshbits.ClosestPoints(b).query(pts)
    assert np.array_equal(q1.distances, q2.distances) and np.array_equal(q1.faces, q2.faces)
    assert np.array_equal(q1.points, q2.points)


def test_far_from_the_origin():
    # Coordinates on a 2**-30 grid stay exact when 1e6 is added.
    a, b = load("bunny_res4.ply"), load("bunny_res3.ply")
    a = (np.round(a[0] * 2**30) / 2**30, a[1])
    b = (np.round(b[0] * 2**30) / 2**30, b[1])
    near = meshbits.hausdorff(a, b, samples=20_000, tolerance=1e-5)
    far = meshbits.hausdorff((a[0] + 1e6, a[1]), (b[0] + 1e6, b[1]), samples=20_000, tolerance=1e-5)
    for x, y in ((near.a_to_b, far.a_to_b), (near.b_to_a, far.b_to_a)):
        for name in ("max", "mean", "rms", "p50", "p95", "p99", "upper"):
            assert getattr(y, name) == pytest.approx(getattr(x, name), rel=1e-9), name
        np.testing.assert_allclose(y.argmax - 1e6, x.argmax, atol=1e-9)
    pts = meshbits.surface_samples(a, seed=2).points
    d0 = meshbits.ClosestPoints(b).query(pts).distances
    d1 = meshbits.ClosestPoints((b[0] + 1e6, b[1])).query(pts + 1e6).distances
    np.testing.assert_allclose(d1, d0, rtol=1e-9, atol=1e-9 * np.ptp(b[0]))


# --- peers (optional) --------------------------------------------------------------------


def _bunny_pair():
    v, f = load("bunny.ply")
    return (v, f), (quantize(v, 10), f)


def test_agrees_with_libigl():
    igl = pytest.importorskip("igl")
    a, b = _bunny_pair()
    r = meshbits.hausdorff(a, b, samples=100_000, return_samples=True)
    d2, _, _ = igl.point_mesh_squared_distance(r.a_to_b.samples, b[0], b[1].astype(np.int64))
    assert np.sqrt(d2).max() == pytest.approx(r.a_to_b.max, rel=1e-6)
    np.testing.assert_allclose(np.sqrt(d2), r.a_to_b.distances, rtol=1e-6, atol=1e-12)


def test_agrees_with_open3d():
    o3d = pytest.importorskip("open3d")
    a, b = _bunny_pair()
    r = meshbits.hausdorff(a, b, samples=100_000, return_samples=True)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(
        o3d.core.Tensor(b[0].astype(np.float32)), o3d.core.Tensor(b[1].astype(np.uint32))
    )
    d = scene.compute_distance(o3d.core.Tensor(r.a_to_b.samples.astype(np.float32))).numpy()
    # Open3D works in float32: agree to its precision (coordinates of size 0.2).
    assert abs(float(d.max()) - r.a_to_b.max) <= 1e-6 * np.ptp(b[0])


# --- bad input ---------------------------------------------------------------------------


def test_bad_input_is_refused_clearly():
    v, f = square(1)
    with pytest.raises(ValueError, match="faces has no rows"):
        meshbits.hausdorff((v, np.zeros((0, 3), int)), (v, f))
    with pytest.raises(ValueError, match="not finite"):
        meshbits.ClosestPoints((np.where(v == 1, np.nan, v), f))
    with pytest.raises(ValueError, match="out of range"):
        meshbits.hausdorff((v, f), (v, f + 1))
    with pytest.raises(ValueError, match="tolerance must be positive"):
        meshbits.hausdorff((v, f), (v, f), tolerance=0.0)
    with pytest.raises(ValueError, match="tolerance must be positive"):
        meshbits.hausdorff((v, f), (v, f), tolerance=float("nan"))
    with pytest.raises(ValueError, match="samples must be non-negative"):
        meshbits.hausdorff((v, f), (v, f), samples=-1)
    with pytest.raises(TypeError, match="seed must be an integer"):
        meshbits.hausdorff((v, f), (v, f), seed=1.5)
    with pytest.raises(ValueError, match="seed must be in"):
        meshbits.hausdorff((v, f), (v, f), seed=-1)
    with pytest.raises(TypeError, match="expected a trimesh"):
        meshbits.hausdorff("mesh.ply", (v, f))
    cp = meshbits.ClosestPoints((v, f))
    with pytest.raises(ValueError, match=r"shape \(n, 3\)"):
        cp.query(np.zeros((4, 2)))
    with pytest.raises(ValueError, match="not finite"):
        cp.query([[0.0, np.inf, 0.0]])
    with pytest.raises(TypeError, match="real numbers"):
        cp.query([["a", "b", "c"]])


def test_zero_area_mesh_samples_vertices_and_bounds_its_edges():
    v = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]])
    a = (v, [[0, 1, 2]])  # a segment from 0 to 2
    b = (np.array([[0.0, 0, 0], [0, 1, 0], [0, 0, 1]]), [[0, 1, 2]])  # a triangle at x = 0
    r = meshbits.hausdorff(a, b, samples=100, tolerance=1e-6)
    assert r.a_to_b.n_samples == 3  # no area: only the vertices
    assert r.a_to_b.max == 2.0 and r.a_to_b.upper <= 2.0 + 1e-6


# --- CLI ---------------------------------------------------------------------------------


def test_cli_json_and_table(capsys):
    a, b = str(DATA / "bunny_res4.ply"), str(DATA / "bunny_res3.ply")
    assert main(["hausdorff", a, b, "--samples", "5000", "--seed", "3", "--json", "--quiet"]) == 0
    out = json.loads(capsys.readouterr().out)
    ref = meshbits.hausdorff(load("bunny_res4.ply"), load("bunny_res3.ply"), samples=5000, seed=3)
    assert out["distance"] == ref.distance and out["a_to_b"]["p95"] == ref.a_to_b.p95
    assert main(["hausdorff", a, b, "--samples", "2000", "--tolerance", "1e-5", "--max-only"]) == 0
    captured = capsys.readouterr()
    assert "certified upper bound" in captured.out and "mean" not in captured.out
    assert "building the BVH" in captured.err
    # --bounds alone: each direction's bound within 1% of its sampled maximum.
    assert main(["hausdorff", a, b, "--samples", "2000", "--bounds", "--json", "--quiet"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["relative_tolerance"] == 0.01 and out["tolerance"] is None
    for side in ("a_to_b", "b_to_a"):
        assert out[side]["converged"] and out[side]["upper"] <= 1.01 * out[side]["max"]
    assert main(["hausdorff", a, str(DATA / "missing.ply")]) == 2
    assert "no such mesh file" in capsys.readouterr().err
    assert main(["hausdorff", a, b, "--tolerance", "-1", "--quiet"]) == 2


# --- refusals found by the fuzz campaign (benches/fuzz.py) --------------------------------

TRIANGLE = (np.eye(3), np.array([[0, 1, 2]]))


def test_a_sample_count_beyond_memory_is_refused_not_aborted():
    """3e9 samples asked for 72 GB at once: the allocation failure aborted Python."""
    code = (
        "import numpy as np, meshbits\n"
        "try:\n"
        "    meshbits.surface_samples((np.eye(3), [[0, 1, 2]]), samples=3_000_000_000)\n"
        "except meshbits.MeshbitsError as err:\n"
        "    print(err)\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert "3000000000 area samples need 72.0 GB" in done.stdout


@pytest.mark.parametrize("name", ["samples", "refine_budget"])
def test_counts_beyond_2_to_the_32_are_refused(name):
    """samples=2**64 raised OverflowError from the binding."""
    with pytest.raises(meshbits.MeshbitsError, match=name):
        meshbits.hausdorff(TRIANGLE, TRIANGLE, **{name: 2**64})
    with pytest.raises(meshbits.MeshbitsError, match="samples"):
        meshbits.surface_samples(TRIANGLE, samples=2**32)


def test_a_tolerance_that_is_not_a_number_is_a_type_error():
    """tolerance='x' raised float()'s ValueError."""
    with pytest.raises(TypeError, match="tolerance"):
        meshbits.hausdorff(TRIANGLE, TRIANGLE, tolerance="x")


def test_points_beyond_the_supported_reach_are_refused():
    """A query at 1e300 answered an infinite distance (its square overflowed)."""
    tree = meshbits.ClosestPoints(TRIANGLE)
    with pytest.raises(meshbits.MeshbitsError, match=r"point 1 lies 1\.000e300"):
        tree.query([[0.0, 0.0, 0.0], [1e300, 0.0, 0.0]])
    assert tree.query([[1e30, 0.0, 0.0]]).distances[0] == pytest.approx(1e30)


def test_meshes_too_far_apart_are_refused():
    """A triangle at -1e308 against one at the origin gave an infinite distance."""
    far = (np.full((3, 3), -1e308), np.array([[0, 1, 2]]))
    for a, b in [(far, TRIANGLE), (TRIANGLE, far)]:
        with pytest.raises(meshbits.MeshbitsError, match="more than the supported 1e36"):
            meshbits.hausdorff(a, b)


def test_samples_of_a_mesh_near_the_float64_limit_are_finite():
    """The centre (lo + hi) / 2 of a box at -1e308 overflowed: every sample was infinite."""
    far = (np.full((3, 3), -1e308), np.array([[0, 1, 2]]))
    points = meshbits.surface_samples(far, samples=10).points
    assert np.isfinite(points).all() and (points == -1e308).all()


def test_ragged_point_lists_are_refused_naming_the_argument():
    """A list of rows of different lengths raised numpy's ValueError."""
    with pytest.raises(meshbits.MeshbitsError, match="points must be"):
        meshbits.ClosestPoints(TRIANGLE).query([[0.0, 0.0, 0.0], [1.0, 2.0]])
    with pytest.raises(meshbits.MeshbitsError, match="faces must be"):
        meshbits.surface_samples(np.eye(3), [[0, 1, 2], [0, 1]])


def _overlapping_fans(n_faces: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Polygons of corners from all over a mesh, fan-triangulated: what the fuzz campaign
    built from bunny_res4 (rows of 8 to 255 random vertices)."""
    rng = np.random.default_rng(seed)
    vertices = rng.uniform(0.0, 1.0, (453, 3))
    return vertices, rng.integers(0, 453, (n_faces, 3))


def test_overlapping_triangles_are_refused_not_measured_for_minutes():
    """10,000 closest-point queries against 240k such faces took 140 s; compress on 5,688
    took 62 s. A BVH cannot cull boxes that each span the mesh."""
    from meshbits.mesh import MAX_BOX_OVERLAP, box_overlap

    bunny = load("bunny.ply")
    assert box_overlap(*bunny) < 0.1
    tangle = _overlapping_fans(5688)
    assert box_overlap(*tangle) > MAX_BOX_OVERLAP
    with pytest.raises(meshbits.MeshbitsError, match="overlap"):
        meshbits.hausdorff(tangle, bunny, samples=1000)
    with pytest.raises(meshbits.MeshbitsError, match="overlap"):
        meshbits.ClosestPoints(tangle)
    with pytest.raises(meshbits.MeshbitsError, match="overlap"):
        meshbits.Reference(bunny).hausdorff(tangle)
    with pytest.raises(meshbits.MeshbitsError, match="overlap"):
        meshbits.compress(tangle, error=0.01, relative=True)


def test_a_mesh_of_subnormal_size_is_not_refused_as_overlapping():
    """One triangle 1.2e-38 long: its boxes' pads were subnormal, below the f32 boxes'
    rounding, and it scored 617 boxes per point (found by hypothesis)."""
    vertices = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 1.1754943508222875e-38]])
    closest = meshbits.ClosestPoints((vertices, [[0, 0, 2]]))
    assert closest.query(np.zeros((1, 3))).distances[0] == 0.0


def test_parts_far_apart_along_one_axis_are_measured_not_refused():
    """Two bunnies 1e4 apart along x, one mesh: the empty middle of its long box holds no
    triangle, so they overlap no more than one bunny does (each side was widened by 1e-3
    of the largest, 10 m on a 0.15 m bunny: refused as 'triangles overlap')."""
    from meshbits.mesh import box_overlap

    vertices, faces = load("bunny.ply")
    two = (
        np.vstack([vertices, vertices + np.array([1e4, 0.0, 0.0])]),
        np.vstack([faces, faces + len(vertices)]),
    )
    assert box_overlap(*two) <= box_overlap(vertices, faces)
    clustered = meshbits.cluster(two, bits=20)
    result = meshbits.hausdorff(two, clustered, samples=2000, tolerance=1e-6)
    assert result.a_to_b.converged and result.b_to_a.converged
    assert 0 < result.upper < 1e4 * 2.0**-19


def _box_overlap_numpy(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Plain numpy: the triangles' padded box volumes over the mesh's padded box volume."""
    used = np.unique(faces)
    low, high = vertices[used].min(axis=0), vertices[used].max(axis=0)
    largest = float(np.max(high - low))
    if largest == 0:
        return 0.0
    pad = np.maximum(1e-3 * np.maximum(high - low, 1e-5 * largest), 1e3 * 2.0**-126)
    corners = vertices[faces]
    extent = corners.max(axis=1) - corners.min(axis=1) + pad
    return float(np.prod(extent, axis=1).sum() / np.prod(high - low + pad))


@settings(max_examples=60, deadline=None)
@given(
    n_vertices=st.integers(3, 60),
    n_faces=st.integers(1, 300),
    seed=st.integers(0, 2**32 - 1),
    scale=st.floats(1e-6, 1e6),
    stretch=st.sampled_from([1.0, 1e-4, 1e4, 0.0]),
)
def test_box_overlap_matches_numpy(n_vertices, n_faces, seed, scale, stretch):
    from meshbits.mesh import box_overlap

    rng = np.random.default_rng(seed)
    vertices = scale * rng.normal(size=(n_vertices, 3)) * [1.0, 1.0, stretch]
    faces = rng.integers(0, n_vertices, (n_faces, 3))
    expected = _box_overlap_numpy(vertices, faces)
    assert box_overlap(vertices, faces) == pytest.approx(expected, rel=1e-9, abs=1e-300)
    assert box_overlap(vertices, faces.astype(np.uint32)) == box_overlap(vertices, faces)
    # The BVH measures it on its f32 boxes while it is built: each side rounded outward by
    # an f32 ulp of the coordinates, at least 1e-3 of the largest side once padded.
    tree = meshbits._core.build_tree(vertices, faces.astype(np.uint32))
    assert tree.box_overlap == pytest.approx(expected, rel=1e-3, abs=1e-300)


def test_a_threshold_decides_the_certified_bound():
    """``threshold`` settles pieces at the threshold and stops at a point beyond it: the
    verdict agrees with the bound refined to a tight tolerance on either side."""
    bunny = load("bunny.ply")
    clustered = meshbits.cluster(bunny, bits=7)
    reference = meshbits.Reference(bunny, samples=20_000)
    tight = reference.hausdorff(clustered, samples=20_000, tolerance=1e-6)
    assert tight.a_to_b.converged and tight.b_to_a.converged
    above = 1.05 * tight.upper
    decided = reference.hausdorff(clustered, samples=20_000, tolerance=1e-6, threshold=above)
    assert decided.a_to_b.converged and decided.b_to_a.converged
    assert tight.distance <= decided.upper <= above
    below = 0.97 * tight.distance
    decided = reference.hausdorff(clustered, samples=20_000, tolerance=1e-6, threshold=below)
    assert decided.distance > below
    assert decided.distance <= tight.upper
    with pytest.raises(meshbits.MeshbitsError, match="threshold"):
        reference.hausdorff(clustered, tolerance=1e-6, threshold=float("nan"))


def test_once_the_reference_side_exceeds_a_threshold_the_other_is_not_refined():
    """The answer is no as soon as a point of the reference lies beyond the threshold:
    the candidate's side keeps its unrefined bound (refining it to decide took seconds
    on the dragon's answers), and the verdict is the same as with both sides refined."""
    bunny = load("bunny.ply")
    # The clustered copy as the reference: its side (9.7e-4) is the larger one.
    reference = meshbits.Reference(meshbits.cluster(bunny, bits=7), samples=20_000)
    tight = reference.hausdorff(bunny, samples=20_000, tolerance=1e-6)
    assert tight.a_to_b.max > tight.b_to_a.upper
    between = 0.5 * (tight.a_to_b.max + tight.b_to_a.max)
    kept = reference.hausdorff(bunny, samples=20_000, bounds=True)
    assert kept.b_to_a.upper > between  # deciding that side would need refinement
    decided = reference.hausdorff(bunny, samples=20_000, tolerance=1e-6, threshold=between)
    assert decided.a_to_b.max > between and decided.upper > between
    assert decided.b_to_a.refined_points == 0 and decided.b_to_a.converged is False
    assert decided.b_to_a.upper == pytest.approx(kept.b_to_a.upper)
    # Beyond the reference side's maximum, the candidate side is refined as before.
    decided = reference.hausdorff(
        bunny, samples=20_000, tolerance=1e-6, threshold=1.05 * tight.upper
    )
    assert decided.b_to_a.converged and decided.b_to_a.refined_points > 0
