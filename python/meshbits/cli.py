"""The ``meshbits`` command line.

Every subcommand prints a short human-readable report, or one JSON object with
``--json``. Exit codes: 0 success, 1 a budget could not be met, 2 bad input (a one-line
message on stderr, no traceback).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from .complexity import shape_complexity
from .constants import ESTIMATORS, HAUSDORFF_REFINE_BUDGET
from .hausdorff import hausdorff
from .io import example_mesh_path, load_mesh

__all__ = ["main"]

EXIT_OK, EXIT_UNMET, EXIT_BAD_INPUT = 0, 1, 2


class UserError(Exception):
    """A problem with the command's input, reported in one line with exit code 2."""


def _print_json(payload: dict[str, Any]) -> None:
    print(json.dumps(payload, indent=2, allow_nan=True))


def _print_table(title: str, rows: Sequence[tuple[str, Any]]) -> None:
    print(title)
    width = max(len(name) for name, _ in rows)
    for name, value in rows:
        if isinstance(value, float):
            value = f"{value:.6g}"
        print(f"  {name:<{width}}  {value}")


def _complexity_report(path: Path, args: argparse.Namespace) -> dict[str, Any]:
    vertices, faces = load_mesh(path)
    result = shape_complexity(
        vertices, faces, estimator=args.estimator, merge_vertices=not args.no_merge
    )
    return {"mesh": str(path), "vertices": len(vertices), "faces": len(faces), **result.to_dict()}


def _add_k(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("k", help="shape complexity K of a mesh (paper Sec. 4)")
    p.add_argument("mesh", type=Path, help="mesh file (OBJ, PLY, STL, OFF, GLB, ...)")
    p.add_argument("--estimator", choices=ESTIMATORS, default="circumsphere")
    p.add_argument("--no-merge", action="store_true", help="do not weld identical vertices")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(run=_run_k)


def _run_k(args: argparse.Namespace) -> int:
    report = _complexity_report(args.mesh, args)
    if args.json:
        _print_json(report)
        return EXIT_OK
    _print_table(
        f"{report['mesh']}: {report['vertices']} vertices, {report['faces']} faces",
        [
            ("K (grid, /S)", report["k"]),
            ("K (area, /sqrt(A))", report["k_area"]),
            ("K raw (length)", report["k_raw"]),
            ("grid size S (length)", report["grid_size"]),
            ("area (length^2)", report["area"]),
            ("estimator", report["estimator"]),
            ("edges", report["edges"]),
            ("  interior", report["interior_edges"]),
            ("  boundary (skipped)", report["boundary_edges"]),
            ("  non-manifold (skipped)", report["nonmanifold_edges"]),
            ("  flat", report["flat_edges"]),
            ("  ill-conditioned", report["ill_conditioned_edges"]),
            ("  degenerate", report["degenerate_edges"]),
            ("merged vertices", report["merged_vertices"]),
            ("degenerate faces (skipped)", report["degenerate_faces"]),
        ],
    )
    return EXIT_OK


def _add_demo(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("demo", help="run meshbits on the example mesh shipped in the package")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(run=_run_demo)


def _run_demo(args: argparse.Namespace) -> int:
    args.mesh = example_mesh_path()
    args.estimator, args.no_merge = "circumsphere", False
    return _run_k(args)


def _add_hausdorff(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "hausdorff",
        help="sampled Hausdorff distance between two meshes (paper Sec. 3.2, the error E)",
    )
    p.add_argument("a", type=Path, help="first mesh file")
    p.add_argument("b", type=Path, help="second mesh file")
    p.add_argument(
        "--samples",
        type=int,
        default=None,
        help="area samples per mesh, on top of the vertices "
        "(default: 10 per face, clamped to [10000, 1000000])",
    )
    p.add_argument("--seed", type=int, default=0, help="seed of the samples (default 0)")
    p.add_argument(
        "--tolerance",
        type=float,
        default=None,
        help="refine until the certified upper bound is within this length of the "
        "sampled value",
    )
    p.add_argument("--bounds", action="store_true", help="also report a certified upper bound")
    p.add_argument(
        "--max-only",
        action="store_true",
        help="compute the maximum only (faster; no mean, RMS or percentiles)",
    )
    p.add_argument(
        "--refine-budget",
        type=int,
        default=HAUSDORFF_REFINE_BUDGET,
        help="largest number of refinement points per direction",
    )
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(run=_run_hausdorff)


def _progress(message: str) -> None:
    print(f"meshbits hausdorff: {message}", file=sys.stderr, flush=True)


def _run_hausdorff(args: argparse.Namespace) -> int:
    meshes = {}
    for name in ("a", "b"):
        path = getattr(args, name)
        if not args.quiet:
            _progress(f"reading {path}")
        meshes[name] = load_mesh(path)
    result = hausdorff(
        meshes["a"],
        meshes["b"],
        samples=args.samples,
        seed=args.seed,
        statistics=not args.max_only,
        bounds=args.bounds,
        tolerance=args.tolerance,
        refine_budget=args.refine_budget,
        progress=None if args.quiet else _progress,
    )
    report = {"a": str(args.a), "b": str(args.b), **result.to_dict()}
    if args.json:
        _print_json(report)
        return EXIT_OK
    rows: list[tuple[str, Any]] = [("Hausdorff distance (sampled)", result.distance)]
    if result.upper is not None:
        rows.append(("certified upper bound", result.upper))
    for label, d in (("A -> B", result.a_to_b), ("B -> A", result.b_to_a)):
        rows.append((f"{label} max", d.max))
        if d.mean is not None:
            rows += [
                (f"{label} mean", d.mean),
                (f"{label} rms", d.rms),
                (f"{label} p50 / p95 / p99", f"{d.p50:.6g} / {d.p95:.6g} / {d.p99:.6g}"),
            ]
        if d.upper is not None:
            rows.append((f"{label} upper", d.upper))
        if d.converged is not None:
            rows.append((f"{label} converged", d.converged))
        rows.append((f"{label} samples", d.n_samples))
        rows.append((f"{label} argmax", "(" + ", ".join(f"{x:.6g}" for x in d.argmax) + ")"))
    _print_table(f"{args.a} vs {args.b} (seed {result.seed}; lengths in the files' unit)", rows)
    return EXIT_OK


_COMMANDS: tuple[Callable[[argparse._SubParsersAction], None], ...] = (
    _add_k,
    _add_demo,
    _add_hausdorff,
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="meshbits",
        description="How many vertices, and how many bits per coordinate, should a mesh keep?",
    )
    sub = parser.add_subparsers(dest="command", required=True)
    for add in _COMMANDS:
        add(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``meshbits`` program; returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.run(args))
    except (UserError, ValueError, TypeError, FileNotFoundError, OSError) as err:
        print(f"meshbits {args.command}: error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT


if __name__ == "__main__":
    sys.exit(main())
