"""``meshbits calibrate``: fit the size model's alpha and T to real Draco encodings of a
mesh."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..codecs import encode_draco, fit_size_model
from ..constants import FORMAT_MAX_BITS
from ..formats import load_mesh
from ..simplify import simplify
from .common import EXIT_OK, UserError, bit_depth, count, input_file, print_json, print_table


def add_calibrate(sub: argparse._SubParsersAction) -> None:
    """Add the ``calibrate`` subcommand to ``sub``."""
    p = sub.add_parser(
        "calibrate",
        help="fit the size model's alpha and T to real Draco encodings of a mesh",
        description="Simplify MESH to a few vertex counts, encode each with Draco at several "
        "bit depths, and fit F = (3 alpha B + T) V (paper Eq. 1) to the measured sizes.",
    )
    p.add_argument("mesh", type=Path, help="mesh file (OBJ, PLY, STL, OFF, GLB, ...)")
    p.add_argument(
        "--vertices",
        type=count(4),
        nargs="+",
        default=[500, 2000, 8000],
        help="vertex counts to simplify to (default 500 2000 8000)",
    )
    p.add_argument(
        "--bits",
        type=bit_depth(FORMAT_MAX_BITS["draco"]),
        nargs="+",
        default=[6, 8, 10, 12, 14, 16],
        help="bits per coordinate to encode each level at (default 6 8 10 12 14 16)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(run=_run_calibrate)


def _run_calibrate(args: argparse.Namespace) -> int:
    """Run ``meshbits calibrate``; returns the exit code."""
    if len(set(args.bits)) < 2:
        raise UserError("--bits needs two or more distinct values to fit alpha and T")
    mesh = load_mesh(input_file(args.mesh))
    samples = []
    for target in args.vertices:
        level = simplify(mesh, target).mesh
        for bits in args.bits:
            encoded = encode_draco(level, bits)
            samples.append((bits, len(encoded.vertices), encoded.size_bits))
    fit = fit_size_model(*zip(*samples, strict=True))
    payload = {
        "mesh": str(args.mesh),
        **fit.to_dict(),
        "measurements": [
            dict(zip(("bits", "vertices", "size_bits"), s, strict=True)) for s in samples
        ],
    }
    if args.json:
        print_json(payload)
    else:
        print_table(
            f"{args.mesh}: Draco (level 7) sizes, F = (3 alpha B + T) V",
            [
                ("alpha", fit.alpha),
                ("T (bits per vertex)", fit.connectivity_bits),
                ("relative RMS misfit", fit.relative_rms),
                ("encodings", fit.samples),
            ],
        )
        print(
            f"use: meshbits compress MESH --alpha {fit.alpha:.3f} "
            f"--connectivity-bits {fit.connectivity_bits:.2f} ..."
        )
    return EXIT_OK
