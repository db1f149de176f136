"""Large-file readers and ``meshbits k`` end to end, side by side in one run (issue 34).

Writes bumpy icospheres (``refs.bumpy_icosphere``) as binary little-endian PLY files
(float32 x, y, z; uchar count + int indices: 12 bytes a vertex, 13 a face) of 1.3M, 5.2M
and 20.9M faces into a scratch folder (``--folder``, default ``/tmp/meshbits-large``;
never committed), then times, each in a fresh process whose peak resident memory the
kernel reports for it (``ru_maxrss``, through ``/usr/bin/time``):

* reading the file's bytes (``readinto`` a buffer of the file's size; page cache warm);
* meshbits's reader (``meshbits.formats.read_mesh``: the Rust reader, float64 vertices
  and uint32 faces);
* ``trimesh.load(process=False)``, plyfile (``PlyData.read``, its vertex and face
  arrays), Open3D's ``read_triangle_mesh``;
* K on ready arrays (``shape_complexity`` of float64/uint32 arrays already in memory);
* the interpreter's start and meshbits's imports (``import meshbits.cli.main``);
* ``meshbits k FILE --json`` end to end, the console command in its own process.

Each process's time is its own measurement of the operation alone (imports excluded;
``meshbits k`` is timed from outside, interpreter start included), its memory the peak
resident set of the whole process and the resident set before the operation (imports,
and for K the arrays). Targets: ``meshbits k`` within 1.5x of (reading the bytes + K on
ready arrays); its peak memory within 1.3x of the float64/uint32 arrays (24 bytes a
vertex, 12 a face).

plyfile is imported from ``--plyfile-path`` when it is not installed (``pip install
--target DIR plyfile``); a reader that is missing is reported as such.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
SUBDIVISIONS = {8: "1.3M", 9: "5.2M", 10: "20.9M"}

CHILD = r"""
import json, os, sys, time
kind, path, folder, extra = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4]
if extra:
    sys.path.append(extra)
import numpy as np
import meshbits
from meshbits.formats import read_mesh

def resident():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")

note = ""
if kind == "bytes":
    size = os.path.getsize(path)
    buffer = bytearray(size)
    before = resident()
    start = time.perf_counter()
    with open(path, "rb", buffering=0) as f:
        f.readinto(buffer)
    note = "into a buffer of the file's size, zeroed before (counted before)"
elif kind == "meshbits":
    before = resident()
    start = time.perf_counter()
    read = read_mesh(path)
    note = f"{read.reader}, faces {read.faces.dtype}"
elif kind == "trimesh":
    import trimesh
    before = resident()
    start = time.perf_counter()
    mesh = trimesh.load(path, process=False)
    note = f"faces {mesh.faces.dtype}"
elif kind == "plyfile":
    from plyfile import PlyData
    before = resident()
    start = time.perf_counter()
    ply = PlyData.read(path)
    v, f = ply["vertex"].data, ply["face"].data
    note = f"structured arrays (float32 xyz, object lists: {f.dtype})"
elif kind == "open3d":
    import open3d as o3d
    before = resident()
    start = time.perf_counter()
    mesh = o3d.io.read_triangle_mesh(path)
    note = f"{len(mesh.triangles)} triangles, Eigen float64/int32"
elif kind == "k":
    V = np.load(os.path.join(folder, "v.npy"))
    F = np.load(os.path.join(folder, "f.npy"))
    before = resident()
    start = time.perf_counter()
    k = meshbits.shape_complexity(V, F)
    note = f"K = {k.k:.12g}"
