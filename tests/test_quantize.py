"""Grid quantization and vertex clustering, checked against plain numpy references."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, assume, example, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import meshbits
from meshbits.cli import main

DATA = Path(__file__).parent / "data"
EPS = np.finfo(np.float64).eps
SETTINGS = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])


# --- independent numpy reference -------------------------------------------------------


def reference_grid(points, bits, grid="cube", box=None):
    """Box min and per-axis step of the documented grid."""
    lo, hi = (points.min(axis=0), points.max(axis=0)) if box is None else map(np.asarray, box)
    side = hi - lo
    levels = 2.0**bits - 1
    step = np.full(3, side.max() / levels) if grid == "cube" else side / levels
    return lo, step


def reference_codes(points, lo, step, bits):
    """round((x - lo) / step), halves up, 0 where the step is 0, as int64."""
    with np.errstate(divide="ignore", invalid="ignore"):
        y = (points - lo) / step
    whole = np.floor(np.where(step > 0, y, 0.0))
    q = whole + (np.where(step > 0, y, 0.0) - whole >= 0.5)
    return np.clip(q, 0, 2**bits - 1).astype(np.int64)


def reference_cluster(vertices, faces, bits, grid="cube", duplicates="keep"):
    """Clustering with np.unique on code rows, remap, filter: the documented semantics."""
    lo, step = reference_grid(vertices, bits, grid)
    q = reference_codes(vertices, lo, step, bits)
    rows, first, inverse = np.unique(q, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    cf = inverse[faces]
    keep = (cf[:, 0] != cf[:, 1]) & (cf[:, 1] != cf[:, 2]) & (cf[:, 2] != cf[:, 0])
    degenerate = int((~keep).sum())
    duplicate = 0
    if duplicates != "keep" and keep.any():
        candidates = np.flatnonzero(keep)
        tri = cf[candidates]
        if duplicates == "any":
            key = np.sort(tri, axis=1)
        else:
            start = np.argmin(tri, axis=1)
            key = np.stack([tri[np.arange(len(tri)), (start + j) % 3] for j in range(3)], 1)
        _, first_face = np.unique(key, axis=0, return_index=True)
        unique_keep = np.zeros(len(faces), dtype=bool)
        unique_keep[candidates[first_face]] = True
        duplicate = int(keep.sum() - unique_keep.sum())
        keep = unique_keep
    used = np.unique(cf[keep])
    kept_clusters = used[np.argsort(first[used], kind="stable")]
    new_id = np.full(len(rows), -1, dtype=np.int64)
    new_id[kept_clusters] = np.arange(len(kept_clusters))
    return {
        "vertices": lo + rows[kept_clusters] * step,
        "faces": new_id[cf[keep]],
        "codes": rows[kept_clusters],
        "vertex_map": new_id[inverse],
        "face_index": np.flatnonzero(keep),
        "merged_vertices": len(vertices) - len(rows),
        "unreferenced_vertices": len(rows) - len(kept_clusters),
        "degenerate_faces": degenerate,
        "duplicate_faces": duplicate,
    }


def assert_same_clustering(result, expected):
    np.testing.assert_array_equal(result.vertex_map, expected["vertex_map"])
    np.testing.assert_array_equal(result.faces, expected["faces"])
    np.testing.assert_array_equal(result.face_index, expected["face_index"])
    np.testing.assert_array_equal(result.codes, expected["codes"])
    np.testing.assert_array_equal(result.vertices, expected["vertices"])
    for name in ("merged_vertices", "unreferenced_vertices", "degenerate_faces", "duplicate_faces"):
        assert getattr(result, name) == expected[name], name


def slack(points, grid_size):
    """float64 rounding allowance of positions and distances (see docs/quantize.md)."""
    return 8 * EPS * (float(np.abs(points).max()) + grid_size)


# --- strategies -------------------------------------------------------------------------


@st.composite
def point_sets(draw, dyadic=False, max_points=40):
    """Points ``(unit + c) * 2**e``; dyadic units make every operation below exact."""
    n = draw(st.integers(1, max_points))
    if dyadic:
        unit = draw(hnp.arrays(np.int64, (n, 3), elements=st.integers(-(2**20), 2**20))) / 2**20
    else:
        unit = draw(
            hnp.arrays(
                np.float64, (n, 3), elements=st.floats(-1, 1, allow_subnormal=False, width=64)
            )
        )
    c = draw(st.integers(-8, 8))
    return (unit + c) * 2.0 ** draw(st.integers(-30, 30))


bits_st = st.integers(1, 32)
grid_st = st.sampled_from(["cube", "axes"])


@st.composite
def meshes(draw):
    points = draw(point_sets(max_points=30))
    m = draw(st.integers(1, 60))
    faces = draw(hnp.arrays(np.int64, (m, 3), elements=st.integers(0, len(points) - 1)))
    return points, faces


def refused_by_underflow(points, bits, grid):
    side = points.max(axis=0) - points.min(axis=0)
    needed = np.full(3, side.max()) if grid == "cube" else side
    return bool(np.any((needed > 0) & (needed / (2.0**bits - 1) < np.finfo(np.float64).tiny)))


# --- quantize: properties ----------------------------------------------------------------


@SETTINGS
@given(point_sets(), bits_st, grid_st)
def test_codes_match_the_reference_and_stay_in_range(points, bits, grid):
    if refused_by_underflow(points, bits, grid):
        with pytest.raises(meshbits.MeshbitsError, match="too small"):
            meshbits.quantize(points, bits, grid=grid)
        return
    result = meshbits.quantize(points, bits, grid=grid)
    lo, step = reference_grid(points, bits, grid)
    np.testing.assert_array_equal(result.step, step)
    np.testing.assert_array_equal(result.origin, lo)
    assert result.codes.dtype == (np.uint16 if bits <= 16 else np.uint32)
    codes = result.codes.astype(np.int64)
    assert codes.min() >= 0 and codes.max() <= 2**bits - 1
    np.testing.assert_array_equal(codes, reference_codes(points, lo, step, bits))
    np.testing.assert_array_equal(result.positions, lo + codes * step)
    np.testing.assert_array_equal(
        meshbits.dequantize(result.codes, result.origin, result.step), result.positions
    )


@SETTINGS
@given(point_sets(), bits_st, grid_st)
def test_measured_displacement_is_within_the_bound(points, bits, grid):
    assume(not refused_by_underflow(points, bits, grid))
    result = meshbits.quantize(points, bits, grid=grid)
    measured = np.linalg.norm(result.positions - points, axis=1).max()
    assert result.max_displacement == pytest.approx(measured, rel=1e-12, abs=1e-300)
    assert result.bound == pytest.approx(0.5 * np.linalg.norm(result.step), rel=1e-15)
    assert result.max_displacement <= result.bound * (1 + 1e-12) + slack(points, result.grid_size)


@SETTINGS
@given(point_sets(), bits_st, grid_st)
def test_quantizing_the_positions_again_gives_the_same_codes(points, bits, grid):
    assume(not refused_by_underflow(points, bits, grid))
    first = meshbits.quantize(points, bits, grid=grid)
    # Precondition of idempotence (docs/quantize.md): the step is not below 2^-44 times
    # the coordinates, so the float64 positions hold the grid.
    scale = float(np.abs(points).max())
    assume(np.all((first.step == 0) | (first.step >= 2.0**-44 * scale)))
    top = meshbits.dequantize(np.full((1, 3), 2**bits - 1), first.origin, first.step)[0]
    again = meshbits.quantize(first.positions, bits, grid=grid, box=(first.origin, top))
    np.testing.assert_array_equal(again.codes, first.codes)
    # The rebuilt box's side top - origin may differ from S by an ulp, and so the step.
    np.testing.assert_allclose(
        again.positions, first.positions, rtol=0, atol=slack(points, first.grid_size)
    )


@SETTINGS
@given(
    point_sets(dyadic=True),
    bits_st,
    st.integers(-20, 20),
    hnp.arrays(np.int64, 3, elements=st.integers(-(2**20), 2**20)),
)
def test_cube_codes_ignore_uniform_scale_and_translation(points, bits, power, shift):
    # Power-of-two scales and dyadic shifts (at most 2^10 times the points' magnitude, so
    # the sums fit in 53 bits) keep every float64 operation exact: the codes must be
    # identical, ties included.
    magnitude = 2.0 ** np.ceil(np.log2(max(float(np.abs(points).max()), 2.0**-60)))
    offset = shift / 2**10 * magnitude * 2.0**power
    moved = points * 2.0**power + offset
    assert np.array_equal((moved - offset) / 2.0**power, points)
    a = meshbits.quantize(points, bits)
    b = meshbits.quantize(moved, bits)
    np.testing.assert_array_equal(a.codes, b.codes)


def test_cube_codes_under_an_arbitrary_scale_differ_only_at_rounding_ties():
    rng = np.random.default_rng(5)
    points = rng.uniform(-1, 1, (20000, 3))
    a = meshbits.quantize(points, 10)
    b = meshbits.quantize(points * 3.7 + np.array([1e3, -2.5, 0.1]), 10)
    differ = np.any(a.codes != b.codes, axis=1)
    assert differ.sum() <= 2
    if differ.any():
        y = (points[differ] - points.min(axis=0)) / a.step
        assert np.abs(y - np.floor(y) - 0.5).min() < 1e-9


@SETTINGS
@given(point_sets(max_points=20), point_sets(max_points=20), bits_st, grid_st)
def test_a_shared_box_gives_identical_codes_to_identical_points(a, b, bits, grid):
    both = np.vstack([a, b])
    box = (both.min(axis=0), both.max(axis=0))
    assume(not refused_by_underflow(both, bits, grid))
    common = a[: len(a) // 2 + 1]
    qa = meshbits.quantize(a, bits, grid=grid, box=box)
    qb = meshbits.quantize(np.vstack([b, common]), bits, grid=grid, box=box)
    np.testing.assert_array_equal(qa.codes[: len(common)], qb.codes[len(b) :])
    np.testing.assert_array_equal(qa.positions[: len(common)], qb.positions[len(b) :])


@SETTINGS
@given(point_sets(), bits_st, grid_st)
def test_centered_codes_are_the_corner_codes_shifted(points, bits, grid):
    assume(not refused_by_underflow(points, bits, grid))
    corner = meshbits.quantize(points, bits, grid=grid)
    centered = meshbits.quantize(points, bits, grid=grid, convention="centered")
    expected_dtype = np.int16 if bits <= 15 else np.int32 if bits <= 31 else np.int64
    assert centered.codes.dtype == expected_dtype
    offset = 2 ** (bits - 1) - 1
    codes = centered.codes.astype(np.int64)
    np.testing.assert_array_equal(codes, corner.codes.astype(np.int64) - offset)
    assert codes.min() >= -(2 ** (bits - 1)) + 1 and codes.max() <= 2 ** (bits - 1)
    np.testing.assert_array_equal(centered.positions, corner.positions)
    np.testing.assert_array_equal(centered.origin, corner.origin + offset * corner.step)
    np.testing.assert_allclose(
        meshbits.dequantize(centered.codes, centered.origin, centered.step),
        corner.positions,
        rtol=0,
        atol=slack(points, corner.grid_size),
    )


# --- quantize: edge cases ----------------------------------------------------------------


def test_bound_is_sqrt3_over_2_steps_on_the_cube_grid():
    points = np.array([[0.0, 0, 0], [2.0, 1.0, 0.5]])
    cube = meshbits.quantize(points, 8)
    assert cube.grid_size == 2.0
    np.testing.assert_array_equal(cube.step, np.full(3, 2.0 / 255))
    assert cube.bound == pytest.approx(math.sqrt(3) / 2 * 2.0 / 255, rel=1e-15)
    axes = meshbits.quantize(points, 8, grid="axes")
    np.testing.assert_array_equal(axes.step, np.array([2.0, 1.0, 0.5]) / 255)
    assert axes.bound == pytest.approx(0.5 * math.sqrt(4 + 1 + 0.25) / 255, rel=1e-15)
    np.testing.assert_array_equal(axes.codes, [[0, 0, 0], [255, 255, 255]])
    np.testing.assert_array_equal(cube.codes, [[0, 0, 0], [255, 128, 64]])


@pytest.mark.parametrize("grid", ["cube", "axes"])
@pytest.mark.parametrize("offset", [0.0, -7.25, 1e9])
def test_identical_points_get_code_zero_and_keep_their_position(grid, offset):
    points = np.full((5, 3), 0.1) + offset
    result = meshbits.quantize(points, 10, grid=grid)
    np.testing.assert_array_equal(result.codes, 0)
    np.testing.assert_array_equal(result.positions, points)
    np.testing.assert_array_equal(result.step, 0.0)
    assert result.bound == result.max_displacement == result.grid_size == 0.0


@pytest.mark.parametrize("grid", ["cube", "axes"])
def test_flat_mesh_keeps_its_flat_coordinate_exactly(grid):
    rng = np.random.default_rng(1)
    points = np.column_stack([rng.uniform(0, 1, 200), rng.uniform(0, 2, 200), np.full(200, 0.3)])
    result = meshbits.quantize(points, 6, grid=grid)
    np.testing.assert_array_equal(result.codes[:, 2], 0)
    np.testing.assert_array_equal(result.positions[:, 2], 0.3)
    assert result.step[2] == (result.grid_size / 63 if grid == "cube" else 0.0)
    assert result.max_displacement <= result.bound
    lo, step = reference_grid(points, 6, grid)
    np.testing.assert_array_equal(result.codes, reference_codes(points, lo, step, 6))


def test_one_bit_snaps_to_the_box_corners():
    points = np.array([[0.0, 0, 0], [0.49, 0.5, 0.51], [1.0, 1.0, 1.0]])
    result = meshbits.quantize(points, 1)
    np.testing.assert_array_equal(result.codes, [[0, 0, 0], [0, 1, 1], [1, 1, 1]])
    np.testing.assert_array_equal(result.positions, [[0, 0, 0], [0, 1, 1], [1, 1, 1]])
    centered = meshbits.quantize(points, 1, convention="centered")
    np.testing.assert_array_equal(centered.codes, result.codes)


def test_thirty_two_bits_are_exact_integers():
    k = np.arange(0, 2**32, 2**32 // 1000 + 7, dtype=np.int64)
    points = np.column_stack([k, k[::-1], np.zeros_like(k)]).astype(np.float64)
    points[-1, 0] = 2**32 - 1
    result = meshbits.quantize(points, 32, box=([0, 0, 0], [2**32 - 1, 2**32 - 1, 0]))
    assert result.codes.dtype == np.uint32
    np.testing.assert_array_equal(result.step, [1.0, 1.0, 1.0])
    np.testing.assert_array_equal(result.codes.astype(np.int64), points.astype(np.int64))
    assert result.max_displacement == 0.0
    box = ([0, 0, 0], [2**32 - 1] * 3)
    centered = meshbits.quantize(points, 32, box=box, convention="centered")
    assert centered.codes.dtype == np.int64
    assert centered.codes.max() == 2**31 and centered.codes.min() >= -(2**31) + 1


def test_huge_offsets_keep_their_codes():
    rng = np.random.default_rng(2)
    near = rng.integers(0, 2**12, (500, 3)) / 2**10  # dyadic: x - min is exact at 2^30
    far = near + 2.0**30
    for bits in (8, 16, 24, 32):
        a, b = meshbits.quantize(near, bits), meshbits.quantize(far, bits)
        np.testing.assert_array_equal(a.codes, b.codes)
        np.testing.assert_array_equal(a.step, b.step)
    # A 1e9 offset with non-dyadic data: codes computed relative to the min, positions
    # within the bound plus the spacing of float64 at 1e9.
    points = rng.uniform(-1, 1, (1000, 3)) + 1e9
    result = meshbits.quantize(points, 20)
    lo, step = reference_grid(points, 20)
    np.testing.assert_array_equal(result.codes, reference_codes(points, lo, step, 20))
    assert result.max_displacement <= result.bound + slack(points, result.grid_size)


def test_empty_points_need_a_box():
    result = meshbits.quantize(np.empty((0, 3)), 8, box=([0, 0, 0], [1, 1, 1]))
    assert result.codes.shape == (0, 3) and result.positions.shape == (0, 3)
    assert result.max_displacement == 0.0
    with pytest.raises(ValueError, match="empty"):
        meshbits.quantize(np.empty((0, 3)), 8)


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"bits": 0}, ValueError, "bits must be from 1 to 32"),
        ({"bits": 33}, ValueError, "bits must be from 1 to 32"),
        ({"bits": 8.0}, TypeError, "bits must be an integer"),
        ({"bits": True}, TypeError, "bits must be an integer"),
        ({"bits": 8, "grid": "sphere"}, ValueError, "grid must be one of"),
        ({"bits": 8, "convention": "middle"}, ValueError, "convention must be one of"),
        ({"bits": 8, "box": [0, 1]}, ValueError, r"two 3-vectors, got shape \(2,\)"),
        ({"bits": 8, "box": "ab"}, TypeError, "box must be"),
        ({"bits": 8, "box": ([0, 2, 0], [1, 1, 1])}, meshbits.MeshbitsError, "min exceeds"),
        ({"bits": 8, "box": ([0, np.nan, 0], [1, 1, 1])}, meshbits.MeshbitsError, "finite"),
        ({"bits": 8, "box": ([0, 0, 0], [1, 1, 0.5])}, meshbits.MeshbitsError, "point 2 lies"),
    ],
)
def test_bad_parameters_are_refused(kwargs, error, match):
    points = np.array([[0.0, 0, 0], [0.5, 0.5, 0.5], [1.0, 1, 1]])
    with pytest.raises(error, match=match):
        meshbits.quantize(points, **kwargs)


@pytest.mark.parametrize(
    ("points", "error", "match"),
    [
        (np.array([[0.0, 0, 0], [np.nan, 0, 0]]), ValueError, r"points\[1\].*not finite"),
        (np.array([[0.0, 0, 0], [0, np.inf, 0]]), ValueError, "not finite"),
        (np.zeros((4, 2)), ValueError, r"shape \(n, 3\)"),
        (np.zeros(3), ValueError, r"shape \(n, 3\)"),
        (np.array([["a", "b", "c"]]), TypeError, "real numbers"),
    ],
)
def test_bad_points_are_refused(points, error, match):
    with pytest.raises(error, match=match):
        meshbits.quantize(points, 8)


def test_dequantize_checks_its_input():
    np.testing.assert_array_equal(
        meshbits.dequantize(np.array([[1, 2, 3]], dtype=np.uint8), [1, 1, 1], 0.5), [[1.5, 2, 2.5]]
    )
    assert meshbits.dequantize(np.empty((0, 3), np.int32), [0, 0, 0], [1, 1, 1]).shape == (0, 3)
    with pytest.raises(TypeError, match="integers"):
        meshbits.dequantize(np.zeros((2, 3)), [0, 0, 0], 1.0)
    with pytest.raises(ValueError, match=r"shape \(n, 3\)"):
        meshbits.dequantize(np.zeros((2, 2), int), [0, 0, 0], 1.0)
    with pytest.raises(ValueError, match="origin must be a 3-vector"):
        meshbits.dequantize(np.zeros((2, 3), int), [0, 0], 1.0)
    with pytest.raises(meshbits.MeshbitsError, match="finite"):
        meshbits.dequantize(np.zeros((2, 3), int), [0, 0, 0], [1, np.inf, 1])
    with pytest.raises(meshbits.MeshbitsError, match="beyond the float64 range"):
        meshbits.dequantize(np.array([[2**62, 0, 0]]), [0, 0, 0], [1e300, 1, 1])


def test_quantize_accepts_a_trimesh_and_results_serialise():
    mesh = trimesh.creation.icosphere(subdivisions=2)
    result = meshbits.quantize(mesh, 7)
    assert result.codes.shape == mesh.vertices.shape
    report = json.loads(json.dumps(result.to_dict()))
    assert report["bits"] == 7 and len(report["step"]) == 3 and "codes" not in report
    assert len(result.to_dict(arrays=True)["codes"]) == len(mesh.vertices)


# --- cluster -----------------------------------------------------------------------------


@settings(max_examples=200, deadline=None)
@given(meshes(), st.integers(1, 12), grid_st, st.sampled_from(["keep", "oriented", "any"]))
def test_cluster_matches_the_numpy_reference_on_random_meshes(mesh, bits, grid, duplicates):
    vertices, faces = mesh
    assume(not refused_by_underflow(vertices, bits, grid))
    result = meshbits.cluster(vertices, faces, bits, grid=grid, duplicates=duplicates)
    assert_same_clustering(result, reference_cluster(vertices, faces, bits, grid, duplicates))
    assert result.input_vertices == (
        result.output_vertices + result.merged_vertices + result.unreferenced_vertices
    )
    assert result.input_faces == (
        result.output_faces + result.degenerate_faces + result.duplicate_faces
    )
    kept = result.vertex_map >= 0
    if kept.any():
        moved = np.linalg.norm(result.vertices[result.vertex_map[kept]] - vertices[kept], axis=1)
        assert result.max_displacement == pytest.approx(moved.max(), rel=1e-12, abs=1e-300)
        assert result.max_displacement <= result.bound * (1 + 1e-12) + slack(
            vertices, result.grid_size
        )


@pytest.fixture(scope="module")
def real_meshes():
    return {name: meshbits.load_mesh(DATA / f"{name}.ply") for name in ("bunny", "horse")}


@pytest.mark.parametrize("name", ["bunny", "horse"])
@pytest.mark.parametrize("bits", [6, 8, 10])
@pytest.mark.parametrize("duplicates", ["keep", "any"])
def test_cluster_matches_the_numpy_reference_on_real_meshes(real_meshes, name, bits, duplicates):
    vertices, faces = real_meshes[name]
    result = meshbits.cluster(vertices, faces, bits, duplicates=duplicates)
    expected = reference_cluster(vertices, faces, bits, "cube", duplicates)
    assert_same_clustering(result, expected)
    assert result.merged_vertices > 0  # the comparison is not vacuous
    assert result.degenerate_faces > 0 or bits == 10


def test_cluster_oriented_duplicates_on_a_real_mesh(real_meshes):
    vertices, faces = real_meshes["bunny"]
    result = meshbits.cluster(vertices, faces, 6, grid="axes", duplicates="oriented")
    assert_same_clustering(result, reference_cluster(vertices, faces, 6, "axes", "oriented"))
    assert result.duplicate_faces > 0


def test_cluster_does_not_depend_on_the_thread_count(real_meshes):
    vertices, faces = real_meshes["horse"]
    with meshbits.threads(1):
        one = meshbits.cluster(vertices, faces, 9, duplicates="any")
        q1 = meshbits.quantize(vertices, 9)
    many = meshbits.cluster(vertices, faces, 9, duplicates="any")
    qm = meshbits.quantize(vertices, 9)
    for name in ("vertices", "faces", "codes", "vertex_map", "face_index"):
        np.testing.assert_array_equal(getattr(one, name), getattr(many, name))
    assert one.to_dict() == many.to_dict()
    np.testing.assert_array_equal(q1.codes, qm.codes)
    assert q1.max_displacement == qm.max_displacement


def test_cluster_of_a_thin_sheet_drops_degenerate_and_duplicate_faces():
    # A closed box 1e-3 thick, both big sides split along the same diagonal: at 2 bits
    # (step 1/3) the top collapses onto the bottom.
    square = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    vertices = np.vstack([square, square + np.array([0, 0, 1e-3])])
    bottom, top = [[0, 2, 1], [0, 3, 2]], [[4, 5, 6], [4, 6, 7]]
    sides = []
    for a in range(4):
        b = (a + 1) % 4
        sides += [[a, b, b + 4], [a, b + 4, a + 4]]
    faces = np.array(bottom + top + sides)
    keep = meshbits.cluster(vertices, faces, 2)
    assert keep.degenerate_faces == 8  # the four thin sides
    assert keep.output_faces == 4 and keep.duplicate_faces == 0
    np.testing.assert_array_equal(keep.vertex_map, [0, 1, 2, 3, 0, 1, 2, 3])
    oriented = meshbits.cluster(vertices, faces, 2, duplicates="oriented")
    np.testing.assert_array_equal(oriented.faces, [[0, 2, 1], [0, 3, 2], [0, 1, 2], [0, 2, 3]])
    anyway = meshbits.cluster(vertices, faces, 2, duplicates="any")
    assert anyway.duplicate_faces == 2
    np.testing.assert_array_equal(anyway.faces, bottom)
    np.testing.assert_array_equal(anyway.face_index, [0, 1])
    np.testing.assert_array_equal(anyway.vertices, square)


def test_cluster_output_lies_on_the_grid_and_nothing_merges_at_high_bits():
    mesh = trimesh.creation.icosphere(subdivisions=3)
    result = meshbits.cluster(mesh.vertices, mesh.faces, 20)
    assert result.merged_vertices == result.degenerate_faces == 0
    np.testing.assert_array_equal(result.vertex_map, np.arange(len(mesh.vertices)))
    np.testing.assert_array_equal(result.faces, mesh.faces)
    np.testing.assert_array_equal(
        result.vertices, meshbits.dequantize(result.codes, result.origin, result.step)
    )
    centered = meshbits.cluster(mesh, 20, convention="centered")
    np.testing.assert_array_equal(centered.vertices, result.vertices)
    # origin + q * step with the shifted origin and codes rounds differently.
    np.testing.assert_allclose(
        centered.vertices,
        meshbits.dequantize(centered.codes, centered.origin, centered.step),
        rtol=0,
        atol=slack(mesh.vertices, result.grid_size),
    )


def test_cluster_of_identical_points_drops_everything():
    vertices = np.full((4, 3), 2.5)
    result = meshbits.cluster(vertices, [[0, 1, 2], [1, 2, 3]], 8)
    assert result.output_vertices == result.output_faces == 0
    assert (result.merged_vertices, result.unreferenced_vertices) == (3, 1)
    assert result.degenerate_faces == 2
    np.testing.assert_array_equal(result.vertex_map, -1)
    assert result.vertices.shape == (0, 3) and result.faces.shape == (0, 3)
    assert result.max_displacement == 0.0


def test_cluster_on_a_shared_box_welds_two_halves_without_cracks():
    mesh = trimesh.creation.icosphere(subdivisions=3)
    left = mesh.submesh([mesh.triangles_center[:, 0] < 0], append=True)
    right = mesh.submesh([mesh.triangles_center[:, 0] >= 0], append=True)
    box = (mesh.vertices.min(axis=0), mesh.vertices.max(axis=0))
    a = meshbits.cluster(left, 7, box=box)
    b = meshbits.cluster(right, 7, box=box)
    whole = meshbits.cluster(mesh, 7)
    seam = set(map(tuple, a.vertices)) & set(map(tuple, b.vertices))
    assert len(seam) > 10
    union = set(map(tuple, a.vertices)) | set(map(tuple, b.vertices))
    assert union == set(map(tuple, whole.vertices))


@pytest.mark.parametrize(
    ("args", "kwargs", "error", "match"),
    [
        ((np.zeros((3, 3)), [[0, 1, 3]], 8), {}, ValueError, "out of range"),
        ((np.zeros((3, 3)), [[0, 1, -1]], 8), {}, ValueError, "negative"),
        ((np.zeros((3, 3)), np.empty((0, 3), int), 8), {}, ValueError, "empty"),
        ((np.zeros((3, 3)), [[0.0, 1, 2]], 8), {}, TypeError, "integer"),
        ((np.zeros((3, 3)), [[0, 1]], 8), {}, ValueError, r"shape \(m, 3\)"),
        (
            (np.array([[0, 0, np.nan], [0, 0, 0], [1, 1, 1]]), [[0, 1, 2]], 8),
            {},
            ValueError,
            "not finite",
        ),
        ((np.zeros((3, 3)), [[0, 1, 2]]), {}, TypeError, "needs bits"),
        ((np.zeros((3, 3)), [[0, 1, 2]], 40), {}, ValueError, "bits must be"),
        ((np.zeros((3, 3)), [[0, 1, 2]], 8), {"duplicates": "some"}, ValueError, "duplicates"),
        (
            (np.eye(3), [[0, 1, 2]], 8),
            {"box": ([0, 0, 0], [1, 1, 0.5])},
            meshbits.MeshbitsError,
            "point 2 lies outside",
        ),
        (("not a mesh",), {"bits": 8}, TypeError, "expected a trimesh"),
    ],
)
def test_cluster_refuses_bad_input(args, kwargs, error, match):
    with pytest.raises(error, match=match):
        meshbits.cluster(*args, **kwargs)


def test_native_functions_refuse_bad_input_without_panicking():
    # Straight to the kernels, past the Python checks.
    from meshbits import _core

    good = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    nan = good.copy()
    nan[1, 2] = np.nan
    faces = np.array([[0, 1, 2]], dtype=np.uint32)
    with pytest.raises(meshbits.MeshbitsError, match="vertex 1 has a NaN"):
        _core.cluster(nan, faces, 8, "cube", None, None, False, "keep")
    with pytest.raises(meshbits.MeshbitsError, match="vertex 1 has a NaN"):
        _core.quantize(nan, 8, "axes", None, None, False)
    with pytest.raises(meshbits.MeshbitsError, match="face 0 refers to vertex 7"):
        _core.cluster(
            good, np.array([[0, 1, 7]], dtype=np.uint32), 8, "cube", None, None, False, "keep"
        )
    with pytest.raises(meshbits.MeshbitsError, match="bits must be an integer from 1 to 32"):
        _core.quantize(good, 0, "cube", None, None, False)
    with pytest.raises(meshbits.MeshbitsError, match="both box corners"):
        _core.quantize(good, 8, "cube", (0, 0, 0), None, False)
    with pytest.raises(ValueError, match="grid must be"):
        _core.quantize(good, 8, "sphere", None, None, False)
    result = _core.cluster(good, faces, 8, "cube", None, None, False, "keep")
    assert result["faces"].dtype == np.uint32 and result["vertex_map"].dtype == np.int64


# --- command line ------------------------------------------------------------------------


def test_cli_quantize_writes_the_clustered_mesh(tmp_path, capsys):
    out = tmp_path / "bunny8.ply"
    assert main(["quantize", str(DATA / "bunny.ply"), "--bits", "8", "-o", str(out), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    vertices, faces = meshbits.load_mesh(DATA / "bunny.ply")
    result = meshbits.cluster(vertices, faces, 8)
    assert report["output_faces"] == result.output_faces
    assert report["output_vertices"] == result.output_vertices
    assert report["degenerate_faces"] == result.degenerate_faces
    assert report["bound"] == result.bound and report["max_displacement"] <= report["bound"]
    written_v, written_f = meshbits.load_mesh(out)
    np.testing.assert_array_equal(written_f, result.faces)
    np.testing.assert_allclose(written_v, result.vertices, rtol=1e-6)


def test_cli_quantize_text_report_and_bad_bits(capsys):
    mesh = str(DATA / "suzanne.ply")
    assert main(["quantize", mesh, "--bits", "5", "--grid", "axes", "--duplicates", "any"]) == 0
    text = capsys.readouterr().out
    assert "5-bit axes grid" in text and "max displacement" in text
    assert main(["quantize", mesh, "--bits", "0"]) == 2
    assert "--bits: must be at least 1, got '0'" in capsys.readouterr().err
    assert main(["quantize", mesh, "--bits", "33"]) == 2
    assert "--bits: must be at most 32, got '33'" in capsys.readouterr().err


def test_cli_quantize_refuses_to_write_an_empty_mesh(tmp_path, capsys):
    path = tmp_path / "flat.ply"
    meshbits.save_mesh(path, np.array([[0.0, 0, 0], [1, 0, 0], [0, 1e-3, 0]]), [[0, 1, 2]])
    out = tmp_path / "out.ply"
    assert main(["quantize", str(path), "--bits", "1", "-o", str(out)]) == 2
    assert "no face survives clustering at 1 bits" in capsys.readouterr().err
    assert not out.exists()


# --- the cube grid over a box: points on the far faces stay inside ---------------------

_coordinate = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False)
_extent = st.one_of(st.just(0.0), st.floats(1e-9, 1e4, allow_nan=False, allow_infinity=False))
#: The box of a simplified bunny that broke the GLB and PLY writers: lo + (hi - lo) rounds
#: to an ulp below hi on the x axis.
_BUNNY_LEVEL_BOX = (
    [-0.09472355680328087, 0.03298740088939667, -0.061873599886894226],
    [0.06105089225045258, 0.18733351625319664, 0.058847996081781144],
)


@settings(max_examples=300, deadline=None)
@given(
    lo=hnp.arrays(np.float64, 3, elements=_coordinate),
    extent=hnp.arrays(np.float64, 3, elements=_extent),
    bits=st.integers(1, 32),
    fractions=hnp.arrays(np.float64, (6, 3), elements=st.floats(0, 1)),
)
@example(
    lo=np.array(_BUNNY_LEVEL_BOX[0]),
    extent=np.array(_BUNNY_LEVEL_BOX[1]) - np.array(_BUNNY_LEVEL_BOX[0]),
    bits=12,
    fractions=np.full((6, 3), 0.5),
)
def test_cube_grid_holds_every_point_of_the_box(lo, extent, bits, fractions):
    """Points on the faces, edges and far corner of [lo, hi] quantize on the grid built by
    cube_grid (compress and the GLB/PLY writers build theirs with it)."""
    hi = np.maximum(lo + extent, lo)
    corners = np.array([lo, hi])
    inside = np.clip(lo + fractions * (hi - lo), lo, hi)
    on_faces = np.concatenate(
        [
            np.where(np.arange(3) == axis, corners[end], inside)
            for axis in range(3)
            for end in (0, 1)
        ]
    )
    points = np.concatenate([corners, on_faces])
    origin, side = meshbits.cube_grid(lo, hi)
    assert side >= (hi - lo).max()
    assert side <= np.nextafter((hi - lo).max(), np.inf) * (1 + 4 * EPS)
    q = meshbits.quantize(points, bits, box=(origin, origin + side))
    assert int(np.asarray(q.codes).max()) <= 2**bits - 1


def test_the_bunny_level_box_needs_the_rounded_up_side():
    lo, hi = map(np.array, _BUNNY_LEVEL_BOX)
    assert (lo + (hi - lo).max() < hi).any()  # the rounding that broke the writers
    origin, side = meshbits.cube_grid(lo, hi)
    assert (origin + side >= hi).all() and side > (hi - lo).max()


@pytest.mark.parametrize("fmt", ["glb", "ply", "draco"])
def test_writers_take_the_extreme_vertex_of_a_simplified_mesh(bunny, fmt):
    """compress -o x.glb / x.ply on the bunny at 0.002 S used to stop with 'point N lies
    outside the quantization box'."""
    result = meshbits.compress(bunny, error=0.002, relative=True, format=fmt, max_iterations=2)
    assert result.size_bits > 0


