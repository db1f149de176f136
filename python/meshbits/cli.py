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
from .constants import DUPLICATES, ESTIMATORS, GRIDS
from .io import example_mesh_path, load_mesh, save_mesh
from .quantize import cluster

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


def _add_quantize(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "quantize",
        help="quantize a mesh to B bits per coordinate and cluster its vertices (Sec. 1.1)",
    )
    p.add_argument("mesh", type=Path, help="mesh file (OBJ, PLY, STL, OFF, GLB, ...)")
    p.add_argument("--bits", type=int, required=True, help="bits per coordinate, 1 to 32")
    p.add_argument("-o", "--output", type=Path, help="write the clustered mesh (PLY, OBJ, ...)")
    p.add_argument("--grid", choices=GRIDS, default="cube", help="one step (cube) or one per axis")
    p.add_argument(
        "--duplicates",
        choices=DUPLICATES,
        default="keep",
        help="drop repeated faces: no (keep), same winding (oriented), any order (any)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(run=_run_quantize)


def _run_quantize(args: argparse.Namespace) -> int:
    vertices, faces = load_mesh(args.mesh)
    result = cluster(vertices, faces, args.bits, grid=args.grid, duplicates=args.duplicates)
    if args.output is not None:
        if result.output_faces == 0:
            raise UserError(
                f"no face survives clustering at {args.bits} bits; nothing written to {args.output}"
            )
        save_mesh(args.output, result.vertices, result.faces)
    report = {
        "mesh": str(args.mesh),
        "output": None if args.output is None else str(args.output),
        **result.to_dict(),
    }
    if args.json:
        _print_json(report)
        return EXIT_OK
    _print_table(
        f"{report['mesh']}: {result.input_vertices} vertices, {result.input_faces} faces, "
        f"{result.bits}-bit {result.grid} grid",
        [
            ("vertices kept", result.output_vertices),
            ("  merged", result.merged_vertices),
            ("  unreferenced (dropped)", result.unreferenced_vertices),
            ("faces kept", result.output_faces),
            ("  degenerate (dropped)", result.degenerate_faces),
            ("  duplicate (dropped)", result.duplicate_faces),
            ("grid size S (length)", result.grid_size),
            ("step (length)", " ".join(f"{s:.6g}" for s in result.step)),
            ("bound 0.5|step| (length)", result.bound),
            ("max displacement (length)", result.max_displacement),
            ("written to", report["output"] or "-"),
        ],
    )
    return EXIT_OK


_COMMANDS: tuple[Callable[[argparse._SubParsersAction], None], ...] = (
    _add_k,
    _add_demo,
    _add_quantize,
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
