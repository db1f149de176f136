"""Benchmark: closest points and the sampled Hausdorff distance, meshbits against peers.

Meshes: an icosphere with bumps (radius ``1 + 0.08 sin 6x sin 6y sin 6z + 0.02 sin(20x + 3y)``)
at 327,680 and 1,310,720 faces, against its 8-bit quantized copy (same connectivity, the
vertices rounded to a 255-step grid over the bounding box). Each side is sampled with
:func:`meshbits.surface_samples` (every referenced vertex plus N area samples, seed 0), and
*every tool is given these same points*, in both directions.

Per tool: the time to build its acceleration structures for both meshes, the time of the
closest-point queries of both directions, queries per second, the symmetric Hausdorff
distance H (the larger of the two sampled maxima) and its relative difference to
meshbits's. "meshbits max-only H" is the whole ``meshbits.hausdorff(a, b,
statistics=False)`` call, sampling and both BVH builds included; the peers' "total" is
their two builds plus their two query passes (their sampling is not counted). The last
column is that total over meshbits's max-only total. Every time is the shortest of
``REPEATS`` (3) runs (trimesh: one run), builds and queries taken separately for the peers:
the first run in a process pays for fresh memory (page faults), which a CLI user pays once
and a long-running tool once per size.

Peers that fail to import are skipped with a note. trimesh runs on a subset of the points
(its answer is not a reference: it misses the closest triangle for some queries) and its
query time is extrapolated; it is skipped on the large mesh, whose rtree takes minutes.
PyMeshLab's ``get_hausdorff_distance`` is given the points as a vertex-only mesh with
``samplevert=True`` (its default samples vertices only, unreferenced ones included).

A second part (``--bounds``, also in the full run) measures the certified upper bound:
``hausdorff(..., tolerance=t)`` on the Stanford bunny against its 8-bit clustered copy and
on the 1.3M-face sphere, reporting lower, upper, the refinement points and the time; and
the PyMeshLab trap on the bunny: its filter with default options (vertices only,
unreferenced vertices included) against the surface value.

    python benches/bench_hausdorff.py            # both meshes, 100k and 1M samples, bounds
    python benches/bench_hausdorff.py --quick    # the small mesh, 100k samples
    python benches/bench_hausdorff.py --bounds   # the bounds and trap part only
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import trimesh

import meshbits

BUNNY = Path(__file__).resolve().parent.parent / "tests" / "data" / "bunny.ply"


def bumpy_icosphere(subdivisions: int) -> tuple[np.ndarray, np.ndarray]:
    mesh = trimesh.creation.icosphere(subdivisions=subdivisions)
    x, y, z = mesh.vertices.T
    r = 1 + 0.08 * np.sin(6 * x) * np.sin(6 * y) * np.sin(6 * z) + 0.02 * np.sin(20 * x + 3 * y)
    return mesh.vertices * r[:, None], np.asarray(mesh.faces, dtype=np.int64)


def quantize(vertices: np.ndarray, bits: int = 8) -> np.ndarray:
    lo = vertices.min(axis=0)
    size = (vertices.max(axis=0) - lo).max()
    k = 2**bits - 1
    return lo + np.round((vertices - lo) * k / size) * size / k


REPEATS = 3


def timed(fn: Callable[[], object]) -> tuple[float, object]:
    start = time.perf_counter()
    out = fn()
    return time.perf_counter() - start, out


def best_of(fn: Callable[[], object], repeats: int = REPEATS) -> tuple[float, object]:
    """The shortest of ``repeats`` timed calls, and the last call's result."""
    times, out = [], None
    for _ in range(repeats):
        seconds, out = timed(fn)
        times.append(seconds)
    return min(times), out


def best_peer(run: Callable, *args, repeats: int = REPEATS) -> tuple[float, float, float, str]:
    """A peer run ``repeats`` times: its shortest build and shortest query time."""
    results = [run(*args) for _ in range(repeats)]
    build = min(r[0] for r in results)
    query = min(r[1] for r in results)
    return build, query, results[-1][2], results[-1][3]


# --- peers: each returns (build seconds, query seconds, symmetric H, note) -----------------


