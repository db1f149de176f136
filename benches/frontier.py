"""compress against a brute-force oracle: how close it comes to the fewest bytes (or the
least error) any (simplification, B) of a dense grid reaches.

The oracle, per mesh: a ladder of 20 vertex counts (log-spaced, the full mesh included)
from each of three simplifiers (meshoptimizer keeping input vertices, meshoptimizer moving
them to their quadric optimum, fast-simplification), times every B from 6 to 20; each cell
encoded with Draco (DracoPy, compression level 7, the cube grid of the original's box) and
decoded with DracoPy. Every cell is measured with meshbits; the cells that decide a
budget, and every output of compress, are measured independently of meshbits with Open3D
(``hausdorff_open3d`` of ../shared/bench-refs/refs.py, stated in docs/benchmarks.md: every
vertex plus 300,000 area samples per mesh, float32 RaycastingScene), and Open3D's number
decides. A certified oracle is placed too. For error budgets: the smallest cell whose
meshbits certified bound, refined until it decides the budget as compress certifies its
answers, is within it (and Open3D confirms it). For size budgets: the cell of least
certified error (the bound's upper end, refined to within 1% of the sampled maximum),
against compress's output certified the same way; sampled maxima are lower bounds, and
the least of many is biased low.

For each error budget (0.005, 0.002, 0.001, 0.0005 S) the oracle's best is the smallest
cell whose Open3D error is within the budget and that is not refuted: a sampled error is
a lower bound, so a cell is refuted when meshbits' refinement (compress's certification)
finds a point of one surface farther than the budget from the other and Open3D, asked for
that point's distance on its own, agrees (the smaller refuted cell is printed beside it);
for each size budget (4, 16, 64 kB) the
cell of least Open3D error within it. Printed per run: compress's bytes and error, the
oracle's, the excess, the passes, whether Open3D confirms "met", and Draco on the full
mesh at 11 and 14 bits; then the summary against the targets, and one figure per mesh
(bytes against error, log-log) in benches/out/frontier/.

    python benches/frontier.py [--meshes bunny horse ...] [--fresh] [--dragon] [--oracle-only]

The oracle grids are cached in benches/out/frontier/*.json (``--fresh`` rebuilds them).
"""

from __future__ import annotations

import argparse
import gzip
import json
import math
import statistics
import time
from pathlib import Path

import numpy as np
import trimesh
from _shared import SHARED, import_refs

import meshbits
from meshbits.codecs import encode_draco
from meshbits.compress import MIN_SAMPLES
from meshbits.constants import CERTIFY_TOLERANCE
from meshbits.formats.drc import decode_draco
from meshbits.hausdorff import default_samples
from meshbits.quantize import cube_grid

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "benches" / "out" / "frontier"

#: The six of the first runs, then (issue 33) a dense scan (the Stanford dragon at its
#: second resolution, 202,520 faces: above BASE_FACES, so the large-mesh search), a
#: scanned bust and coarse scans and models (the bunny and the dragon decimated by
#: Stanford, spot, the cow, the teapot, Suzanne): 15 meshes of shared/meshes.
MESHES = [
    "bunny",
    "horse",
    "hand",
    "fandisk",
    "armadillo",
    "nefertiti",
    "dragon_res2",
    "max-planck",
    "bunny_res3",
    "bunny_res4",
    "dragon_res4",
    "spot",
    "cow",
    "teapot",
    "suzanne",
]
ERROR_BUDGETS = [0.005, 0.002, 0.001, 0.0005]
SIZE_BUDGETS_KB = [4, 16, 64]
BITS = range(6, 21)
LADDER = 20
OPEN3D_SAMPLES = 300_000
#: Relative width of the certified interval that places a size budget's error: the
#: Hausdorff distance of compress's output and of the oracle's cells is known within 1%.
TIGHT = 0.01
#: A size budget gets no certified oracle when this many of its least-error cells do not
#: converge within the refinement budget (errors of about 1e-5 S and below).
MAX_UNSETTLED = 5
SIMPLIFIERS = {
    "meshopt": {"method": "meshopt"},
    "meshopt-update": {"method": "meshopt", "update_positions": True},
    "fast-simplification": {"method": "fast-simplification"},
}


