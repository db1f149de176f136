"""The speed targets of issue 16, each against its reference in ../shared/bench-refs/refs.py
(stated in docs/benchmarks.md).

Every ratio is ``reference time / meshbits time`` measured in this one run, on the same
arrays (best of ``--repeat`` calls for meshbits, of fewer for the slower references):

* K: :func:`meshbits.shape_complexity` against ``k_reference`` on ``bumpy_icosphere(8)``
  (and 9 with ``--large``); the peak memory K allocates beyond its input arrays, measured
  in a fresh process, against the size of those arrays.
* cluster: :func:`meshbits.cluster` at B = 8 against ``cluster_reference``.
* Hausdorff: :func:`meshbits.hausdorff` between ``bumpy_icosphere(8)`` and its 8-bit
  clustered mesh against ``hausdorff_open3d``, at 100k and 1M samples per side, with its
  statistics (every sample's exact distance, as Open3D computes them) and max only (what
  compress measures, and all ``hausdorff_open3d`` returns).

    python benches/bench_refs.py [--repeat 5] [--large] [--skip-hausdorff]
    python benches/bench_refs.py --linearity
    python benches/bench_refs.py --phases

``--phases`` times K's phases apart on ``bumpy_icosphere(8)`` (the Rust driver
``benches/k_phases.rs``, built with cargo): the edge table alone against the time the 30x
target allows.
"""

from __future__ import annotations

import os

# OpenBLAS threads left spinning by the references' numpy calls steal CPU from the next call.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from _shared import import_refs

import meshbits

ROOT = Path(__file__).resolve().parents[1]
refs = import_refs()

# Run in a fresh process: the peak resident set K adds on top of its loaded input.
PEAK = """
import numpy as np
import meshbits
def high_water():
    status = open("/proc/self/status").read()
    return int(status.split("VmHWM:")[1].split()[0]) * 1024
V, F = np.load({v!r}), np.load({f!r})
meshbits.shape_complexity(V[:4], np.array([[0, 1, 2]]))
before = high_water()
meshbits.shape_complexity(V, F)
print(high_water() - before, V.nbytes + F.nbytes)
"""


def best(repeat: int, fn: Callable[..., object], *args: object, **kwargs: object) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn(*args, **kwargs)
        times.append(time.perf_counter() - start)
    return min(times)


def row(what: str, faces: int, ours: float, ref: float, target: float, note: str = "") -> None:
    ratio = ref / ours
    met = "yes" if ratio >= target else "no"
    print(
        f"| {what} | {faces:,} | {ours * 1e3:.1f} | {ref * 1e3:.1f} | {ratio:.1f}x "
        f"| {target:g}x | {met} | {1e9 * ours / faces:.0f} | {note} |",
        flush=True,
    )


def phases(repeat: int) -> None:
    """K's phases on ``bumpy_icosphere(8)`` timed by the Rust driver, beside
    ``k_reference`` and the time 30x of it allows."""
    V, F = refs.bumpy_icosphere(8)
    ref = best(2, refs.k_reference, V, F)
    subprocess.run(
        ["cargo", "build", "--quiet", "--release", "--example", "k_phases"], cwd=ROOT, check=True
    )
    with tempfile.TemporaryDirectory() as tmp:
        v, f = Path(tmp) / "v.f64", Path(tmp) / "f.i64"
        np.ascontiguousarray(V, dtype="<f8").tofile(v)
        np.ascontiguousarray(F, dtype="<i8").tofile(f)
        driver = ROOT / "target" / "release" / "examples" / "k_phases"
        print(subprocess.check_output([driver, v, f, str(max(repeat, 5))], text=True), end="")
    print(
        f"\nk_reference: {ref * 1e3:.1f} ms; K at 30x of it: {ref * 1e3 / 30:.1f} ms "
        f"(load average {os.getloadavg()[0]:.1f} at the end)"
    )


