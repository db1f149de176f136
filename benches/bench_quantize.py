"""Vertex clustering on a B-bit grid: meshbits vs vectorised numpy vs trimesh's merge route.

Every row times the whole job on the same mesh in the same run (best of several runs):
quantize to the cube grid, merge vertices sharing a code, drop degenerate faces, drop
unreferenced vertices, return the new mesh and the old->new vertex map.

* ``meshbits``: :func:`meshbits.cluster` (all cores, and one thread).
* ``numpy``: codes packed in one int64, ``np.unique(return_inverse=True)``, remap, filter.
  Its vertices come out sorted by code (cheaper than meshbits' first-occurrence order);
  the script checks that it builds the same mesh up to that vertex permutation.
* ``trimesh``: snap the vertices to the grid, then ``merge_vertices``,
  ``update_faces(nondegenerate_faces())`` and ``remove_unreferenced_vertices``. Its
  degeneracy test is geometric, so its face count may differ (shown in the table).

Meshes: icospheres of about 20k to 5M faces, ``tests/data`` and, when present,
``../shared/meshes`` next to the repository (listed in docs/benchmarks.md).
Run: ``python benches/bench_quantize.py``
(``--quick`` skips the 5M-face sphere and the trimesh route on it).
"""

from __future__ import annotations

import os

# Nothing timed here calls BLAS, but OpenBLAS worker threads left spinning by earlier
# calls steal CPU from whatever runs next on a small machine.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import trimesh
from _shared import SHARED as SHARED_ROOT

import meshbits

ROOT = Path(__file__).resolve().parent.parent
SHARED = SHARED_ROOT / "meshes"


def best_time(run: Callable[..., Any], args: tuple, repeats: int) -> tuple[float, float, Any]:
    """Fastest of ``repeats`` calls ``run(*args)``: wall time and process CPU time, in
    seconds, and the last result."""
    wall, cpu, out = float("inf"), float("inf"), None
    for _ in range(repeats):
        start, start_cpu = time.perf_counter(), time.process_time()
        out = run(*args)
        wall = min(wall, time.perf_counter() - start)
        cpu = min(cpu, time.process_time() - start_cpu)
    return wall, cpu, out


def grid(vertices: np.ndarray, bits: int) -> tuple[np.ndarray, float]:
    lo = vertices.min(axis=0)
    return lo, float((vertices.max(axis=0) - lo).max()) / (2**bits - 1)


def numpy_cluster(vertices: np.ndarray, faces: np.ndarray, bits: int) -> dict[str, np.ndarray]:
    lo, step = grid(vertices, bits)
    q = np.floor((vertices - lo) / step + 0.5).astype(np.int64)
    key = (q[:, 0] << (2 * bits)) | (q[:, 1] << bits) | q[:, 2]
    unique, inverse = np.unique(key, return_inverse=True)
    cf = inverse[faces]
    keep = (cf[:, 0] != cf[:, 1]) & (cf[:, 1] != cf[:, 2]) & (cf[:, 2] != cf[:, 0])
    cf = cf[keep]
    used = np.zeros(len(unique), dtype=bool)
    used[cf.ravel()] = True
    new_id = np.cumsum(used) - 1
    kept = unique[used]
    mask = (1 << bits) - 1
    codes = np.column_stack([kept >> (2 * bits), (kept >> bits) & mask, kept & mask])
    return {
        "vertices": lo + codes * step,
        "faces": new_id[cf],
        "vertex_map": np.where(used[inverse], new_id[inverse], -1),
    }


def trimesh_cluster(vertices: np.ndarray, faces: np.ndarray, bits: int) -> trimesh.Trimesh:
    lo, step = grid(vertices, bits)
    snapped = lo + np.floor((vertices - lo) / step + 0.5) * step
    mesh = trimesh.Trimesh(snapped, faces, process=False)
    mesh.merge_vertices()
    mesh.update_faces(mesh.nondegenerate_faces())
    mesh.remove_unreferenced_vertices()
    return mesh


def same_mesh(result: meshbits.Clustered, reference: dict[str, np.ndarray]) -> bool:
    """True when numpy's code-ordered mesh is meshbits' mesh with vertices permuted."""
    if len(result.vertices) != len(reference["vertices"]):
        return False
    if len(result.faces) != len(reference["faces"]):
        return False
    codes = result.codes.astype(np.int64)
    order = np.lexsort((codes[:, 2], codes[:, 1], codes[:, 0]))
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    return (
        np.array_equal(rank[result.faces], reference["faces"])
        and np.allclose(result.vertices[order], reference["vertices"], rtol=0, atol=1e-12)
        and np.array_equal(
            np.where(result.vertex_map >= 0, rank[result.vertex_map], -1),
            reference["vertex_map"],
        )
    )


def meshes(quick: bool) -> list[tuple[str, np.ndarray, np.ndarray]]:
    out = []
    for level in (5, 6, 7, 8) if quick else (5, 6, 7, 8, 9):
        sphere = trimesh.creation.icosphere(subdivisions=level)
        out.append((f"icosphere({level})", np.asarray(sphere.vertices), np.asarray(sphere.faces)))
    paths = [ROOT / "tests" / "data" / f"{name}.ply" for name in ("bunny", "horse")]
    paths += [SHARED / name for name in ("armadillo.ply", "nefertiti.ply", "dragon.ply.gz")]
    for path in paths:
        if path.is_file():
            vertices, faces = meshbits.load_mesh(path)
            out.append((path.name.split(".")[0], vertices, faces))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="skip the 5M-face icosphere")
    parser.add_argument("--bits", type=int, nargs="+", default=[8, 12])
    args = parser.parse_args()
    if meshbits._core.BUILD_PROFILE != "release":
        raise SystemExit("benchmark a release build: maturin develop --release")

    header = (
        f"{'mesh':<15}{'V':>9}{'F':>9}{'B':>4}{'F out':>9}{'meshbits':>10}{'1 thread':>10}"
        f"{'numpy':>9}{'trimesh':>9}{'numpy/mb':>10}{'cpu ratio':>10}{'trim/mb':>9}"
        f"{'trim F':>9}  same"
    )
    print(
        "wall times in ms, best of several runs; numpy/mb and trim/mb: wall-time ratios to\n"
        "meshbits on all cores; cpu ratio: process CPU time of numpy / meshbits on 1 thread"
    )
    print(header)
    print("-" * len(header))
    for name, vertices, faces in meshes(args.quick):
        repeats = 9 if len(faces) < 500_000 else 7
        for bits in args.bits:
            job = (vertices, faces, bits)
            t_mb, _, result = best_time(meshbits.cluster, job, repeats)
            with meshbits.threads(1):
                t_one, c_one, _ = best_time(meshbits.cluster, job, repeats)
            t_np, c_np, reference = best_time(numpy_cluster, job, repeats)
            t_tm, _, tm = best_time(trimesh_cluster, job, 1 if len(faces) > 2e6 else 2)
            print(
                f"{name:<15}{len(vertices):>9}{len(faces):>9}{bits:>4}{result.output_faces:>9}"
                f"{t_mb * 1e3:>10.1f}{t_one * 1e3:>10.1f}{t_np * 1e3:>9.1f}{t_tm * 1e3:>9.1f}"
                f"{t_np / t_mb:>10.1f}{c_np / c_one:>10.1f}{t_tm / t_mb:>9.1f}{len(tm.faces):>9}"
                f"  {'yes' if same_mesh(result, reference) else 'NO'}",
                flush=True,
            )


if __name__ == "__main__":
    main()