def load(name: str) -> tuple[np.ndarray, np.ndarray]:
    for path in (SHARED / "meshes" / f"{name}.ply", SHARED / "meshes" / f"{name}.ply.gz"):
        if path.exists():
            source = gzip.open(path) if path.suffix == ".gz" else path
            mesh = trimesh.load(source, file_type="ply", process=False, force="mesh")
            return np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces)
    raise FileNotFoundError(name)


def _referenced(mesh: tuple) -> tuple[np.ndarray, np.ndarray]:
    vertices, faces = np.asarray(mesh[0]), np.asarray(mesh[1])
    used, inverse = np.unique(faces.reshape(-1), return_inverse=True)
    return vertices[used], inverse.reshape(-1, 3)


def open3d_error(original: tuple[np.ndarray, np.ndarray], decoded: tuple) -> float:
    """The independent measurement (length): Open3D, every vertex plus 300,000 area
    samples of each mesh. Unreferenced vertices are left out first: they are not on
    the surface (the bunny has 1,113, which Draco drops)."""
    hausdorff_open3d = import_refs().hausdorff_open3d

    a, b = _referenced(original), _referenced(decoded)
    return hausdorff_open3d(*a, *b, samples=OPEN3D_SAMPLES, seed=1)


def open3d_point_distance(mesh: tuple, point: np.ndarray) -> float:
    """Open3D's distance (length) from one point to a mesh (float32 RaycastingScene)."""
    import open3d as o3d

    vertices, faces = _referenced(mesh)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(
        o3d.core.Tensor(np.asarray(vertices, dtype=np.float32)),
        o3d.core.Tensor(np.asarray(faces, dtype=np.uint32)),
    )
    query = o3d.core.Tensor(np.asarray(point, dtype=np.float32).reshape(1, 3))
    return float(scene.compute_distance(query).numpy()[0])