def run_open3d(a, b, pa, pb):
    import open3d as o3d

    def scene(mesh):
        s = o3d.t.geometry.RaycastingScene()
        s.add_triangles(
            o3d.core.Tensor(mesh[0].astype(np.float32)), o3d.core.Tensor(mesh[1].astype(np.uint32))
        )
        s.compute_distance(o3d.core.Tensor(np.zeros((1, 3), np.float32)))  # builds the BVH
        return s

    tb, (sa, sb) = timed(lambda: (scene(a), scene(b)))
    pa32, pb32 = pa.astype(np.float32), pb.astype(np.float32)
    tq, (dab, dba) = timed(
        lambda: (
            sb.compute_distance(o3d.core.Tensor(pa32)).numpy(),
            sa.compute_distance(o3d.core.Tensor(pb32)).numpy(),
        )
    )
    return tb, tq, max(float(dab.max()), float(dba.max())), "float32"


def run_fcpw(a, b, pa, pb):
    import fcpw

    def scene(mesh):
        s = fcpw.scene_3D()
        s.set_object_count(1)
        s.set_object_vertices(np.asfortranarray(mesh[0], dtype=np.float32), 0)
        s.set_object_triangles(np.asfortranarray(mesh[1], dtype=np.int32), 0)
        s.build(fcpw.aggregate_type.bvh_surface_area, True)
        return s

    tb, (sa, sb) = timed(lambda: (scene(a), scene(b)))

    def query(s, p):
        hits = fcpw.interaction_3D_list()
        s.find_closest_points(
            np.asfortranarray(p, dtype=np.float32), np.full(len(p), np.inf, np.float32), hits
        )
        return hits

    tq, (hab, hba) = timed(lambda: (query(sb, pa), query(sa, pb)))
    h = max(max(x.d for x in hab), max(x.d for x in hba))
    return tb, tq, float(h), "float32, vectorized SAH BVH"


def run_libigl(a, b, pa, pb):
    import igl

    def tree(mesh):
        t = igl.AABB()
        t.init(mesh[0], mesh[1])
        return t

    tb, (ta, tb_) = timed(lambda: (tree(a), tree(b)))

    def query(t, mesh, p):
        d2, _, _ = t.squared_distance(mesh[0], mesh[1], p)
        return d2

    tq, (dab, dba) = timed(lambda: (query(tb_, b, pa), query(ta, a, pb)))
    return tb, tq, float(np.sqrt(max(dab.max(), dba.max()))), "float64 AABB tree"


def run_pymeshlab(a, b, pa, pb):
    import pymeshlab

    def one_way(points, target):
        ms = pymeshlab.MeshSet()
        ms.add_mesh(pymeshlab.Mesh(vertex_matrix=points))
        ms.add_mesh(pymeshlab.Mesh(vertex_matrix=target[0], face_matrix=target[1].astype(np.int32)))
        r = ms.get_hausdorff_distance(
            sampledmesh=0,
            targetmesh=1,
            samplevert=True,
            sampleedge=False,
            sampleface=False,
            samplenum=len(points),
            maxdist=pymeshlab.PercentageValue(100),
        )
        return float(r["max"])

    tq, h = timed(lambda: max(one_way(pa, b), one_way(pb, a)))
    return 0.0, tq, h, "build inside the query time"


def run_trimesh(a, b, pa, pb, subset=2000):
    ma = trimesh.Trimesh(a[0], a[1], process=False)
    mb = trimesh.Trimesh(b[0], b[1], process=False)
    tb, _ = timed(lambda: (ma.triangles_tree, mb.triangles_tree))
    rng = np.random.default_rng(0)
    sa, sb = rng.choice(len(pa), subset, replace=False), rng.choice(len(pb), subset, replace=False)
    tq, (dab, dba) = timed(
        lambda: (
            trimesh.proximity.closest_point(mb, pa[sa])[1],
            trimesh.proximity.closest_point(ma, pb[sb])[1],
        )
    )
    scale = (len(pa) + len(pb)) / (2 * subset)
    note = f"{subset} + {subset} points, time x{scale:.0f}; H on the subset"
    return tb, tq * scale, float(max(dab.max(), dba.max())), note


