"""``meshbits quantize``: quantize a mesh to B bits per coordinate and cluster its
vertices (paper Sec. 1.1)."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..constants import DUPLICATES, GRIDS, MAX_BITS
from ..formats import load_mesh, save_mesh
from ..quantize import cluster
from ..units import length_unit_of
from .common import (
    EXIT_OK,
    UserError,
    bit_depth,
    input_file,
    output_file,
    print_json,
    print_table,
)

#: What ``save_mesh`` writes (``meshbits quantize -o``).
_MESH_OUTPUTS = (".ply", ".obj", ".off", ".stl", ".glb", ".gltf")


def add_quantize(sub: argparse._SubParsersAction) -> None:
    """Add the ``quantize`` subcommand to ``sub``."""
    p = sub.add_parser(
        "quantize",
        help="quantize a mesh to B bits per coordinate and cluster its vertices (Sec. 1.1)",
    )
    p.add_argument("mesh", type=Path, help="mesh file (OBJ, PLY, STL, OFF, GLB, ...)")
    p.add_argument(
        "--bits",
        type=bit_depth(MAX_BITS),
        required=True,
        help=f"bits per coordinate, 1 to {MAX_BITS}",
    )
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
    """Run ``meshbits quantize``; returns the exit code."""
    output_file(args.output, args.mesh)
    if args.output is not None and args.output.suffix.lower() not in _MESH_OUTPUTS:
        raise UserError(
            f"{args.output}: cannot write {args.output.suffix or 'a file without a suffix'}; "
            f"write a mesh: {', '.join(_MESH_OUTPUTS)}"
        )
    vertices, faces = load_mesh(input_file(args.mesh))
    result = cluster(vertices, faces, bits=args.bits, grid=args.grid, duplicates=args.duplicates)
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
        print_json(report, args.mesh)
        return EXIT_OK
    unit = length_unit_of(args.mesh)
    print_table(
        f"{report['mesh']}: {result.input_vertices} vertices, {result.input_faces} faces, "
        f"{result.bits}-bit {result.grid} grid",
        [
            ("vertices kept", result.output_vertices),
            ("  merged", result.merged_vertices),
            ("  unreferenced (dropped)", result.unreferenced_vertices),
            ("faces kept", result.output_faces),
            ("  degenerate (dropped)", result.degenerate_faces),
            ("  duplicate (dropped)", result.duplicate_faces),
            (f"grid size S ({unit})", result.grid_size),
            (f"step ({unit})", " ".join(f"{s:.6g}" for s in result.step)),
            (f"bound 0.5|step| ({unit})", result.bound),
            (f"max displacement ({unit})", result.max_displacement),
            ("written to", report["output"] or "-"),
        ],
    )
    return EXIT_OK