class Oracle:
    """The grid of cells of one mesh, cached in benches/out/frontier/<mesh>.json.

    Every cell is measured with meshbits (its default sampling, the original sampled
    once); the cells that decide a budget are measured again with Open3D, which decides:
    for an error budget, cells in order of bytes until Open3D confirms one within it;
    for a size budget, every cell within it whose meshbits error is within 10% of the
    least."""

    def __init__(self, name: str, mesh: tuple[np.ndarray, np.ndarray], fresh: bool) -> None:
        self.name, self.mesh = name, mesh
        self.cache = OUT / f"{name}.json"
        self.levels: dict[tuple[str, int], tuple[np.ndarray, np.ndarray]] = {}
        self.reference: meshbits.Reference | None = None
        if self.cache.exists() and not fresh:
            data = json.loads(self.cache.read_text())
        else:
            data = self._grid()
        self.grid_size = data["grid_size"]
        self.vertices = data["vertices"]
        self.cells = data["cells"]

    def _grid(self) -> dict:
        vertices, faces = self.mesh
        used = len(np.unique(faces))
        lo, hi = vertices.min(axis=0), vertices.max(axis=0)
        grid_size = float((hi - lo).max())
        reference = meshbits.Reference(self.mesh)
        counts = sorted({round(c) for c in np.geomspace(60, used, LADDER)})
        cells = []
        start = time.perf_counter()
        for simplifier in SIMPLIFIERS:
            for count in counts:
                level = self._level(simplifier, count)
                origin, side = cube_grid(
                    np.minimum(lo, level[0].min(axis=0)), np.maximum(hi, level[0].max(axis=0))
                )
                for bits in BITS:
                    encoded = encode_draco(level, bits, origin=origin, grid_size=side)
                    decoded = decode_draco(encoded.data)
                    cells.append(
                        {
                            "simplifier": simplifier,
                            "target": count,
                            "vertices": len(decoded[0]),
                            "bits": bits,
                            "bytes": encoded.size_bytes,
                            "error": reference.hausdorff(decoded).distance / grid_size,
                        }
                    )
            print(f"  {self.name}: {simplifier} ladder ({time.perf_counter() - start:.0f} s)")
        data = {"mesh": self.name, "grid_size": grid_size, "vertices": used, "cells": cells}
        self._save(data)
        return data

    def _save(self, data: dict | None = None) -> None:
        OUT.mkdir(parents=True, exist_ok=True)
        data = data or {
            "mesh": self.name,
            "grid_size": self.grid_size,
            "vertices": self.vertices,
            "cells": self.cells,
        }
        self.cache.write_text(json.dumps(data))

    def _level(self, simplifier: str, count: int) -> tuple[np.ndarray, np.ndarray]:
        key = (simplifier, count)
        if key not in self.levels:
            used = len(np.unique(self.mesh[1]))
            if count >= used:
                self.levels[key] = self.mesh
            else:
                self.levels[key] = meshbits.simplify(
                    self.mesh, count, **SIMPLIFIERS[simplifier]
                ).mesh
        return self.levels[key]

    def _decoded(self, cell: dict) -> tuple[np.ndarray, np.ndarray]:
        level = self._level(cell["simplifier"], cell["target"])
        lo, hi = self.mesh[0].min(axis=0), self.mesh[0].max(axis=0)
        origin, side = cube_grid(
            np.minimum(lo, level[0].min(axis=0)), np.maximum(hi, level[0].max(axis=0))
        )
        encoded = encode_draco(level, cell["bits"], origin=origin, grid_size=side)
        return decode_draco(encoded.data)

    def independent(self, cell: dict) -> float:
        """The cell's Open3D error / S, computed once."""
        if "open3d" not in cell:
            cell["open3d"] = open3d_error(self.mesh, self._decoded(cell)) / self.grid_size
            self._save()
        return cell["open3d"]

    def certified(self, cell: dict, budget: float) -> float:
        """A certified upper bound on the cell's error / S, as compress certifies its
        answers (meshbits, its samples, refined until within the budget or within
        CERTIFY_TOLERANCE of it), computed once per budget."""
        bounds = cell.setdefault("certified", {})
        key = str(budget)
        if key not in bounds:
            bounds[key] = float(self._certify(cell, budget).upper) / self.grid_size
            self._save()
        return bounds[key]

    def _certify(self, cell: dict, budget: float) -> meshbits.Hausdorff:
        """The cell measured as compress certifies: refined until the bound decides the
        budget (/ S) or is within CERTIFY_TOLERANCE of it."""
        absolute = budget * self.grid_size
        return self._reference_tree().hausdorff(
            self._decoded(cell),
            bounds=True,
            tolerance=CERTIFY_TOLERANCE * absolute,
            threshold=absolute,
        )

    def _reference_tree(self) -> meshbits.Reference:
        if self.reference is None:
            count = max(default_samples(len(self.mesh[1])), MIN_SAMPLES)
            self.reference = meshbits.Reference(self.mesh, samples=count, seed=0)
        return self.reference

    def tight(self, decoded: tuple, sampled: float) -> float | None:
        """The Hausdorff distance / S of ``decoded`` to the original, certified within
        :data:`TIGHT` of the sampled ``sampled`` (/ S): the bound's upper end; None when
        the refinement budget ran out first."""
        h = self._reference_tree().hausdorff(
            decoded, bounds=True, tolerance=TIGHT * sampled * self.grid_size
        )
        converged = h.a_to_b.converged and h.b_to_a.converged
        return float(h.upper) / self.grid_size if converged else None

    def tight_cell(self, cell: dict) -> float:
        """:meth:`tight` of a cell, computed once (infinite when it did not converge)."""
        if "tight_upper" not in cell:
            cell["tight_upper"] = self.tight(self._decoded(cell), cell["error"])
            self._save()
        return math.inf if cell["tight_upper"] is None else cell["tight_upper"]

    def best_for_size_certified(self, limit: float) -> dict | None:
        """The cell of least certified error within the size. A cell's sampled error is
        a lower bound of its distance, so cells are certified in order of it until the
        next one's is above the least certified bound found; None after
        :data:`MAX_UNSETTLED` cells whose bound did not converge."""
        best: dict | None = None
        unsettled = 0
        fitting = [c for c in self.cells if c["bytes"] <= limit]
        for cell in sorted(fitting, key=lambda c: c["error"]):
            if best is not None and cell["error"] >= self.tight_cell(best):
                break
            if math.isinf(self.tight_cell(cell)):
                unsettled += 1
                if unsettled >= MAX_UNSETTLED:
                    return None
            elif best is None or self.tight_cell(cell) < self.tight_cell(best):
                best = cell
        return best

    def best_for_error_certified(self, budget: float) -> dict | None:
        """The smallest cell certified within the budget (and confirmed by Open3D): the
        oracle on compress's own terms, which certifies what it returns."""
        for cell in sorted(self.cells, key=lambda c: c["bytes"]):
            if cell["error"] <= budget and self.certified(cell, budget) <= budget:
                if self.independent(cell) <= budget:
                    return cell
        return None

    def best_for_error(self, budget: float) -> tuple[dict | None, dict | None]:
        """The smallest cell that Open3D finds within the budget and that is not refuted
        (:meth:`refuted`), and the smallest cell Open3D finds within it (the two differ
        when that one is refuted)."""
        first = None
        for cell in sorted(self.cells, key=lambda c: c["bytes"]):
            if cell["error"] <= 1.1 * budget and self.independent(cell) <= budget:
                first = first or cell
                if self.refuted(cell, budget) is None:
                    return cell, first
        return None, first

    def refuted(self, cell: dict, budget: float) -> float | None:
        """A sampled error is a lower bound: a cell Open3D finds within the budget may
        not be. meshbits' refinement (as compress certifies) looks for a surface point
        farther than the budget from the other mesh; when it finds one, Open3D measures
        that point's distance on its own, and a distance over the budget (returned, / S)
        refutes the cell. None when no such point was found or Open3D does not confirm
        it. Computed once per budget."""
        witnesses = cell.setdefault("refuted", {})
        key = str(budget)
        if key not in witnesses:
            h = self._certify(cell, budget)
            witnesses[key] = None
            if h.distance > budget * self.grid_size:
                # a_to_b: a point of the original, measured to the decoded cell.
                forward = h.a_to_b.max >= h.b_to_a.max
                d = h.a_to_b if forward else h.b_to_a
                target = self._decoded(cell) if forward else self.mesh
                distance = open3d_point_distance(target, d.argmax) / self.grid_size
                if distance > budget:
                    witnesses[key] = distance
            self._save()
        return witnesses[key]

    def best_for_size(self, limit: float) -> dict | None:
        """The cell of least Open3D error within the size."""
        fitting = [c for c in self.cells if c["bytes"] <= limit]
        if not fitting:
            return None
        least = min(c["error"] for c in fitting)
        close = [c for c in fitting if c["error"] <= 1.1 * least]
        return min(close, key=self.independent)