PEERS = {
    "open3d": run_open3d,
    "fcpw": run_fcpw,
    "libigl": run_libigl,
    "pymeshlab": run_pymeshlab,
    "trimesh": run_trimesh,
}


def bench(subdivisions: int, samples: int, peers: list[str], skipped: dict[str, str]) -> None:
    a = bumpy_icosphere(subdivisions)
    b = (quantize(a[0]), a[1])
    pa = meshbits.surface_samples(a, samples=samples, seed=0).points
    pb = meshbits.surface_samples(b, samples=samples, seed=0).points
    n = len(pa) + len(pb)
    print(
        f"\n### {len(a[1]):,} faces vs 8-bit quantized, {samples:,} area samples per side "
        f"({len(pa):,} + {len(pb):,} = {n:,} query points)\n"
    )
    rows = []

    # meshbits: whole max-only and full-statistics calls, then the bare query throughput.
    t_max, r_max = best_of(lambda: meshbits.hausdorff(a, b, samples=samples, statistics=False))
    t_full, r_full = best_of(lambda: meshbits.hausdorff(a, b, samples=samples))
    t_bound, r_bound = best_of(
        lambda: meshbits.hausdorff(a, b, samples=samples, statistics=False, bounds=True)
    )
    tb, (ca, cb) = best_of(lambda: (meshbits.ClosestPoints(a), meshbits.ClosestPoints(b)))
    tq, (qab, qba) = best_of(lambda: (cb.query(pa), ca.query(pb)))
    h_ref = max(float(qab.distances.max()), float(qba.distances.max()))
    assert h_ref == r_max.distance == r_full.distance, (h_ref, r_max.distance, r_full.distance)
    rows.append(("meshbits max-only H", None, None, t_max, r_max.distance, "whole call"))
    rows.append(("meshbits full statistics", None, None, t_full, r_full.distance, "whole call"))
    rows.append(
        (
            "meshbits max-only + bounds",
            None,
            None,
            t_bound,
            r_bound.distance,
            f"upper {r_bound.upper:.6g}",
        )
    )
    rows.append(("meshbits ClosestPoints", tb, tq, tb + tq, h_ref, "float64, exact"))
    for name in peers:
        if name in skipped:
            continue
        if name == "trimesh" and len(a[1]) > 400_000:
            rows.append((name, None, None, None, None, "skipped: rtree build takes minutes"))
            continue
        try:
            repeats = 1 if name == "trimesh" else REPEATS
            build, query, h, note = best_peer(PEERS[name], a, b, pa, pb, repeats=repeats)
        except Exception as err:  # a peer's failure is reported, not fatal
            rows.append((name, None, None, None, None, f"failed: {type(err).__name__}: {err}"))
            continue
        rows.append((name, build, query, build + query, h, note))

    print(
        "| tool | build (s) | query (s) | queries/s | total (s) | H | H rel. diff "
        "| x meshbits max-only | note |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|---|")
    for name, build, query, total, h, note in rows:
        qps = f"{n / query / 1e6:.2f} M" if query else ""
        diff = f"{abs(h - h_ref) / h_ref:.1e}" if h is not None else ""
        ratio = f"{total / t_max:.1f}" if total is not None else ""
        cells = [
            name,
            f"{build:.3f}" if build is not None else "",
            f"{query:.3f}" if query is not None else "",
            qps,
            f"{total:.3f}" if total is not None else "",
            f"{h:.6g}" if h is not None else "",
            diff,
            ratio,
            note,
        ]
        print("| " + " | ".join(cells) + " |")


