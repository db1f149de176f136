"""``meshbits hausdorff``: the sampled (and optionally certified) Hausdorff distance
between two meshes, and a mesh coloured by each vertex's distance."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

from ..constants import BOUNDS_RELATIVE_TOLERANCE, HAUSDORFF_REFINE_BUDGET
from ..formats import load_mesh
from ..hausdorff import ClosestPoints, hausdorff
from ..plot import error_map
from ..units import length_unit_of
from .common import (
    EXIT_OK,
    UserError,
    count,
    input_file,
    need_matplotlib,
    output_file,
    positive_number,
    print_json,
    print_table,
)


def add_hausdorff(sub: argparse._SubParsersAction) -> None:
    """Add the ``hausdorff`` subcommand to ``sub``."""
    p = sub.add_parser(
        "hausdorff",
        help="sampled Hausdorff distance between two meshes (paper Sec. 3.2, the error E)",
    )
    p.add_argument("a", type=Path, help="first mesh file")
    p.add_argument("b", type=Path, help="second mesh file")
    p.add_argument(
        "--samples",
        type=count(0),
        default=None,
        help="area samples per mesh, on top of the vertices "
        "(default: 10 per face, clamped to [10000, 1000000])",
    )
    p.add_argument("--seed", type=count(0), default=0, help="seed of the samples (default 0)")
    p.add_argument(
        "--tolerance",
        type=positive_number,
        default=None,
        help="refine until the certified upper bound is within this length of the sampled value",
    )
    p.add_argument(
        "--bounds",
        action="store_true",
        help="also report a certified upper bound, refined until each direction's is within "
        f"{100 * BOUNDS_RELATIVE_TOLERANCE:g}%% of its sampled maximum (or within --tolerance)",
    )
    p.add_argument(
        "--max-only",
        action="store_true",
        help="compute the maximum only (faster; no mean, RMS or percentiles)",
    )
    p.add_argument(
        "--refine-budget",
        type=count(0),
        default=HAUSDORFF_REFINE_BUDGET,
        help="largest number of refinement points per direction",
    )
    p.add_argument(
        "--colors",
        type=Path,
        default=None,
        metavar="OUT.ply",
        help="also write A as a PLY coloured by each vertex's distance to B "
        "(and OUT_colorbar.png; needs matplotlib)",
    )
    p.add_argument(
        "--vmax",
        type=positive_number,
        default=None,
        help="distance of the top colour (default: largest)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(run=_run_hausdorff)


def _progress(message: object) -> None:
    """A progress line on stderr."""
    print(f"meshbits hausdorff: {message}", file=sys.stderr, flush=True)


def _run_hausdorff(args: argparse.Namespace) -> int:
    """Run ``meshbits hausdorff``; returns the exit code."""
    output_file(args.colors, args.a, args.b)
    if args.colors is not None and args.colors.suffix.lower() != ".ply":
        raise UserError(
            f"cannot write {args.colors}: --colors writes a PLY with vertex colours; name it .ply"
        )
    if args.colors is not None:
        need_matplotlib("--colors")
        output_file(args.colors.with_name(args.colors.stem + "_colorbar.png"))
    for path in (args.a, args.b):
        input_file(path)
    meshes = {name: load_mesh(getattr(args, name)) for name in ("a", "b")}
    if not args.quiet:
        # After both reads: a file that cannot be read gets its one error line only.
        for name, (vertices, faces) in meshes.items():
            _progress(f"read {getattr(args, name)}: {len(vertices)} vertices, {len(faces)} faces")
    result = hausdorff(
        meshes["a"],
        meshes["b"],
        samples=args.samples,
        seed=args.seed,
        statistics=not args.max_only,
        bounds=args.bounds,
        tolerance=args.tolerance,
        relative_tolerance=(
            BOUNDS_RELATIVE_TOLERANCE if args.bounds and args.tolerance is None else None
        ),
        refine_budget=args.refine_budget,
        progress=None if args.quiet else _progress,
    )
    report = {"a": str(args.a), "b": str(args.b), **result.to_dict()}
    if args.colors is not None:
        report["colors"] = _write_colors(meshes["a"], meshes["b"], args)
    # A file without units measured against glTF is taken in meters, glTF's unit.
    gltf = [p for p in (args.a, args.b) if length_unit_of(p) == "m"]
    if args.json:
        print_json(report, gltf[0] if gltf else args.a)
        return EXIT_OK
    rows: list[tuple[str, Any]] = [("Hausdorff distance (sampled)", result.distance)]
    if result.upper is not None:
        rows.append(("certified upper bound", result.upper))
    for label, d in (("A -> B", result.a_to_b), ("B -> A", result.b_to_a)):
        rows.append((f"{label} max", d.max))
        if d.mean is not None:
            rows += [
                (f"{label} mean (area samples)", d.mean),
                (f"{label} rms (area samples)", d.rms),
                (
                    f"{label} p50 / p95 / p99 (area samples)",
                    f"{d.p50:.6g} / {d.p95:.6g} / {d.p99:.6g}",
                ),
            ]
        if d.upper is not None:
            rows.append((f"{label} upper", d.upper))
        if d.converged is not None:
            rows.append((f"{label} converged", d.converged))
        rows.append((f"{label} samples", d.n_samples))
        rows.append((f"{label} argmax", "(" + ", ".join(f"{x:.6g}" for x in d.argmax) + ")"))
    if args.colors is not None:
        rows.append(("coloured mesh (A by distance to B)", report["colors"]["path"]))
        rows.append(("colour bar", report["colors"]["colorbar_path"]))
    unit = "the files' unit"
    if gltf:
        unitless = [str(p) for p in (args.a, args.b) if p not in gltf]
        unit = "m" + (f"; {', '.join(unitless)} names no unit, read as m" if unitless else "")
    print_table(f"{args.a} vs {args.b} (seed {result.seed}; lengths in {unit})", rows)
    return EXIT_OK


def _write_colors(
    a: tuple[Any, Any], b: tuple[Any, Any], args: argparse.Namespace
) -> dict[str, Any]:
    """Colour A's vertices by their exact distance to B (``meshbits plot.error_map``)."""
    distances = ClosestPoints(b).query(a[0]).distances
    bar = args.colors.with_name(args.colors.stem + "_colorbar.png")
    unit = length_unit_of(args.a)
    written = error_map(
        a,
        distances,
        args.colors,
        colorbar_path=bar,
        vmax=args.vmax,
        label=f"distance to {Path(args.b).name} ({unit})",
    )
    if not args.quiet:
        _progress(f"wrote {written.path} and {written.colorbar_path}")
    return {
        "path": str(written.path),
        "colorbar_path": str(written.colorbar_path),
        "vmax": written.vmax,
        "vertex_distance_max": float(distances[np.unique(a[1])].max()),
    }
