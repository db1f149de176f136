"""meshbits batch on one machine: serial, the local process pool and a Dask LocalCluster.

The library: ``--count`` meshes (200 by default) made from ten small meshes of
../shared/meshes (453 to 15,982 vertices; docs/benchmarks.md lists them), each copy
rotated by a random rotation and scaled by a random factor in [0.5, 20] (seeded:
``--seed``), written as binary PLY under
``benches/out/batch/library/``, in ``--rounds`` parts (4 by default) of one sub-folder per
source mesh. Every configuration compresses all of them to a relative Hausdorff error of
0.005 (Draco), into fresh output folders, with one :func:`meshbits.batch` call per part
(so a pool or a cluster is started once per part, and that start-up is counted); the
configurations take turns part by part, so that a change in the machine's load during the
bench falls on all of them alike. The configurations:

- ``serial, 1 thread``: ``workers=1`` (in this process) with the kernels on one thread,
  the one-core baseline the ratios are taken against;
- ``serial, N threads``: ``workers=1`` with the kernels on every core (what
  ``--workers 1`` does);
- ``pool``: the default local pool, one spawned worker per core, one kernel thread each;
- ``dask``: ``dask="local:N"``, a LocalCluster of N worker processes (its start-up
  included in the wall time, as the pool's is).

Per configuration, summed over the parts: wall time (s), meshes/s, MB/s (input bytes per
wall second), and the overhead per task, ``(wall * workers - sum of task seconds) /
tasks``: the worker time per task not spent inside the task (start-up, scheduling,
sending rows back, idle workers at the end). All runs are in one process, so the ratios
come from one session of the machine; the load average (1 min) before and after each part
is printed with them.

``--memory`` runs the memory batch instead: the dragon (``dragon.ply.gz``, 437,645
vertices, 871,414 faces) among ``--small`` small meshes (40 by default), on the pool of
one worker per core, and prints each worker's peak resident memory next to its largest
input and the bound stated in docs/batch.md.

    python benches/bench_batch.py [--count 200] [--rounds 4] [--runs serial1,serialN,pool,dask]
    python benches/bench_batch.py --memory [--small 40]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import trimesh
from _shared import SHARED as SHARED_ROOT

import meshbits
from meshbits.batch import BatchResult
from meshbits.batch.task import available_cores
from meshbits.threads import get_num_threads, set_num_threads

ROOT = Path(__file__).resolve().parents[1]
SHARED = SHARED_ROOT / "meshes"
OUT = ROOT / "benches" / "out" / "batch"
SOURCES = (
    "bunny_res3",
    "bunny_res4",
    "dragon_res4",
    "suzanne",
    "spot",
    "teapot",
    "fandisk",
    "cow",
    "hand",
    "max-planck",
)
ERROR = 0.005  # relative: a fraction of each mesh's largest bounding-box side
#: The stated memory bound of one worker (docs/batch.md): BASE_BYTES (a worker with
#: meshbits and its dependencies loaded, compressing a tiny mesh) plus BYTES_PER_FACE per
#: face of the largest input it ran.
BASE_BYTES = 200e6
BYTES_PER_FACE = 1000


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


def make_library(
    folder: Path, count: int, seed: int, names: tuple[str, ...], parts: int = 1
) -> int:
    """``count`` rotated and scaled copies of the ``names`` meshes as binary PLY, copy i in
    ``part{i % parts}/`` (when ``parts > 1``), in one sub-folder per source mesh; returns
    their total size in bytes."""
    if folder.exists():
        shutil.rmtree(folder)
    rng = np.random.default_rng(seed)
    meshes = {name: meshbits.load_mesh(SHARED / f"{name}.ply") for name in names}
    total = 0
    for i in range(count):
        name = names[i % len(names)]
        vertices, faces = meshes[name]
        scale = float(np.exp(rng.uniform(np.log(0.5), np.log(20.0))))
        moved = (vertices - vertices.mean(axis=0)) @ _random_rotation(rng).T * scale
        part = folder / f"part{i % parts}" if parts > 1 else folder
        path = part / name / f"{name}_{i:03d}.ply"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(trimesh.Trimesh(moved, faces, process=False).export(file_type="ply"))
        total += path.stat().st_size
    return total


def _load() -> float:
    try:
        return os.getloadavg()[0]
    except OSError:  # pragma: no cover - not on Linux/macOS
        return float("nan")


def run(name: str, library: Path, **options: Any) -> tuple[BatchResult, dict[str, Any]]:
    """One batch call into a fresh ``out_{name}`` folder, with its figures."""
    out = OUT / f"out_{name}"
    if out.exists():
        shutil.rmtree(out)
    load = _load()
    start = time.perf_counter()
    result = meshbits.batch(library, out, error=ERROR, relative=True, **options)
    wall = time.perf_counter() - start
    ran = [r for r in result.rows if not r.resumed]
    row = {
        "run": name,
        "backend": result.backend,
        "workers": result.workers,
        "kernel_threads": result.kernel_threads,
        "tasks": len(ran),
        "met": result.met,
        "input_bytes": result.input_bytes,
        "wall_s": wall,
        "worker_s": wall * result.workers,
        "task_s_sum": sum(r.seconds for r in ran),
        "task_cpu_s_sum": sum(r.cpu_seconds or 0.0 for r in ran),
        "loads": [load, _load()],
    }
    return result, row


def throughput(args: argparse.Namespace) -> None:
    library = OUT / "library"
    cores = available_cores()
    size = make_library(library, args.count, args.seed, SOURCES, args.rounds)
    print(
        f"{args.count} meshes from {len(SOURCES)} sources, {size / 1e6:.1f} MB of binary PLY, "
        f"in {args.rounds} parts; {cores} cores; error {ERROR} relative, Draco",
        flush=True,
    )
    runs = args.runs.split(",")
    unknown = set(runs) - {"serial1", "serialN", "pool", "dask"}
    if unknown:
        sys.exit(f"unknown runs {sorted(unknown)}")
    parts: dict[str, list[dict[str, Any]]] = {name: [] for name in runs}
    before = get_num_threads()
    for k in range(args.rounds):
        folder = library / f"part{k}" if args.rounds > 1 else library
        for name in runs:
            if name in ("serial1", "serialN"):
                set_num_threads(1 if name == "serial1" else cores)
                _, part = run(name, folder, workers=1)
                set_num_threads(before)
            elif name == "pool":
                _, part = run(name, folder)
            else:
                _, part = run(name, folder, dask=f"local:{cores}")
            parts[name].append(part)
            print(
                f"  part {k}, {name}: {part['tasks']} meshes, {part['wall_s']:.1f} s, load "
                f"{part['loads'][0]:.2f} -> {part['loads'][1]:.2f}",
                flush=True,
            )
    rows = []
    for name in runs:
        done = parts[name]
        wall = sum(p["wall_s"] for p in done)
        tasks = sum(p["tasks"] for p in done)
        task_s = sum(p["task_s_sum"] for p in done)
        cpu_s = sum(p["task_cpu_s_sum"] for p in done)
        rows.append(
            {
                "run": name,
                "workers": done[0]["workers"],
                "kernel_threads": done[0]["kernel_threads"],
                "tasks": tasks,
                "not_met": tasks - sum(p["met"] for p in done),
                "wall_s": wall,
                "meshes_per_s": tasks / wall,
                "mb_per_s": sum(p["input_bytes"] for p in done) / 1e6 / wall,
                "task_s_sum": task_s,
                "task_cpu_s_sum": cpu_s,
                # CPU time the tasks got over the worker-thread time they had: 1 on an
                # idle machine, lower when other processes share the cores.
                "cpu_share": cpu_s / (task_s * done[0]["kernel_threads"]),
                "overhead_per_task_ms": 1e3 * (sum(p["worker_s"] for p in done) - task_s) / tasks,
                "loads": [x for p in done for x in p["loads"]],
                "parts": done,
            }
        )
    base = next((r for r in rows if r["run"] == "serial1"), None)
    labels = {
        "serial1": "serial, 1 kernel thread",
        "serialN": f"serial, {cores} kernel threads",
        "pool": f"local pool, {cores} processes x 1 thread",
        "dask": f"Dask LocalCluster, {cores} processes x 1 thread",
    }
    print()
    print(
        "| run | wall (s) | meshes/s | MB/s | task wall, sum (s) | task CPU, sum (s) "
        "| CPU share | overhead per task (ms) | vs serial, 1 thread |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for row in rows:
        ratio = f"{base['wall_s'] / row['wall_s']:.2f}x" if base else ""
        print(
            f"| {labels[row['run']]} | {row['wall_s']:.1f} | {row['meshes_per_s']:.2f} "
            f"| {row['mb_per_s']:.2f} | {row['task_s_sum']:.1f} | {row['task_cpu_s_sum']:.1f} "
            f"| {row['cpu_share']:.2f} | {row['overhead_per_task_ms']:.0f} | {ratio} |"
        )
    loads = [x for row in rows for x in row["loads"]]
    print()
    print(
        f"load average (1 min) at the parts' starts and ends: {min(loads):.2f} to "
        f"{max(loads):.2f}, mean {np.mean(loads):.2f}, on {cores} cores"
    )
    for row in rows:
        if row["not_met"]:
            print(f"{row['run']}: {row['not_met']} inputs did not meet the budget")
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "bench_batch.json").write_text(json.dumps(rows, indent=1))


def memory(args: argparse.Namespace) -> None:
    library = OUT / "memory_library"
    make_library(library, args.small, args.seed, ("suzanne", "bunny_res4", "spot", "teapot"))
    shutil.copy(SHARED / "dragon.ply.gz", library / "dragon.ply.gz")
    print(f"the dragon and {args.small} small meshes, {available_cores()} workers", flush=True)
    result, row = run("memory", library)
    by_worker: dict[str, list[meshbits.BatchRow]] = {}
    for r in result.rows:
        by_worker.setdefault(r.worker, []).append(r)
    print(f"{row['wall_s']:.1f} s, {result.met} met of {result.inputs}")
    print()
    print(
        "| worker | tasks | largest input (faces) | RSS at first task (MB) | peak RSS (MB) "
        "| bound (MB) | peak / bound |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|")
    for worker, rows in sorted(by_worker.items()):
        largest = max(r.input_faces or 0 for r in rows)
        idle = min(r.rss_before_bytes or 0 for r in rows)
        peak = max(r.peak_rss_bytes or 0 for r in rows)
        bound = BASE_BYTES + BYTES_PER_FACE * largest
        print(
            f"| {worker} | {len(rows)} | {largest:,} | {idle / 1e6:.0f} | {peak / 1e6:.0f} "
            f"| {bound / 1e6:.0f} | {peak / bound:.2f} |"
        )
    dragon = next(r for r in result.rows if r.relative == "dragon.ply.gz")
    rise = (dragon.peak_rss_bytes or 0) - (dragon.rss_before_bytes or 0)
    print()
    print(
        f"dragon: {dragon.input_faces:,} faces, {dragon.seconds:.1f} s, peak RSS "
        f"{(dragon.peak_rss_bytes or 0) / 1e6:.0f} MB, rise {rise / 1e6:.0f} MB = "
        f"{rise / (dragon.input_faces or 1):.0f} bytes per face ({dragon.peak_rss_scope} scope)"
    )
    small = [r for r in result.rows if r is not dragon and r.peak_rss_bytes]
    print(
        f"small meshes: peak RSS {min(r.peak_rss_bytes or 0 for r in small) / 1e6:.0f} to "
        f"{max(r.peak_rss_bytes or 0 for r in small) / 1e6:.0f} MB"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--count", type=int, default=200, help="meshes in the library")
    parser.add_argument("--seed", type=int, default=0, help="seed of the rotations and scales")
    parser.add_argument(
        "--rounds", type=int, default=4, help="parts the configurations take turns on"
    )
    parser.add_argument(
        "--runs", default="serial1,serialN,pool,dask", help="comma-separated runs, in order"
    )
    parser.add_argument("--memory", action="store_true", help="the dragon memory batch")
    parser.add_argument("--small", type=int, default=40, help="small meshes with the dragon")
    args = parser.parse_args()
    if args.memory:
        memory(args)
    else:
        throughput(args)


if __name__ == "__main__":
    main()