def bounds_and_traps() -> None:
    print("\n### Certified upper bound (max-only, default samples, seed 0)\n")
    print(
        "| case | faces | tolerance | lower (sampled H) | upper | upper - lower "
        "| refined points | converged | time (s) |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    raw = trimesh.load(BUNNY, process=False)
    bunny = (np.asarray(raw.vertices), np.asarray(raw.faces))
    clustered = meshbits.cluster(bunny, bits=8)
    size = float(np.ptp(bunny[0], axis=0).max())
    sphere = bumpy_icosphere(8)
    cases = [
        ("bunny vs 8-bit clustered", bunny, (clustered.vertices, clustered.faces)),
        ("bumpy sphere vs 8-bit quantized", sphere, (quantize(sphere[0]), sphere[1])),
    ]
    for name, a, b in cases:
        extent = float(np.ptp(a[0], axis=0).max())
        for relative in (None, 1e-3, 1e-4):
            tolerance = None if relative is None else relative * extent
            seconds, r = timed(
                lambda a=a, b=b, t=tolerance: meshbits.hausdorff(
                    a, b, statistics=False, bounds=True, tolerance=t
                )
            )
            refined = r.a_to_b.refined_points + r.b_to_a.refined_points
            converged = (
                "" if tolerance is None else str(bool(r.a_to_b.converged and r.b_to_a.converged))
            )
            cells = [
                name,
                f"{len(a[1]):,}",
                "none (bounds only)" if tolerance is None else f"{tolerance:.3g}",
                f"{r.distance:.6g}",
                f"{r.upper:.6g}",
                f"{r.upper - r.distance:.3g}",
                f"{refined:,}",
                converged,
                f"{seconds:.2f}",
            ]
            print("| " + " | ".join(cells) + " |")

    print("\n### PyMeshLab's defaults on the bunny vs its 8-bit clustered copy\n")
    referenced_points = bunny[0][np.unique(bunny[1])]
    unreferenced = len(bunny[0]) - len(referenced_points)
    ours = meshbits.hausdorff(bunny, (clustered.vertices, clustered.faces), tolerance=1e-4 * size)
    print(f"bunny: {len(bunny[0]):,} vertices, {unreferenced:,} of them unreferenced")
    print(
        f"meshbits h(bunny -> clustered): sampled {ours.a_to_b.max:.4g}, certified upper "
        f"{ours.a_to_b.upper:.4g} (tolerance {1e-4 * size:.2g})"
    )
    try:
        import pymeshlab
    except Exception as err:
        print(f"pymeshlab: cannot import ({type(err).__name__}: {err})")
        return
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=bunny[0], face_matrix=bunny[1].astype(np.int32)))
    ms.add_mesh(
        pymeshlab.Mesh(
            vertex_matrix=clustered.vertices, face_matrix=clustered.faces.astype(np.int32)
        )
    )
    default = ms.get_hausdorff_distance(sampledmesh=0, targetmesh=1)
    print(f"pymeshlab get_hausdorff_distance, default options: max {default['max']:.4g}")
    ms.add_mesh(
        pymeshlab.Mesh(vertex_matrix=referenced_points, face_matrix=np.zeros((0, 3), np.int32))
    )
    referenced = ms.get_hausdorff_distance(sampledmesh=2, targetmesh=1)
    target = meshbits.ClosestPoints((clustered.vertices, clustered.faces))
    same_points = target.query(referenced_points).distances.max()
    print(
        f"pymeshlab on the referenced vertices only: max {referenced['max']:.4g} "
        f"(meshbits on the same points: {same_points:.4g})"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small mesh and 100k samples only")
    parser.add_argument(
        "--bounds", action="store_true", help="the certified-bound and trap part only"
    )
    parser.add_argument("--peers", default=",".join(PEERS), help="comma-separated peers to run")
    args = parser.parse_args()
    if meshbits._core.BUILD_PROFILE != "release":
        raise SystemExit("meshbits is a debug build: run `maturin develop --release` first")
    peers = [p for p in args.peers.split(",") if p]
    skipped = {}
    for name in peers:
        module = {"libigl": "igl"}.get(name, name)
        try:
            __import__(module)
        except Exception as err:
            skipped[name] = f"{type(err).__name__}: {err}"
    print(f"meshbits {meshbits.__version__}, {os.cpu_count()} cores, default thread count")
    for name, why in skipped.items():
        print(f"skipped {name}: cannot import ({why})")
    if args.bounds:
        bounds_and_traps()
        return
    cases = [(7, 100_000)]
    if not args.quick:
        cases += [(7, 1_000_000), (8, 100_000), (8, 1_000_000)]
    for subdivisions, samples in cases:
        bench(subdivisions, samples, peers, skipped)
    if not args.quick:
        bounds_and_traps()


if __name__ == "__main__":
    main()
