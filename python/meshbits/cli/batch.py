"""``meshbits batch``: compress every mesh of a folder, glob or manifest to one budget, in
parallel, with a report (:func:`meshbits.batch.batch`)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..batch import BatchInterrupted, BatchResult, batch
from ..batch.report import bytes_text
from .common import (
    EXIT_INTERRUPTED,
    UserError,
    add_budget_arguments,
    budget_from_args,
    count,
    print_json,
)


def add_batch(sub: argparse._SubParsersAction) -> None:
    """Add the ``batch`` subcommand to ``sub``."""
    p = sub.add_parser(
        "batch",
        help="compress every mesh of a folder, glob or manifest to one budget, in parallel",
        description="Compress every input with the same options, on a pool of worker "
        "processes (or Dask), mirroring the input's sub-folders under OUT_DIR, and write "
        "OUT_DIR/meshbits-report.jsonl (a row per input, as each finishes), "
        "meshbits-summary.csv and meshbits-report.png (with matplotlib). A rerun skips the "
        "inputs already done with the same options and input bytes. A bad input or an "
        "unmet budget is recorded and the batch goes on. Exit code 0 when every budget was "
        "met, 1 when some were not, 2 when some inputs were unusable, 3 when a task hit an "
        "internal error, 130 when interrupted (the report keeps what finished).",
    )
    p.add_argument(
        "input",
        help="a folder (searched recursively for .ply .ply.gz .obj .stl .off .glb .gltf .drc), "
        "a glob pattern (quote it; ** for sub-folders), or a manifest: .csv with a 'path' "
        'column or .jsonl with a "path" key (relative to the manifest)',
    )
    p.add_argument(
        "-o", "--output", type=Path, required=True, metavar="OUT_DIR", help="output folder"
    )
    add_budget_arguments(p, vertices=False)
    p.add_argument(
        "--format",
        choices=("drc", "ply", "glb", "gltf"),
        default="drc",
        help="output format: drc (Draco, default) or ply, one merged mesh per input; glb or "
        "gltf, the whole scene with --codec",
    )
    p.add_argument(
        "--codec",
        choices=("auto", "draco", "meshopt"),
        default="auto",
        help="for glb/gltf: auto (default: both tried per file, the smaller within the "
        "budget kept), draco (KHR_draco_mesh_compression) or meshopt "
        "(EXT_meshopt_compression)",
    )
    p.add_argument(
        "--workers",
        type=count(1),
        help="worker processes (default: one per core); 1 runs in this process with the "
        "kernels on every core",
    )
    p.add_argument(
        "--dask",
        metavar="ADDRESS",
        help="run on Dask distributed: a scheduler address (tcp://host:8786; inputs and "
        "OUT_DIR at the same paths on the workers) or local:N for a LocalCluster of N "
        "processes (needs meshbits[dask])",
    )
    p.add_argument("--seed", type=count(0), default=0, help="seed of the samples (default 0)")
    p.add_argument(
        "--max-iterations",
        type=count(1),
        default=6,
        help="passes of the search per input at most, drc/ply (default 6)",
    )
    p.add_argument(
        "--force", action="store_true", help="redo inputs whose output is already up to date"
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(run=_run_batch)


def _run_batch(args: argparse.Namespace) -> int:
    """Run ``meshbits batch``; returns the exit code."""
    budget = budget_from_args(args)
    if args.dask is not None and args.workers is not None:
        raise UserError("give --workers or --dask, not both (--dask local:N sets the workers)")
    try:
        result = batch(
            args.input,
            args.output,
            **budget.options(),
            format=args.format,
            codec=args.codec,
            seed=args.seed,
            max_iterations=args.max_iterations,
            workers=args.workers,
            dask=args.dask,
            force=args.force,
            progress=not args.quiet and not args.json and sys.stderr.isatty(),
        )
    except BatchInterrupted as stop:
        _print_batch(stop.result, args)
        print("meshbits batch: interrupted; the report keeps what finished", file=sys.stderr)
        return EXIT_INTERRUPTED
    _print_batch(result, args)
    return result.exit_code


#: Failed inputs listed by ``meshbits batch`` at most (the report has them all).
_BATCH_LISTED = 20


def _print_batch(result: BatchResult, args: argparse.Namespace) -> None:
    """The batch's JSON, or its totals and the inputs that failed (at most 20)."""
    if args.json:
        print_json(result.to_dict())
        return
    ignored = sum(result.ignored.values())
    extras = [
        f"{result.resumed} resumed",
        *([f"{ignored} other files ignored"] if ignored else []),
        *([f"{result.duplicates} duplicates"] if result.duplicates else []),
        *([f"{result.not_reached} not reached"] if result.not_reached else []),
    ]
    print(
        f"{args.input}: {result.inputs} inputs ({', '.join(extras)}): {result.met} met, "
        f"{result.unmet} unmet, {result.unusable} unusable, {result.internal_errors} "
        "internal errors"
    )
    ratio = f", {100 * result.saved_bytes / result.input_bytes:.1f}%" if result.input_bytes else ""
    if result.backend == "none":
        where = "(nothing to run)"
    elif result.backend == "serial":
        where = "in this process"
    else:
        kind = "Dask" if result.backend == "dask" else "process"
        where = f"on {result.workers} {kind} workers"
    print(
        f"  {bytes_text(result.input_bytes)} -> {bytes_text(result.output_bytes)} (saved "
        f"{bytes_text(result.saved_bytes)}{ratio}) in {result.seconds:.1f} s {where}"
    )
    print(f"  report: {result.report}")
    plot = f", plot: {result.plot}" if result.plot else ", no plot (it needs matplotlib)"
    print(f"  summary: {result.summary}{plot}")
    failed = [r for r in result.rows if r.status != "met"]
    for row in failed[:_BATCH_LISTED]:
        print(f"  {row.status}: {row.relative}: {row.message}")
    if len(failed) > _BATCH_LISTED:
        print(f"  ... and {len(failed) - _BATCH_LISTED} more (see the report)")
