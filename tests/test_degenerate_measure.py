"""Measurements against collapsed meshes (issue #31, item 3: no measurement takes
unbounded time): a mesh collapsed to one point, and one collapsed onto a line.

A mesh whose vertices all sit at one point (the bunny scaled by 1e-6 and decoded by Draco)
has every triangle at exactly the same distance from any query: the nearest-triangle
search used to test every triangle for each query, and the tree build was quadratic too
(69k faces: minutes). Here the answers are checked against the analytic ones; the speed
itself is covered by the Rust tests, which count the triangles each query tests.

A mesh collapsed onto a line (every vertex on one diagonal) has only zero-area faces,
segments overlapping about 450 deep along the line, each inside a box far looser than
itself: a query tested about 5,600 triangles, and hausdorff() with bounds took minutes.
The faces are now searched as one segment (docs/hausdorff.md, *Collinear runs*); the
answers are checked against brute-force numpy distances.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import trimesh
from independent import distances_to_mesh

import meshbits

DATA = Path(__file__).parent / "data"


def bunny() -> tuple[np.ndarray, np.ndarray]:
    mesh = trimesh.load(DATA / "bunny.ply", process=False, force="mesh")
    return np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int64)


def test_closest_points_on_a_collapsed_mesh_are_the_point_and_the_first_face():
    v, f = bunny()
    at = v[123]
    closest = meshbits.ClosestPoints((np.tile(at, (len(v), 1)), f)).query(v)
    np.testing.assert_array_equal(closest.faces, 0)
    np.testing.assert_array_equal(closest.points, np.tile(at, (len(v), 1)))
    np.testing.assert_allclose(closest.distances, np.linalg.norm(v - at, axis=1), rtol=1e-15)


def test_hausdorff_to_a_collapsed_mesh_is_the_farthest_vertex():
    # h(bunny, point) is the largest |p - point| over the surface, a convex function of p:
    # reached at a vertex, and every referenced vertex is sampled. h(point, bunny) is
    # smaller.
    v, f = bunny()
    collapsed = (np.zeros_like(v), f)
    farthest = np.linalg.norm(v[np.unique(f)], axis=1).max()
    r = meshbits.hausdorff((v, f), collapsed, samples=20_000, relative_tolerance=0.01)
    assert r.distance == r.a_to_b.max
    np.testing.assert_allclose(r.a_to_b.max, farthest, rtol=1e-15)
    np.testing.assert_array_equal(r.a_to_b.argmax_closest, [0.0, 0.0, 0.0])
    assert r.a_to_b.argmax_face == 0
    assert r.a_to_b.converged and r.b_to_a.converged
    assert r.a_to_b.max <= r.a_to_b.upper <= r.a_to_b.max * 1.01
    assert r.b_to_a.max < r.a_to_b.max
    reference = meshbits.Reference(collapsed, samples=20_000)
    again = reference.hausdorff((v, f), bounds=True)
    np.testing.assert_allclose(again.distance, farthest, rtol=1e-15)


def test_a_collapsed_source_is_not_refined_below_the_rounding_floor():
    # Every cell of a collapsed source is one point: a tolerance under the rounding
    # margin cannot be met, and the refinement stops at once instead of spending its
    # budget on copies of the point.
    v, f = bunny()
    r = meshbits.hausdorff(
        (np.zeros_like(v), f), (v, f), samples=10_000, tolerance=1e-18, refine_budget=10**6
    )
    assert r.a_to_b.refined_points == 0
    assert r.a_to_b.converged is False
    assert r.a_to_b.max <= r.a_to_b.upper


def test_collapsed_measurements_do_not_depend_on_threads():
    v, f = bunny()
    collapsed = (np.tile(v[7], (len(v), 1)), f)
    out = []
    for count in (1, 2):
        with meshbits.threads(count):
            r = meshbits.hausdorff((v, f), collapsed, samples=20_000, tolerance=1e-6)
            q = meshbits.ClosestPoints(collapsed).query(v[::7])
        out.append((json.dumps(r.to_dict()), q.distances.tobytes(), q.faces.tobytes()))
    assert out[0] == out[1]


def on_a_line(v: np.ndarray) -> np.ndarray:
    """Every vertex moved onto the diagonal: ``x * (1, 1, 1)``."""
    return np.outer(v[:, 0], [1.0, 1.0, 1.0])


def segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distances from the points ``p`` to the segments ``[a, b]`` (rows, broadcast)."""
    ab, ap = b - a, p - a
    length2 = np.einsum("...j,...j->...", ab, ab)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.clip(np.einsum("...j,...j->...", ap, ab) / length2, 0.0, 1.0)
    t = np.where(length2 > 0, t, 0.0)
    return np.linalg.norm(ap - ab * t[..., None], axis=-1)


def test_hausdorff_to_a_mesh_collapsed_onto_a_line_is_certified():
    # The line mesh is the union of its faces' segments, the diagonal segment from the
    # smallest to the largest x: its distance is convex, so h(bunny, line) is reached at
    # a vertex, computed here by brute force. h(line, bunny) is bounded from below by
    # dense points of the line measured in numpy.
    v, f = bunny()
    line = on_a_line(v)
    used = np.unique(f)
    ends = line[used][[np.argmin(v[used, 0]), np.argmax(v[used, 0])]]
    to_union = segment_distance(v[used], ends[0], ends[1])
    # The union is the line mesh: brute force over every face's segments agrees.
    some = v[used[:: len(used) // 60]]
    corners = line[f]
    to_faces = np.min(
        [
            segment_distance(some[:, None], corners[None, :, i], corners[None, :, j]).min(axis=1)
            for i, j in ((0, 1), (1, 2), (2, 0))
        ],
        axis=0,
    )
    np.testing.assert_allclose(to_faces, segment_distance(some, ends[0], ends[1]), rtol=1e-12)
    truth = to_union.max()

    r = meshbits.hausdorff((v, f), (line, f), relative_tolerance=0.01)
    ab, ba = r.a_to_b, r.b_to_a
    assert ab.converged and ba.converged
    np.testing.assert_allclose(ab.max, truth, rtol=1e-12)
    assert truth <= ab.upper <= truth * 1.01 + 1e-12
    dense = ends[0] + np.linspace(0.0, 1.0, 2001)[:, None] * (ends[1] - ends[0])
    below = distances_to_mesh(dense, v, f).max()
    assert below <= ba.upper and ba.max <= ba.upper <= ba.max * 1.01 + 1e-12
    # compress's certification: the reference is the bunny, the candidate the line,
    # decided against a threshold.
    h = meshbits.Reference((v, f)).hausdorff(
        (line, f), bounds=True, tolerance=1e-4, threshold=truth * 1.001
    )
    assert truth <= h.a_to_b.upper <= truth * 1.001 and below <= h.b_to_a.upper


def test_measurements_on_a_line_do_not_depend_on_threads():
    v, f = bunny()
    line = on_a_line(v)
    out = []
    for count in (1, 2):
        with meshbits.threads(count):
            r = meshbits.hausdorff((v, f), (line, f), samples=20_000, tolerance=1e-6)
            q = meshbits.ClosestPoints((line, f)).query(v[::7])
        out.append((json.dumps(r.to_dict()), q.distances.tobytes(), q.faces.tobytes()))
    assert out[0] == out[1]
