"""The certificate matrix of tests/test_certificates.py, larger: every output path at
many offsets, scales and budgets, each written file read back without meshbits and
measured in float64 (tests/independent.py), with counts of broken certificates, unmet
budgets and cases over a minute.

    python benches/certificates.py [--cases N] [--seed S] [--mesh tests/data/bunny_res3.ply]

Prints one line per case and a table of counts per output; docs/reliability.md keeps the
last run. Exit code 1 when any certificate is broken or any case ran past a minute.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from test_certificates import CASE_SECONDS, OUTPUTS, rotation, run_case  # noqa: E402

import meshbits  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=120, help="cases (default 120)")
    parser.add_argument("--seed", type=int, default=1, help="seed of the draws (default 1)")
    parser.add_argument(
        "--mesh", type=Path, default=ROOT / "tests" / "data" / "bunny_res3.ply", help="input"
    )
    args = parser.parse_args()
    vertices, faces = meshbits.load_mesh(args.mesh)
    vertices = vertices - vertices.mean(axis=0)
    side = float(np.ptp(vertices, axis=0).max())
    rng = np.random.default_rng(args.seed)
    counts = {f"{s} {c or ''}".strip(): [0, 0, 0, 0, 0.0, 0] for s, c in OUTPUTS}
    broken = slow = 0
    started = time.perf_counter()
    case = 0
    while case < args.cases:
        output = OUTPUTS[case % len(OUTPUTS)]
        scale = 10.0 ** rng.uniform(-9, 9)
        axis = rng.normal(size=3) * (rng.random(3) < 0.7)
        offset = 10.0 ** rng.uniform(-2, 7) * axis / max(np.abs(axis).max(), 1e-300)
        if np.abs(offset).max() * 2.0**-52 >= 1e-5 * scale * side:
            continue  # the float64 input cannot hold the shape there: nothing to certify
        moved = vertices @ rotation(tuple(rng.uniform(0, 2 * math.pi, 3))).T * scale + offset
        error = float(10 ** rng.uniform(-3, math.log10(0.05))) if rng.random() < 0.6 else None
        size = None if error is not None else int(rng.integers(2_000, 40_000))
        with tempfile.TemporaryDirectory() as folder:
            result = run_case(Path(folder), moved, faces, output, error, size)
        budget = f"error {error:.3g} x S" if error is not None else f"size {size} B"
        row = counts[f"{output[0]} {output[1] or ''}".strip()]
        if "refused" in result:
            row[0] += 1
            row[5] += 1
            print(
                f"{case:4d} {output[0]:5s} {output[1] or '':8s} scale {scale:9.3g} offset "
                f"{np.abs(offset).max():9.3g} {budget:18s} refused: {result['refused']}"
            )
            case += 1
            continue
        bound, true = result["bound"], result["true"]
        bad = bound is not None and true > bound
        row[0] += 1
        row[1] += bad
        row[2] += not result["met"]
        row[3] += result["seconds"] >= CASE_SECONDS
        row[4] = max(row[4], result["seconds"])
        broken += bad
        slow += result["seconds"] >= CASE_SECONDS
        print(
            f"{case:4d} {output[0]:5s} {output[1] or '':8s} scale {scale:9.3g} offset "
            f"{np.abs(offset).max():9.3g} {budget:18s} met {result['met']!s:5s} bound "
            f"{'none' if bound is None else f'{bound:.4g}':>10} true >= {true:.4g} "
            f"{result['seconds']:5.1f} s{'  BROKEN' if bad else ''}",
            flush=True,
        )
        case += 1
    print(f"\n{args.cases} cases on {args.mesh.name}, {time.perf_counter() - started:.0f} s")
    print(
        "| output | cases | broken certificates | budgets not met | refused (float32) "
        "| over 60 s | longest (s) |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|")
    for name, (n, bad, unmet, over, longest, refused) in counts.items():
        print(f"| {name} | {n} | {bad} | {unmet} | {refused} | {over} | {longest:.1f} |")
    return 1 if broken or slow else 0


if __name__ == "__main__":
    raise SystemExit(main())
