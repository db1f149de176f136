"""The Sec. 7 loop end to end: budgets met, passes, and where the time goes.

For each mesh and budget, prints the chosen B and V, the measured error and size, the
number of passes and the seconds spent per phase (K, simplification, Draco encoding with
decoding, Hausdorff), then the sizes of one quantized mesh in the three writers (Draco,
glTF with KHR_mesh_quantization, quantized PLY) next to the paper's F. Meshes: the
bundled Spot, tests/data, and ../shared/meshes (the 871k-face Stanford dragon;
docs/benchmarks.md lists the meshes) when present.

    python benches/bench_compress.py
"""

from __future__ import annotations

import gzip
import time
from pathlib import Path

import numpy as np
import trimesh
from _shared import SHARED as SHARED_ROOT

import meshbits
from meshbits.codecs import encode

ROOT = Path(__file__).resolve().parents[1]
SHARED = SHARED_ROOT / "meshes"


def load(name: str) -> tuple[np.ndarray, np.ndarray] | None:
    for folder in (ROOT / "tests" / "data", SHARED):
        path = folder / name
        if path.exists():
            source = gzip.open(path) if name.endswith(".gz") else path
            mesh = trimesh.load(source, file_type="ply", process=False, force="mesh")
            return np.asarray(mesh.vertices), np.asarray(mesh.faces)
    return None


CASES = [
    ("spot", {"error": 0.002, "relative": True}),
    ("spot", {"size": 8 * 10_000}),
    ("bunny.ply", {"error": 0.002, "relative": True}),
    ("bunny.ply", {"size": 8 * 40_000}),
    ("horse.ply", {"error": 0.002, "relative": True}),
    ("dragon.ply.gz", {"error": 0.001, "relative": True}),
    ("dragon.ply.gz", {"size": 8 * 200_000}),
]


def formats() -> None:
    """The same quantized mesh in the three writers, next to the paper's F."""
    print(
        "\n| mesh | V | B | model F, alpha = 1, T = 4 (bytes) | Draco (bytes) | GLB (bytes) "
        "| PLY (bytes) |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|")
    for name in ("spot", "bunny.ply"):
        mesh = meshbits.load_mesh(meshbits.example_mesh_path()) if name == "spot" else load(name)
        if mesh is None:
            continue
        used = len(np.unique(mesh[1]))
        for bits in (8, 11, 14):
            sizes = [encode(mesh, bits, format=f).size_bytes for f in ("draco", "glb", "ply")]
            model_bytes = meshbits.model.file_size(bits, used, alpha=1.0, connectivity_bits=4.0) / 8
            print(
                f"| {name.split('.')[0]} | {used:,} | {bits} | {model_bytes:,.0f} | "
                + " | ".join(f"{size:,}" for size in sizes)
                + " |"
            )


def main() -> None:
    print(
        "| mesh | faces | budget | met | B | V | error / S | bytes | passes | K (s) | simplify (s) "
        "| encode (s) | Hausdorff (s) | total (s) |"
    )
    print("|---|---:|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for name, budget in CASES:
        mesh = meshbits.load_mesh(meshbits.example_mesh_path()) if name == "spot" else load(name)
        if mesh is None:
            continue
        start = time.perf_counter()
        result = meshbits.compress(mesh, **budget)
        total = time.perf_counter() - start
        label = (
            f"E <= {budget['error']} S" if "error" in budget else f"F <= {budget['size'] // 8:,} B"
        )
        t = result.seconds
        print(
            f"| {name.split('.')[0]} | {len(mesh[1]):,} | {label} | {result.met} | {result.bits} "
            f"| {len(result.vertices):,} | {result.error / result.complexity.grid_size:.2e} "
            f"| {result.size_bytes:,} | {len(result.iterations)} | {t['complexity']:.2f} "
            f"| {t['simplify']:.2f} | {t['encode']:.2f} | {t['hausdorff']:.2f} | {total:.2f} |",
            flush=True,
        )
    formats()


if __name__ == "__main__":
    main()
