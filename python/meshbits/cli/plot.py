"""``meshbits plot``: draw the paper's Fig. 1 for a mesh (needs matplotlib)."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..complexity import shape_complexity
from ..compress import welded_vertex_count
from ..constants import DRACO_ALPHA, DRACO_CONNECTIVITY_BITS, ESTIMATORS
from ..formats import load_mesh
from ..model import plan_for_vertices
from ..plot import error_surface
from .common import (
    EXIT_OK,
    UserError,
    check_size_model,
    input_file,
    need_matplotlib,
    output_file,
    positive_number,
    print_json,
)


def add_plot(sub: argparse._SubParsersAction) -> None:
    """Add the ``plot`` subcommand to ``sub``."""
    p = sub.add_parser(
        "plot",
        help="draw the paper's Fig. 1 for a mesh: iso-error and iso-size curves over (V, B) "
        "with the optimal B(V) (needs matplotlib)",
    )
    p.add_argument("mesh", type=Path, help="mesh file")
    p.add_argument("-o", "--output", type=Path, required=True, help="PNG to write")
    p.add_argument(
        "--alpha",
        type=positive_number,
        default=DRACO_ALPHA,
        help="size model alpha, bits per coordinate bit, in (0, 1] "
        f"(default: fitted to Draco, {DRACO_ALPHA}; the paper's is 1)",
    )
    p.add_argument(
        "--connectivity-bits",
        type=float,
        default=DRACO_CONNECTIVITY_BITS,
        help="size model T, bits per vertex for connectivity, >= 0 "
        f"(default: fitted to Draco, {DRACO_CONNECTIVITY_BITS:g}; the paper's is 4)",
    )
    p.add_argument("--estimator", choices=ESTIMATORS, default="circumsphere", help="estimator of K")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(run=_run_plot)


def _run_plot(args: argparse.Namespace) -> int:
    """Run ``meshbits plot``; returns the exit code."""
    need_matplotlib("meshbits plot")
    check_size_model(args)
    output_file(args.output, args.mesh)
    if args.output.suffix.lower() != ".png":
        raise UserError(f"cannot write {args.output}: plot writes a PNG image; name it .png")
    vertices, faces = load_mesh(input_file(args.mesh))
    k = shape_complexity(vertices, faces, estimator=args.estimator)
    n = welded_vertex_count((vertices, faces))
    plan = plan_for_vertices(
        max(n, 4), k.k, alpha=args.alpha, connectivity_bits=args.connectivity_bits, grid_size=1.0
    )
    low = max(4.0, min(n / 100.0, 100.0))
    high = max(100.0 * n, 10.0 * low)
    error_surface(
        k.k,
        alpha=args.alpha,
        connectivity_bits=args.connectivity_bits,
        vertices=(low, high),
        bits=(2.0, max(20.0, plan.bits + 4.0)),
        points=[(n, plan.bits, f"{args.mesh.name}: V = {n}")],
        title=f"{args.mesh.name}: K = {k.k:.4g} (grid), alpha = {args.alpha:g}, "
        f"T = {args.connectivity_bits:g}",
        path=args.output,
    )
    report = {
        "mesh": str(args.mesh),
        "output": str(args.output),
        "k": k.k,
        "vertices": n,
        "optimal_bits": plan.bits,
    }
    if args.json:
        print_json(report)
    else:
        print(
            f"wrote {args.output} (K = {k.k:.4g}, V = {n}: the vertices its faces use, "
            f"identical positions welded; optimal B = {plan.bits:.2f})"
        )
    return EXIT_OK