def linearity(repeat: int) -> None:
    """K's ns/face on bumpy icospheres of 1.3M, 5.2M and 21M faces, in one process
    (target: within 1.3x of each other)."""
    print(f"load average {os.getloadavg()[0]:.1f} at the start, {os.cpu_count()} cores")
    print("| subdivision | faces | K (ms) | ns/face |")
    print("|---:|---:|---:|---:|")
    per_face = []
    for s in (8, 9, 10):
        V, F = refs.bumpy_icosphere(s)
        seconds = best(repeat if s < 10 else 3, meshbits.shape_complexity, V, F)
        per_face.append(1e9 * seconds / len(F))
        print(f"| {s} | {len(F):,} | {1e3 * seconds:.1f} | {per_face[-1]:.0f} |", flush=True)
        del V, F
    spread = max(per_face) / min(per_face)
    print(f"\nns/face from 1.3M to 21M faces: {spread:.2f}x apart (target <= 1.3x)")
    print(f"load average at the end: {os.getloadavg()[0]:.1f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--large", action="store_true", help="also K at subdivision 9")
    parser.add_argument("--skip-hausdorff", action="store_true")
    parser.add_argument(
        "--linearity",
        action="store_true",
        help="only K's time per face at subdivisions 8, 9 and 10 (1.3M to 21M faces)",
    )
    parser.add_argument(
        "--phases",
        action="store_true",
        help="only K's phases timed apart (the edge table alone, the weld, the whole K)",
    )
    args = parser.parse_args()
    if args.phases:
        phases(args.repeat)
        return
    if meshbits._core.BUILD_PROFILE != "release":
        raise SystemExit("benchmark a release build: maturin develop --release")
    if args.linearity:
        linearity(args.repeat)
        return
    load = os.getloadavg()[0]
    print(
        f"meshbits {meshbits.__version__}, {os.cpu_count()} cores, load average {load:.1f} "
        f"at the start, numpy {np.__version__}"
    )
    print(
        "| kernel | faces | meshbits (ms) | reference (ms) | ratio | target | met "
        "| meshbits ns/face | note |"
    )
    print("|---|---:|---:|---:|---:|---:|---|---:|---|")
    for s in (8, 9) if args.large else (8,):
        V, F = refs.bumpy_icosphere(s)
        got = meshbits.shape_complexity(V, F)
        want, _ = refs.k_reference(V, F)
        assert abs(got.k_raw - want) <= 1e-9 * want, (got.k_raw, want)
        ours = best(args.repeat, meshbits.shape_complexity, V, F)
        ref = best(1 if s > 8 else 2, refs.k_reference, V, F)
        row(f"K (s={s})", len(F), ours, ref, 30)
    s = 8
    V, F = refs.bumpy_icosphere(s)
    ours = best(args.repeat, meshbits.cluster, V, F, bits=8)
    ref = best(3, refs.cluster_reference, V, F, 8)
    row("cluster B=8", len(F), ours, ref, 5)
    if not args.skip_hausdorff:
        c = meshbits.cluster(V, F, bits=8)
        Vb, Fb = c.vertices, c.faces.astype(np.int64)
        for samples in (100_000, 1_000_000):
            ref = best(2, refs.hausdorff_open3d, V, F, Vb, Fb, samples=samples)
            # Statistics: every sample's exact distance, as Open3D computes them; max only:
            # what compress measures, and all that hausdorff_open3d returns.
            ours = best(3, meshbits.hausdorff, (V, F), (Vb, Fb), samples=samples)
            row("Hausdorff", len(F), ours, ref, 3, f"{samples:,} samples per side, statistics")
            ours = best(3, meshbits.hausdorff, (V, F), (Vb, Fb), samples=samples, statistics=False)
            row("Hausdorff", len(F), ours, ref, 3, f"{samples:,} samples per side, max only")
    with tempfile.TemporaryDirectory() as tmp:
        v, f = str(Path(tmp) / "v.npy"), str(Path(tmp) / "f.npy")
        np.save(v, V)
        np.save(f, F)
        code = PEAK.format(v=v, f=f)
        peak, inputs = map(int, subprocess.check_output([sys.executable, "-c", code]).split())
    print(
        f"\nK peak memory beyond its input at s=8: {peak / 2**20:.0f} MiB for "
        f"{inputs / 2**20:.0f} MiB of input arrays (float64 vertices, int64 faces): "
        f"{peak / inputs:.2f}x (target <= 2x)"
    )
    print(f"load average at the end: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