seconds = time.perf_counter() - start
print(json.dumps({"seconds": seconds, "before": before, "note": note}))
"""


def write_ply(path: Path, subdivisions: int, refs) -> tuple[int, int]:
    """The bumpy icosphere as a binary PLY (float32 xyz, uchar count + int indices)."""
    V, F = refs.bumpy_icosphere(subdivisions)
    header = (
        f"ply\nformat binary_little_endian 1.0\nelement vertex {len(V)}\n"
        "property float x\nproperty float y\nproperty float z\n"
        f"element face {len(F)}\nproperty list uchar int vertex_indices\nend_header\n"
    ).encode()
    faces = np.empty(len(F), dtype=[("n", "u1"), ("i", "<i4", 3)])
    faces["n"], faces["i"] = 3, F
    with open(path, "wb") as out:
        out.write(header)
        out.write(V.astype("<f4").tobytes())
        out.write(faces.tobytes())
    return len(V), len(F)


def prepare(folder: Path, subdivisions: int, refs) -> tuple[Path, int, int]:
    """The PLY file and the float64/uint32 arrays K takes (as .npy), made once."""
    import meshbits.formats

    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"bumpy{subdivisions}.ply"
    arrays = folder / f"arrays{subdivisions}"
    if not path.is_file() or not (arrays / "f.npy").is_file():
        write_ply(path, subdivisions, refs)
        read = meshbits.formats.read_mesh(path)
        arrays.mkdir(exist_ok=True)
        np.save(arrays / "v.npy", read.vertices)
        np.save(arrays / "f.npy", read.faces)
    V = np.load(arrays / "v.npy", mmap_mode="r")
    F = np.load(arrays / "f.npy", mmap_mode="r")
    return path, len(V), len(F)


def run(argv: list[str]) -> tuple[float, int, str]:
    """Runs ``argv`` under ``/usr/bin/time``; returns its wall time, its peak resident
    bytes and its stdout. (``wait4`` on a child of this process would report at least
    this process's own peak: Linux carries the high-water mark across fork and exec.)"""
    with tempfile.NamedTemporaryFile("r", suffix=".txt") as peak_file:
        timed = ["/usr/bin/time", "-f", "%M", "-o", peak_file.name, *argv]
        start = time.perf_counter()
        done = subprocess.run(timed, capture_output=True, check=False)
        wall = time.perf_counter() - start
        if done.returncode != 0:
            raise RuntimeError(f"{' '.join(argv[:5])} failed: {done.stderr.decode()[-800:]}")
        peak = int(peak_file.read().split()[-1]) * 1024
    return wall, peak, done.stdout.decode()


def row(name: str, seconds: float, peak: int, before: int | None, arrays: int, note: str) -> None:
    added = "" if before is None else f"{(peak - before) / 1e6:,.0f}"
    print(
        f"| {name} | {seconds:.2f} | {peak / 1e6:,.0f} | {added} | {peak / arrays:.2f} | {note} |",
        flush=True,
    )


def bench(path: Path, vertices: int, faces: int, folder: Path, plyfile_path: str) -> None:
    arrays = 24 * vertices + 12 * faces
    print(
        f"\n### {faces:,} faces, {vertices:,} vertices: {path.stat().st_size / 1e6:,.0f} MB "
        f"PLY, arrays (float64 vertices + uint32 faces) {arrays / 1e6:,.0f} MB\n"
    )
    print("| what | time (s) | peak RSS (MB) | added by it (MB) | peak / arrays | note |")
    print("|---|---:|---:|---:|---:|---|")
    times = {}
    for kind, name in [
        ("bytes", "reading the file's bytes"),
        ("meshbits", "meshbits reader (read_mesh)"),
        ("trimesh", "trimesh.load"),
        ("plyfile", "plyfile"),
        ("open3d", "Open3D read_triangle_mesh"),
        ("k", "K on ready arrays"),
    ]:
        argv = [sys.executable, "-c", CHILD, kind, str(path), str(folder), plyfile_path]
        try:
            _, peak, out = run(argv)
        except RuntimeError as err:
            print(f"| {name} | | | | | failed: {str(err).splitlines()[-1][:120]} |")
            continue
        own = json.loads(out.strip().splitlines()[-1])
        times[kind] = own["seconds"]
        row(name, own["seconds"], peak, own["before"], arrays, own["note"])
    start_wall, start_peak, _ = run([sys.executable, "-c", "import meshbits.cli.main"])
    row("interpreter start + meshbits imports", start_wall, start_peak, None, arrays, "")
    wall, peak, out = run([sys.executable, "-m", "meshbits.cli", "k", str(path), "--json"])
    report = json.loads(out)
    times["cli"] = wall
    row(
        "`meshbits k` end to end",
        wall,
        peak,
        None,
        arrays,
        f"K = {report['k']:.12g}, "
        f"reader {report['reader']}, interpreter start and imports included",
    )
    if "bytes" in times and "k" in times:
        budget = times["bytes"] + times["k"]
        print(
            f"\n`meshbits k`: {wall:.2f} s against 1.5 x (bytes {times['bytes']:.2f} s + K "
            f"{times['k']:.2f} s) = {1.5 * budget:.2f} s: "
            f"{'met' if wall <= 1.5 * budget else 'not met'} ({wall / budget:.2f}x); "
            f"peak {peak / 1e6:,.0f} MB against 1.3 x arrays = {1.3 * arrays / 1e6:,.0f} MB: "
            f"{'met' if peak <= 1.3 * arrays else 'not met'} ({peak / arrays:.2f}x)"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--folder", type=Path, default=Path("/tmp/meshbits-large"))
    parser.add_argument(
        "--subdivisions",
        type=int,
        nargs="+",
        default=[8, 9, 10],
        choices=sorted(SUBDIVISIONS),
        help="8: 1.3M faces, 9: 5.2M, 10: 20.9M",
    )
    parser.add_argument("--plyfile-path", default="", help="a folder holding plyfile")
    args = parser.parse_args()
    sys.path.insert(0, str(HERE))
    from _shared import import_refs

    import meshbits

    if meshbits._core.BUILD_PROFILE != "release":
        raise SystemExit("benchmark a release build")
    refs = import_refs()
    print(
        f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {os.cpu_count()} cores, "
        f"load average {os.getloadavg()[0]:.1f} at the start"
    )
    for s in args.subdivisions:
        path, vertices, faces = prepare(args.folder, s, refs)
        bench(path, vertices, faces, args.folder / f"arrays{s}", args.plyfile_path)
    print(f"\nload average {os.getloadavg()[0]:.1f} at the end")


if __name__ == "__main__":
    main()
