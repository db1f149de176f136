"""One simplification of a whole mesh, meshbits against its peers, at the same target.

compress's search on a large mesh is bounded by its simplifications: each level is the
whole original simplified once (see docs/compress.md). This prints what one such call
costs in meshbits (:func:`meshbits.simplify`, meshoptimizer's simplifier through the
`meshopt` crate) beside the same simplifier built independently (the `meshoptimizer`
Python package) and the other simplifiers of the field at the same face count
(fast-simplification, Open3D's quadric decimation, PyMeshLab's quadric edge collapse),
best of ``--repeat`` calls, with the faces each kept. meshoptimizer takes an error target
(length, mesh units): meshbits's error-driven call sets the face count the others are
asked for. Meshes: tests/data/bunny.ply and, when present, the 871k-face Stanford dragon
of ../shared/meshes (docs/benchmarks.md lists the meshes).

    python benches/bench_simplify.py [--repeat 3]
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from _shared import SHARED as SHARED_ROOT

import meshbits

ROOT = Path(__file__).resolve().parents[1]
SHARED = SHARED_ROOT / "meshes"

#: (mesh, meshoptimizer error targets relative to the bounding-box diagonal S); the
#: dragon's are about those compress's search asks for at 0.001 S.
CASES = [
    (ROOT / "tests" / "data" / "bunny.ply", (2e-4, 1e-3)),
    (SHARED / "dragon.ply.gz", (0.0, 1e-4, 3e-4)),
]


def best(repeat: int, run: Callable[[], int]) -> tuple[float, int]:
    """Best time (s) of ``repeat`` calls, and the faces the last call kept."""
    times, kept = [], 0
    for _ in range(repeat):
        start = time.perf_counter()
        kept = run()
        times.append(time.perf_counter() - start)
    return min(times), kept


def peers(vertices: np.ndarray, faces: np.ndarray, error: float) -> dict[str, Callable[[], int]]:
    """Each simplifier, asked for what meshbits's call at ``error`` kept."""
    target = len(meshbits.simplify((vertices, faces), error=error).faces)
    runs: dict[str, Callable[[], int]] = {
        "meshbits.simplify (error target)": lambda: len(
            meshbits.simplify((vertices, faces), error=error).faces
        ),
    }
    try:
        import meshoptimizer

        # The same algorithm and options as meshbits's call: absolute error, float32
        # positions about the box centre (meshbits also welds identical vertices first).
        centre = (vertices.max(axis=0) + vertices.min(axis=0)) / 2
        positions = np.ascontiguousarray(vertices - centre, dtype=np.float32)
        indices = np.ascontiguousarray(faces, dtype=np.uint32).ravel()

        def meshoptimizer_run() -> int:
            out = np.empty_like(indices)
            count = meshoptimizer.simplify(
                out,
                indices,
                positions,
                target_index_count=0,
                target_error=error,
                options=meshoptimizer.SIMPLIFY_ERROR_ABSOLUTE,
            )
            return count // 3

        runs["meshoptimizer (Python package, error target)"] = meshoptimizer_run
    except ImportError:
        print("(meshoptimizer not installed: pip install meshoptimizer)")
    try:
        import fast_simplification

        def fast_run() -> int:
            _, f = fast_simplification.simplify(
                vertices.astype(np.float32),
                faces.astype(np.int32),
                target_count=target,
            )
            return len(f)

        runs["fast-simplification (face target)"] = fast_run
    except ImportError:
        print("(fast-simplification not installed)")
    try:
        import open3d as o3d

        mesh = o3d.geometry.TriangleMesh(
            o3d.utility.Vector3dVector(vertices), o3d.utility.Vector3iVector(faces)
        )
        runs["Open3D simplify_quadric_decimation (face target)"] = lambda: len(
            mesh.simplify_quadric_decimation(target).triangles
        )
    except ImportError:
        print("(open3d not installed)")
    try:
        import pymeshlab

        def meshlab_run() -> int:
            ms = pymeshlab.MeshSet()
            ms.add_mesh(pymeshlab.Mesh(vertices, faces))
            ms.meshing_decimation_quadric_edge_collapse(targetfacenum=target)
            return ms.current_mesh().face_number()

        runs["PyMeshLab quadric edge collapse (face target)"] = meshlab_run
    except ImportError:
        print("(pymeshlab not installed)")
    return runs


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    if meshbits._core.BUILD_PROFILE != "release":
        raise SystemExit("benchmark a release build: maturin develop --release")
    print(f"meshbits {meshbits.__version__}, load average {os.getloadavg()[0]:.1f} at the start")
    print("\n| mesh | faces | error target (S) | simplifier | faces kept | s (best) |")
    print("|---|---:|---:|---|---:|---:|")
    for path, targets in CASES:
        if not path.exists():
            continue
        vertices, faces = meshbits.load_mesh(path)
        size = float(np.linalg.norm(vertices.max(axis=0) - vertices.min(axis=0)))
        for relative in targets:
            for name, run in peers(vertices, faces, relative * size).items():
                seconds, kept = best(args.repeat, run)
                print(
                    f"| {path.name} | {len(faces):,} | {relative:g} | {name} | {kept:,} "
                    f"| {seconds:.2f} |",
                    flush=True,
                )
    print(f"\nload average at the end: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