def frontier(cells: list[dict]) -> list[tuple[int, float]]:
    """The cells no other cell beats in both bytes and error, by bytes."""
    out: list[tuple[int, float]] = []
    for cell in sorted(cells, key=lambda c: (c["bytes"], c["error"])):
        if not out or cell["error"] < out[-1][1]:
            out.append((cell["bytes"], cell["error"]))
    return out


def full_mesh_draco(oracle: Oracle, bits: int) -> dict:
    """The original encoded at ``bits``, measured with Open3D."""
    cell = next(
        c
        for c in oracle.cells
        if c["target"] >= oracle.vertices and c["bits"] == bits and c["simplifier"] == "meshopt"
    )
    oracle.independent(cell)
    return cell


def evaluate(name: str, mesh: tuple, oracle: Oracle) -> list[dict]:
    """compress at every budget, measured like the oracle's decisive cells."""
    rows = []
    for kind, budgets in (("error", ERROR_BUDGETS), ("size", SIZE_BUDGETS_KB)):
        for budget in budgets:
            start = time.perf_counter()
            if kind == "error":
                result = meshbits.compress(mesh, error=budget, relative=True)
            else:
                result = meshbits.compress(mesh, size=8 * 1000 * budget)
            seconds = time.perf_counter() - start
            decoded = decode_draco(result.data)
            error = open3d_error(mesh, decoded) / oracle.grid_size
            row = {
                "mesh": name,
                "kind": kind,
                "budget": budget,
                "met": result.met,
                "bits": result.bits,
                "vertices": len(result.vertices),
                "source": result.source,
                "bytes": result.size_bytes,
                "error": error,
                "own_error": result.error / oracle.grid_size,
                "passes": len(result.iterations),
                "seconds": seconds,
            }
            if kind == "error":
                best, first = oracle.best_for_error(budget)
                row["confirmed"] = error <= budget
                row["oracle_bytes"] = best["bytes"] if best else None
                # The smallest cell Open3D's samples find within the budget, when a point
                # farther than the budget refutes it.
                row["oracle_refuted_bytes"] = first["bytes"] if first is not best else None
                row["excess_over_refuted"] = (
                    result.size_bytes / first["bytes"] - 1 if first is not best else None
                )
                row["excess"] = result.size_bytes / best["bytes"] - 1 if best else None
                certified = oracle.best_for_error_certified(budget)
                row["oracle_certified_bytes"] = certified["bytes"] if certified else None
                row["excess_certified"] = (
                    result.size_bytes / certified["bytes"] - 1 if certified else None
                )
                for bits in (11, 14):
                    full = full_mesh_draco(oracle, bits)
                    meets = full["open3d"] <= budget
                    row[f"draco{bits}"] = full["bytes"] if meets else None
            else:
                limit = 1000 * budget
                best = oracle.best_for_size(limit)
                row["confirmed"] = result.size_bytes <= limit
                row["oracle_error"] = best["open3d"] if best else None
                row["excess"] = error / best["open3d"] - 1 if best else None
                certified = oracle.best_for_size_certified(limit)
                own = oracle.tight(decoded, result.error / oracle.grid_size)
                row["certified_error"] = own
                row["oracle_certified_error"] = oracle.tight_cell(certified) if certified else None
                row["excess_certified"] = (
                    own / oracle.tight_cell(certified) - 1 if certified and own else None
                )
            row["oracle_reaches"] = best is not None
            rows.append(row)
            print(
                f"  {name} {kind} {budget}: B={row['bits']} V={row['vertices']} "
                f"({row['source']}) {row['bytes']} bytes, error {error:.3g} S "
                f"(own {row['own_error']:.3g}), excess {_pct(row['excess'])}, "
                f"{row['passes']} passes, {seconds:.1f} s, confirmed {row['confirmed']}"
            )
    return rows


