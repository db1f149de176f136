"""Shape complexity K: meshbits vs a vectorised numpy reference vs a trimesh-adjacency route.

Prints one table; every ratio comes from this one run (best of ``--repeat`` timings).
Meshes: icospheres from 20k to 5M faces, two 5M spheres side by side (10M faces), and
the real meshes in tests/data and ../shared/meshes when present (listed in
docs/benchmarks.md).

    python benches/bench_shape_complexity.py [--max-faces 11000000] [--repeat 3]
"""

from __future__ import annotations

import argparse
import gzip
import os
import sys
import time
from pathlib import Path

import numpy as np
import trimesh
from _shared import SHARED as SHARED_ROOT

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
import reference  # noqa: E402

import meshbits  # noqa: E402

SHARED = SHARED_ROOT / "meshes"


def best_time(fn, repeat: int, *args) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn(*args)
        times.append(time.perf_counter() - start)
    return min(times)


def trimesh_route(vertices: np.ndarray, faces: np.ndarray) -> float:
    """K_raw through trimesh's face adjacency (edge pairs, unshared vertices)."""
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    edges = mesh.face_adjacency_edges
    unshared = mesh.face_adjacency_unshared
    a, b = vertices[edges[:, 0]], vertices[edges[:, 1]]
    c, d = vertices[unshared[:, 0]], vertices[unshared[:, 1]]
    radius = reference.circumsphere_radius(b - a, c - a, d - a)
    area = mesh.area_faces[mesh.face_adjacency].sum(axis=1) / 3.0
    return float((area / radius).sum())


def meshes(max_faces: int):
    for subdivisions in range(5, 10):
        if 20 * 4**subdivisions > max_faces:
            break
        sphere = trimesh.creation.icosphere(subdivisions=subdivisions)
        yield f"icosphere s={subdivisions}", np.asarray(sphere.vertices), np.asarray(sphere.faces)
        if subdivisions == 9 and 2 * len(sphere.faces) <= max_faces:
            v, f = np.asarray(sphere.vertices), np.asarray(sphere.faces)
            yield "2 x icosphere s=9", np.vstack([v, v + 3.0]), np.vstack([f, f + len(v)])
    names = sorted({p.name for p in (ROOT / "tests" / "data").glob("*.ply")})
    for name in ["bunny.ply", "horse.ply", "armadillo.ply", "dragon.ply.gz"]:
        path = SHARED / name
        if not path.exists():
            path = ROOT / "tests" / "data" / name
        if not path.exists() or (name not in names and not SHARED.exists()):
            continue
        source = gzip.open(path) if name.endswith(".gz") else path
        mesh = trimesh.load(source, file_type="ply", process=False, force="mesh")
        yield name, np.asarray(mesh.vertices), np.asarray(mesh.faces)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--max-faces", type=int, default=11_000_000)
    parser.add_argument("--max-reference-faces", type=int, default=6_000_000)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    print(
        f"meshbits {meshbits.__version__} ({meshbits._core.BUILD_PROFILE}), "
        f"{os.cpu_count()} cores, numpy {np.__version__}, trimesh {trimesh.__version__}"
    )
    header = (
        "| mesh | faces | edges | meshbits (s) | numpy (s) | trimesh (s) | numpy / meshbits "
        "| trimesh / meshbits | meshbits ns/face |"
    )
    print(header)
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for name, vertices, faces in meshes(args.max_faces):
        result = meshbits.shape_complexity(vertices, faces)
        ours = best_time(meshbits.shape_complexity, args.repeat, vertices, faces)
        if len(faces) <= args.max_reference_faces:
            want = reference.shape_complexity(vertices, faces)
            assert abs(want["k_raw"] - result.k_raw) <= 1e-9 * abs(result.k_raw), name
            numpy_time = best_time(reference.shape_complexity, 1, vertices, faces)
            trimesh_time = best_time(trimesh_route, 1, vertices, faces)
            ratios = f"{numpy_time / ours:.1f}x | {trimesh_time / ours:.1f}x"
            times = f"{numpy_time:.3f} | {trimesh_time:.3f}"
        else:
            times, ratios = "- | -", "- | -"
        print(
            f"| {name} | {len(faces):,} | {result.edges:,} | {ours:.4f} | {times} | {ratios} "
            f"| {1e9 * ours / len(faces):.0f} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
