"""A behaviour fingerprint: compress's answers (mesh, budget, met, B, V, bytes and the
SHA-256 of the bytes) on the meshes and budgets of ``benches/frontier.py``, and
compress_scene's on the test scene and the example mesh with both codecs. Two commits
whose digests are equal behave the same there; a refactoring is checked by running it
before and after and comparing the files.

    python benches/digest.py > before.txt   (and after.txt; then diff them)

Meshes come from ``shared/meshes`` (benches/_shared.py); ``--quick`` takes the test
meshes of tests/data only.
"""

from __future__ import annotations

import argparse
import hashlib
import sys
import tempfile
from pathlib import Path

from _shared import ROOT, SHARED

import meshbits
from meshbits.scene import compress_scene

ERROR_BUDGETS = [0.005, 0.002, 0.001, 0.0005]
SIZE_BUDGETS_KB = [4, 16, 64]
MESHES = ["bunny", "horse", "hand", "fandisk", "armadillo", "nefertiti"]
QUICK = ["bunny_res3", "hand", "fandisk"]


def _sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()[:16]


def single(path: Path) -> None:
    mesh = meshbits.load_mesh(path)
    for kind, budgets in (("error", ERROR_BUDGETS), ("size", SIZE_BUDGETS_KB)):
        for budget in budgets:
            if kind == "error":
                result = meshbits.compress(mesh, error=budget, relative=True)
            else:
                result = meshbits.compress(mesh, size=8 * 1000 * budget)
            print(
                f"{path.stem} {kind} {budget} met={result.met} B={result.bits} "
                f"V={len(result.vertices)} bytes={result.size_bytes} sha={_sha(result.data)} "
                f"error={result.error:.9g} upper={result.error_upper}"
            )


def scenes(paths: list[Path]) -> None:
    with tempfile.TemporaryDirectory() as folder:
        for path in paths:
            for codec in ("draco", "meshopt"):
                for budget in (0.01, 0.001):
                    out = Path(folder) / f"out_{codec}.glb"
                    result = compress_scene(
                        path, error=budget, relative=True, codec=codec, output=out
                    )
                    bits = [p.bits for p in result.primitives]
                    print(
                        f"{path.name} {codec} {budget} met={result.met} bits={bits} "
                        f"bytes={result.size_bytes} sha={_sha(out.read_bytes())} "
                        f"error={result.world_error:.9g} upper={result.world_error_upper}"
                    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    if args.quick:
        paths = [ROOT / "tests" / "data" / f"{name}.ply" for name in QUICK]
    else:
        paths = [SHARED / "meshes" / f"{name}.ply" for name in MESHES]
    for path in paths:
        single(path)
    sys.path.insert(0, str(ROOT / "tests"))
    from test_scene import build_scene

    with tempfile.TemporaryDirectory() as folder:
        scene, _ = build_scene(Path(folder) / "scene.glb")
        scenes([scene, meshbits.example_mesh_path()])


if __name__ == "__main__":
    main()