def _pct(x: float | None) -> str:
    return "-" if x is None else f"{100 * x:+.1f}%"


def figure(name: str, oracle: Oracle, rows: list[dict]) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 5), layout="constrained")
    cells = oracle.cells
    ax.scatter(
        [c["bytes"] for c in cells],
        [c["error"] for c in cells],
        s=4,
        color="0.8",
        label="oracle cells (3 simplifiers x 20 V x B 6..20)",
    )
    f = frontier(cells)
    ax.step(*zip(*f, strict=True), where="post", color="k", lw=1.2, label="oracle frontier")
    for bits, style in ((14, "--"), (11, ":")):
        fixed = frontier([c for c in cells if c["bits"] == bits])
        ax.plot(*zip(*fixed, strict=True), style, color="tab:blue", label=f"best V at B = {bits}")
        full = full_mesh_draco(oracle, bits)
        ax.plot(full["bytes"], full["error"], "s", color="tab:blue", mfc="none")
        ax.annotate(f"full, {bits} bits", (full["bytes"], full["error"]), fontsize=7)
    ax.plot(
        [r["bytes"] for r in rows],
        [r["error"] for r in rows],
        "o",
        color="tab:red",
        label="compress (error and size budgets)",
    )
    for budget in ERROR_BUDGETS:
        ax.axhline(budget, color="tab:red", lw=0.5, alpha=0.4)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("Draco file size (bytes)")
    ax.set_ylabel("Hausdorff error / S (cells: meshbits; compress: Open3D)")
    ax.set_title(f"{name}: compress against the brute-force oracle")
    ax.legend(fontsize=7)
    path = OUT / f"{name}.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _refuted(row: dict) -> str:
    if row.get("oracle_refuted_bytes") is None:
        return "-"
    return f"{row['oracle_refuted_bytes']} ({_pct(row['excess_over_refuted'])})"