# --- refusals found by the fuzz campaign (benches/fuzz.py) --------------------------------


def test_cube_grid_refuses_corners_that_are_not_3_vectors():
    """Both raised numpy's ValueError ('cannot reshape', 'could not convert')."""
    with pytest.raises(meshbits.MeshbitsError, match="lo must be a 3-vector"):
        meshbits.cube_grid((0, 0), (1, 1, 1))
    with pytest.raises(TypeError, match="hi must be a 3-vector"):
        meshbits.cube_grid((0, 0, 0), "hi")
    with pytest.raises(meshbits.MeshbitsError, match="overflows"):
        meshbits.cube_grid((-1e308,) * 3, (1e308,) * 3)


def test_precision_bits_of_coordinates_beyond_float32_warns_nothing():
    """The float32 round trip warned 'overflow encountered in cast' (an error here)."""
    vertices = np.array([[0.0, 0, 0], [1e308, 0, 0], [0, 1, 0]])
    assert meshbits.precision_bits(vertices) == 53
    assert meshbits.precision_bits(vertices * 1e-300, grid_size=1e300) > 1000
    with pytest.raises(meshbits.MeshbitsError, match="grid_size must be finite"):
        meshbits.precision_bits(vertices, grid_size=math.inf)  # was OverflowError
    with pytest.raises(TypeError, match="grid_size"):
        meshbits.precision_bits(vertices, grid_size="1")
