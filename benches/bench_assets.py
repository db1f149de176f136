"""meshbits against gltfpack on a folder of real third-party assets, at gltfpack's own
independently measured error.

For every asset (``.glb``, ``.gltf``, ``.obj``) of the folder:

1. gltfpack (built from meshoptimizer's sources: a benchmark tool, not a dependency) at
   its defaults with ``-cc`` (positions 14 bits), and at ``-cc -vp 11``; its bytes and time.
2. gltfpack's world-space error, measured without meshbits (tests/independent.py: the
   files decoded with pygltflib, DracoPy and the meshopt package, skinned meshes posed by
   their skins at the rest transforms, morph targets at their default weights; a lower
   bound of the symmetric Hausdorff distance from Open3D's float32 distances, every vertex
   and area samples, corrected with exact float64 distances near the maximum).
3. ``meshbits compress`` at that error as an absolute budget (meters, the glTF unit), with
   each codec; its bytes, time, certified bound, and its own independently measured error
   (which must not exceed the bound).

Printed per asset and setting: bytes of each, the ratio meshbits/gltfpack (the smaller of
the two codecs, and each), the errors, the seconds, and the shares of geometry,
animation and images in each output (``meshbits info``'s byte accounting). Then the
median and worst ratios and how many assets meshbits beats.

    python benches/bench_assets.py FOLDER [--gltfpack PATH] [--out DIR] [--only NAME ...]

The corpus is not part of the repository: benches/CORPUS.md lists the one this project
keeps, with sources and licences.
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

import numpy as np  # noqa: E402
from independent import gltf_world_mesh, hausdorff_lower  # noqa: E402

import meshbits  # noqa: E402

SUFFIXES = (".glb", ".gltf", ".obj")
SETTINGS = {"-cc": ["-cc"], "-cc -vp 11": ["-cc", "-vp", "11"]}
CODECS = ("meshopt", "draco")
SAMPLES = 50_000


def assets(folder: Path, only: list[str] | None) -> list[Path]:
    found = sorted(
        p for p in folder.rglob("*") if p.suffix.lower() in SUFFIXES and ".venv" not in p.parts
    )
    return [p for p in found if not only or any(name in str(p) for name in only)]


def world_mesh(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """An input or output's posed world triangles, read without meshbits where the
    independent reader can (glTF), by meshbits for an OBJ input."""
    if path.suffix.lower() in (".glb", ".gltf"):
        return gltf_world_mesh(path, skinned=True)
    return meshbits.load_mesh(path)


def shares(path: Path) -> dict[str, float]:
    """Geometry, animation and image bytes as shares of the file."""
    done = subprocess.run(
        [str(Path(sys.executable).with_name("meshbits")), "info", str(path), "--json"],
        capture_output=True,
        text=True,
        check=False,
    )
    try:
        parts = json.loads(done.stdout)["bytes_by_part"]
    except (ValueError, KeyError):
        return {}
    total = max(path.stat().st_size, 1)
    return {k: v / total for k, v in parts.items() if k in ("geometry", "animation", "images")}


def run_gltfpack(tool: Path, path: Path, flags: list[str], out: Path) -> dict:
    start = time.perf_counter()
    done = subprocess.run(
        [str(tool), "-i", str(path), "-o", str(out), *flags],
        capture_output=True,
        text=True,
        check=False,
    )
    seconds = time.perf_counter() - start
    if done.returncode != 0 or not out.exists():
        return {"failed": (done.stderr or done.stdout).strip()[-200:]}
    return {"bytes": out.stat().st_size, "seconds": seconds}


def run_meshbits(path: Path, codec: str, error: float, out: Path, timeout: float) -> dict:
    argv = [
        str(Path(sys.executable).with_name("meshbits")), "compress", str(path), "-o", str(out),
        "--codec", codec, "--error", repr(error), "--json", "--quiet",
    ]  # fmt: skip
    start = time.perf_counter()
    try:
        done = subprocess.run(argv, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"failed": "timeout"}
    seconds = time.perf_counter() - start
    try:
        report = json.loads(done.stdout)
    except ValueError:
        return {"failed": (done.stderr or done.stdout).strip()[-200:]}
    if done.returncode not in (0, 1) or not out.exists():
        return {"failed": str(report.get("error"))}
    return {
        "bytes": out.stat().st_size,
        "seconds": seconds,
        "met": done.returncode == 0,
        "bound": report.get("world_error_upper"),
    }


def compare(path: Path, tool: Path, folder: Path, timeout: float) -> list[dict]:
    """One row per gltfpack setting."""
    reference = world_mesh(path)
    triangles = len(reference[1])
    rows = []
    for setting, flags in SETTINGS.items():
        row: dict = {"asset": path.name, "setting": setting, "triangles": triangles}
        packed = folder / f"{path.stem}.gltfpack{len(rows)}.glb"
        row["gltfpack"] = run_gltfpack(tool, path, flags, packed)
        if "failed" in row["gltfpack"]:
            rows.append(row)
            continue
        error = hausdorff_lower(reference, world_mesh(packed), samples=SAMPLES)
        row["gltfpack"] |= {"error": error, "shares": shares(packed)}
        if error <= 0:
            row["note"] = "gltfpack is lossless here: no error budget to compare at"
            rows.append(row)
            continue
        for codec in CODECS:
            out = folder / f"{path.stem}.meshbits{len(rows)}.{codec}.glb"
            result = run_meshbits(path, codec, error, out, timeout)
            if "failed" not in result:
                result["error"] = hausdorff_lower(reference, world_mesh(out), samples=SAMPLES)
                result["shares"] = shares(out)
                result["ratio"] = result["bytes"] / row["gltfpack"]["bytes"]
                result["holds"] = result["bound"] is None or result["error"] <= result["bound"]
            row[codec] = result
        rows.append(row)
    return rows


def _cell(result: dict) -> str:
    if "failed" in result:
        return f"failed ({result['failed'][:40]})"
    flag = "" if result.get("holds", True) else " BROKEN"
    met = "" if result.get("met", True) else " unmet"
    return f"{result['bytes']:>9,} B {result.get('ratio', 1):5.3f}{met}{flag}"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", type=Path)
    parser.add_argument("--gltfpack", type=Path, default=shutil.which("gltfpack"))
    parser.add_argument("--out", type=Path, default=None, help="keep the outputs and rows here")
    parser.add_argument("--only", nargs="+", default=None, help="assets whose path has these")
    parser.add_argument("--timeout", type=float, default=600.0, help="seconds per run")
    args = parser.parse_args()
    if args.gltfpack is None or not Path(args.gltfpack).exists():
        raise SystemExit("gltfpack not found: build it from meshoptimizer's sources, --gltfpack")
    folder = args.out or Path(tempfile.mkdtemp(prefix="bench_assets_"))
    folder.mkdir(parents=True, exist_ok=True)
    rows = []
    print(
        f"{'asset':32} {'setting':11} {'tris':>7} {'gltfpack':>11} {'error (m)':>10} "
        f"{'meshopt':>19} {'draco':>19} {'best':>6} {'s gp':>6} {'s mb':>6}"
    )
    for path in assets(args.folder, args.only):
        try:
            found = compare(path, Path(args.gltfpack), folder, args.timeout)
        except Exception as err:  # an asset the independent reader cannot pose
            print(f"{path.name:32} skipped: {type(err).__name__}: {err}")
            rows.append({"asset": path.name, "skipped": f"{type(err).__name__}: {err}"})
            continue
        for row in found:
            rows.append(row)
            packed = row["gltfpack"]
            if "failed" in packed or "note" in row:
                print(f"{path.name:32} {row['setting']:11} {packed.get('failed', row.get('note'))}")
                continue
            # Only an output within its budget and its bound counts (an unmet one is not
            # at the same error).
            ratios = [
                row[c]["ratio"]
                for c in CODECS
                if "ratio" in row.get(c, {}) and row[c]["met"] and row[c]["holds"]
            ]
            row["best_ratio"] = min(ratios) if ratios else None
            seconds = max((row[c].get("seconds", 0) for c in CODECS), default=0)
            print(
                f"{path.name:32} {row['setting']:11} {row['triangles']:>7,} "
                f"{packed['bytes']:>9,} B {packed['error']:>10.4g} "
                f"{_cell(row['meshopt']):>19} {_cell(row['draco']):>19} "
                f"{row['best_ratio'] or float('nan'):6.3f} {packed['seconds']:6.2f} {seconds:6.1f}"
            )
    (folder / "rows.json").write_text(json.dumps(rows, indent=1))
    for setting in SETTINGS:
        best = [
            r["best_ratio"] for r in rows if r.get("setting") == setting and r.get("best_ratio")
        ]
        if best:
            print(
                f"{setting}: {len(best)} assets, median best ratio {statistics.median(best):.3f}, "
                f"worst {max(best):.3f}, meshbits <= gltfpack on {sum(b <= 1 for b in best)}"
            )
    broken = sum(
        1 for r in rows for c in CODECS if isinstance(r.get(c), dict) and r[c].get("holds") is False
    )
    print(f"broken certificates: {broken}; rows in {folder / 'rows.json'}")
    return 1 if broken else 0


if __name__ == "__main__":
    raise SystemExit(main())