def summary(rows: list[dict]) -> None:
    print(
        "\n| mesh | budget | compress (B, V) | bytes | error / S | oracle | excess "
        "| refuted smaller cell (excess) | certified oracle | excess | passes | s |"
    )
    print("|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        unit = "S" if r["kind"] == "error" else "kB"
        oracle_value = (
            r.get("oracle_bytes") if r["kind"] == "error" else f"{r.get('oracle_error'):.3g}"
        )
        certified = (
            r.get("oracle_certified_bytes")
            if r["kind"] == "error"
            else f"{r['oracle_certified_error']:.3g}"
            if r.get("oracle_certified_error") is not None
            else None
        )
        print(
            f"| {r['mesh']} | {r['budget']} {unit} | {r['bits']}, {r['vertices']} | "
            f"{r['bytes']} | {r['error']:.3g} | {oracle_value} | {_pct(r['excess'])} | "
            f"{_refuted(r)} | "
            f"{'-' if certified is None else certified} | {_pct(r.get('excess_certified'))} | "
            f"{r['passes']} | {r['seconds']:.1f} |"
        )
    excess = [r["excess"] for r in rows if r["excess"] is not None]
    print(
        f"\nexcess over the oracle: median {_pct(statistics.median(excess))}, "
        f"worst {_pct(max(excess))} ({len(excess)} runs)"
    )
    refuted = [r for r in rows if r.get("oracle_refuted_bytes") is not None]
    raw = [
        r["excess_over_refuted"] if r.get("oracle_refuted_bytes") is not None else r["excess"]
        for r in rows
        if r["excess"] is not None
    ]
    print(
        f"error budgets whose smallest Open3D-passing cell was refuted: {len(refuted)}; "
        f"against those cells: median {_pct(statistics.median(raw))}, worst {_pct(max(raw))}"
    )
    certified = [r["excess_certified"] for r in rows if r.get("excess_certified") is not None]
    if certified:
        print(
            f"excess over the certified oracle: median "
            f"{_pct(statistics.median(certified))}, worst {_pct(max(certified))}"
        )
        for kind in ("error", "size"):
            part = [r["excess_certified"] for r in rows if r["kind"] == kind]
            part = [x for x in part if x is not None]
            if part:
                print(
                    f"  {kind} budgets: median {_pct(statistics.median(part))}, "
                    f"worst {_pct(max(part))}"
                )
    for kind in ("error", "size"):
        part = [r["excess"] for r in rows if r["kind"] == kind and r["excess"] is not None]
        if part:
            print(
                f"  {kind} budgets: median {_pct(statistics.median(part))}, worst {_pct(max(part))}"
            )
    print(
        f"passes: median {statistics.median(r['passes'] for r in rows)}, "
        f"max {max(r['passes'] for r in rows)}"
    )
    missed = [r for r in rows if r["oracle_reaches"] and not r["met"]]
    print(f"budgets the oracle reaches but compress missed: {len(missed)}")
    unconfirmed = [r for r in rows if r["met"] and not r["confirmed"]]
    print(
        f"'met' not confirmed by Open3D: {len(unconfirmed)} "
        + " ".join(f"{r['mesh']}@{r['budget']}" for r in unconfirmed)
    )
    larger = [
        (r, bits)
        for r in rows
        if r["kind"] == "error"
        for bits in (11, 14)
        if r.get(f"draco{bits}") is not None and r["bytes"] > r[f"draco{bits}"]
    ]
    print(
        f"larger than Draco on the full mesh at 11/14 bits where that meets the budget: "
        f"{len(larger)} " + " ".join(f"{r['mesh']}@{r['budget']}/{b}" for r, b in larger)
    )
    by_mesh: dict[str, list[dict]] = {}
    for r in rows:
        if r["kind"] == "error":
            by_mesh.setdefault(r["mesh"], []).append(r)
    broken = [
        m
        for m, rs in by_mesh.items()
        for a, b in zip(
            sorted(rs, key=lambda r: r["budget"]),
            sorted(rs, key=lambda r: r["budget"])[1:],
            strict=False,
        )
        if b["bytes"] > a["bytes"]
    ]
    print(f"meshes where a looser error budget gave a bigger file: {sorted(set(broken))}")


def simplifiers(oracles: list[Oracle]) -> None:
    """Which simplifier's cells make the smallest file within each error budget
    (meshbits's measurement of every cell): the basis of compress's "auto"."""
    print("\n| mesh | budget (S) | " + " | ".join(SIMPLIFIERS) + " |")
    print("|---|---:|" + "---:|" * len(SIMPLIFIERS))
    wins = dict.fromkeys(SIMPLIFIERS, 0)
    for oracle in oracles:
        for budget in ERROR_BUDGETS:
            best = {}
            for name in SIMPLIFIERS:
                ok = [
                    c["bytes"]
                    for c in oracle.cells
                    if c["simplifier"] == name and c["error"] <= budget
                ]
                best[name] = min(ok) if ok else None
            least = min(v for v in best.values() if v is not None)
            for name, value in best.items():
                wins[name] += value == least
            cells = " | ".join("-" if v is None else f"{v}" for v in best.values())
            print(f"| {oracle.name} | {budget} | {cells} |")
    print("smallest (ties count for each): " + ", ".join(f"{k} {v}" for k, v in wins.items()))


def dragon() -> None:
    mesh = load("dragon")
    for _ in range(2):
        start = time.perf_counter()
        result = meshbits.compress(mesh, error=0.001, relative=True)
        seconds = time.perf_counter() - start
        print(
            f"dragon, 0.001 S: {seconds:.2f} s, met {result.met}, B = {result.bits}, "
            f"V = {len(result.vertices)}, {result.size_bytes} bytes, {len(result.iterations)} "
            f"passes; by phase: " + ", ".join(f"{k} {v:.2f}" for k, v in result.seconds.items())
        )
    dragon_floor(mesh, result)


def dragon_floor(mesh: tuple, result: meshbits.CompressResult) -> None:
    """What one pass that planned perfectly would cost: each step compress cannot skip,
    timed once on compress's own answer (the original's BVH and samples, one
    simplification of the whole mesh, one sampled measurement, the certification)."""
    from meshbits.mesh import as_mesh

    original = as_mesh(mesh)
    count = max(default_samples(len(original[1])), MIN_SAMPLES)
    answer = (np.asarray(result.vertices), np.asarray(result.faces))
    steps: dict[str, float] = {}

    def timed(step: str, run):
        start = time.perf_counter()
        out = run()
        steps[step] = time.perf_counter() - start
        return out

    reference = timed("BVH and samples", lambda: meshbits.Reference(original, samples=count))
    timed(
        "one simplification",
        lambda: meshbits.simplify(original, method="meshopt", vertices=len(result.vertices)),
    )
    timed(
        "sampled measurement",
        lambda: reference.hausdorff(answer, samples=count, check=False),
    )
    bound = timed(
        "certification",
        lambda: reference.hausdorff(
            answer,
            samples=count,
            check=False,
            bounds=True,
            tolerance=CERTIFY_TOLERANCE * result.budget,
            threshold=result.budget,
        ),
    )
    print(
        f"dragon, one ideal pass: {sum(steps.values()):.2f} s; "
        + ", ".join(f"{k} {v:.2f}" for k, v in steps.items())
        + f"; certified {bound.upper <= result.budget}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--meshes", nargs="+", default=MESHES)
    parser.add_argument("--fresh", action="store_true", help="rebuild the oracle grids")
    parser.add_argument("--dragon", action="store_true", help="also time the dragon")
    parser.add_argument("--oracle-only", action="store_true")
    args = parser.parse_args()
    rows = []
    oracles = []
    for name in args.meshes:
        mesh = load(name)
        grid = Oracle(name, mesh, args.fresh)
        oracles.append(grid)
        if args.oracle_only:
            continue
        mesh_rows = evaluate(name, mesh, grid)
        figure(name, grid, mesh_rows)
        rows += mesh_rows
    simplifiers(oracles)
    if rows:
        OUT.mkdir(parents=True, exist_ok=True)
        (OUT / "runs.json").write_text(json.dumps(rows, indent=1))
        summary(rows)
    if args.dragon:
        dragon()


if __name__ == "__main__":
    main()
