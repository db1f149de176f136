"""``meshbits compress`` (one mesh, or with a .glb/.gltf output or input the whole scene)
and ``meshbits demo`` (compress the example mesh shipped in the package)."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from ..budget import Budget
from ..compress import (
    FLOAT32_LIKENESS,
    CompressResult,
    compress,
    compress_in_frame,
    float32_rounding,
)
from ..constants import DRACO_ALPHA, DRACO_CONNECTIVITY_BITS, ESTIMATORS
from ..formats import example_mesh_path, load_mesh, save_mesh
from ..results import Progress
from ..scene import NORMAL_TOLERANCE_DEGREES, SceneResult, compress_scene, merged_away
from ..search import ANSWER_REFINE_BUDGET
from ..units import in_unit, length_unit_of
from .common import (
    EXIT_OK,
    EXIT_UNMET,
    UserError,
    add_budget_arguments,
    budget_from_args,
    check_size_model,
    count,
    input_file,
    note_unit,
    output_file,
    positive_number,
    print_json,
    print_table,
    vertices_text,
)

#: Budget of ``meshbits demo``: the symmetric Hausdorff error, relative to the grid size S.
DEMO_RELATIVE_ERROR = 0.002


def add_demo(sub: argparse._SubParsersAction) -> None:
    """Add the ``demo`` subcommand to ``sub``."""
    p = sub.add_parser(
        "demo",
        help="compress the example mesh shipped in the package to an error budget",
        description="Run `meshbits compress` on Spot (public domain, shipped in the package) "
        f"with an error budget of {DEMO_RELATIVE_ERROR} of its largest bounding-box side, and "
        "say what it did.",
    )
    p.add_argument("-o", "--output", type=Path, help="also write the result (.drc, .ply, .glb)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(run=_run_demo)


def _run_demo(args: argparse.Namespace) -> int:
    """Run ``meshbits demo``; returns the exit code."""
    args.mesh = example_mesh_path()
    args.size, args.error, args.vertices, args.relative = None, DEMO_RELATIVE_ERROR, None, True
    args.lods, args.alpha, args.connectivity_bits = None, None, None
    args.max_iterations, args.samples, args.seed = 6, None, 0
    args.estimator, args.quiet, args.certify = "circumsphere", args.json, True
    args.method, args.codec, args.normal_tolerance = "auto", "draco", None
    if not args.json:
        print(
            f"meshbits demo: compressing {args.mesh.name} (Spot by Keenan Crane, public "
            f"domain) to a Hausdorff error of at most {DEMO_RELATIVE_ERROR} x its largest "
            "bounding-box side"
        )
    return _run_compress(args)


#: Outputs of one merged mesh whose size the search measures, and their format.
_FORMATS = {".drc": "draco", ".ply": "ply"}
#: Outputs (and inputs, without -o) compressed as a whole scene.
_SCENE_FORMATS = (".glb", ".gltf")
#: Outputs of the decoded mesh, whose size is not the one the search measures.
_UNSIZED_FORMATS = (".obj", ".off", ".stl")
#: Outputs that store float64 coordinates (compressed about a centre far from the origin).
_FLOAT64_FORMATS = (".obj", ".off")


#: Outputs of float32 positions.
_FLOAT32_FORMATS = (".drc", ".ply", ".stl")


def add_compress(sub: argparse._SubParsersAction) -> None:
    """Add the ``compress`` subcommand to ``sub``."""
    p = sub.add_parser(
        "compress",
        help="simplify + quantize + encode a mesh to meet a budget (paper Sec. 7)",
        description="Compute K, solve for B and V, simplify to V, quantize to B bits, encode "
        "(Draco, or with -o x.glb/.gltf Draco or meshopt per primitive), measure the "
        "Hausdorff error and the real size; adjust and repeat until the budget is met. Exit "
        "code 0 when it is met, 1 when it cannot be (the closest result is reported, and "
        "written with -o), 2 on bad input. Without -o nothing is written; a .glb/.gltf input "
        "without -o is reported per primitive, as -o x.glb would write it.",
    )
    p.add_argument("mesh", type=Path, help="mesh file (OBJ, PLY, STL, OFF, GLB, ...)")
    add_budget_arguments(p)
    p.add_argument(
        "-o",
        "--output",
        type=Path,
        help="output file: .glb or .gltf (the whole scene, every attribute, material and "
        "node kept, compressed with --codec), .drc (Draco, one merged mesh), .ply (quantized "
        "PLY); .obj/.off/.stl of the decoded mesh (not with --size: their size is not what "
        "the loop measures). Without it nothing is written (a .glb/.gltf input is then "
        "reported as a scene).",
    )
    p.add_argument(
        "--codec",
        choices=("auto", "draco", "meshopt"),
        default="auto",
        help="for .glb/.gltf: auto (default: the scene compressed with both, the smaller file "
        "within the budget kept, and what the other gave reported), draco "
        "(KHR_draco_mesh_compression) or meshopt (EXT_meshopt_compression with "
        "KHR_mesh_quantization)",
    )
    p.add_argument(
        "--normal-tolerance",
        type=positive_number,
        default=None,
        help="for .glb/.gltf: largest angle in degrees between a normal and its quantized "
        "value (default 1)",
    )
    p.add_argument(
        "--lods", type=Path, nargs="+", help="levels of detail to pick from, instead of simplifying"
    )
    p.add_argument(
        "--method",
        choices=("auto", "meshopt", "fast-simplification"),
        default="auto",
        help="simplifier: meshoptimizer (error targets, spikes locked), fast-simplification, "
        "or auto (both compete up to 200,000 faces, measured; meshoptimizer above; default)",
    )
    p.add_argument(
        "--alpha",
        type=positive_number,
        help="size model alpha, bits per coordinate bit, in (0, 1] (default: fitted to Draco)",
    )
    p.add_argument(
        "--connectivity-bits",
        type=float,
        help="size model T, bits per vertex for connectivity, >= 0 (default: fitted to Draco)",
    )
    p.add_argument(
        "--max-iterations", type=count(1), default=6, help="passes of the loop at most (default 6)"
    )
    p.add_argument(
        "--samples",
        type=count(0),
        help="Hausdorff area samples per mesh (default: 10 per face of the finer mesh, "
        "within [10000, 1000000])",
    )
    p.add_argument("--seed", type=count(0), default=0, help="seed of the samples (default 0)")
    p.add_argument("--estimator", choices=ESTIMATORS, default="circumsphere", help="estimator of K")
    p.add_argument(
        "--no-certify",
        dest="certify",
        action="store_false",
        help="judge an error budget by the sampled error (a lower bound, faster) instead of "
        "a certified upper bound (the default: 'met' means the true error is within it)",
    )
    p.add_argument(
        "--certify", dest="certify", action="store_true", default=True, help=argparse.SUPPRESS
    )
    p.add_argument("--quiet", action="store_true", help="no per-iteration lines on stderr")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(run=_run_compress)


def _note_merged_away(path: Path, suffix: str, away: dict[str, Any]) -> None:
    """One stderr line naming what a merged-mesh output leaves out of a scene input."""
    missing = away.get("missing_material_libraries", [])
    if missing:
        print(
            f"note: material librar{'ies' if len(missing) > 1 else 'y'} "
            f"{', '.join(missing)} named by {path.name} not found beside it: its materials "
            "are unknown",
            file=sys.stderr,
        )
    parts = [
        f"{n} {k.replace('_', ' ')[: None if n != 1 else -1]}"
        for k, n in away.items()
        if k not in ("attributes", "missing_material_libraries")
    ]
    if away["attributes"]:
        parts.append("the vertex attributes " + ", ".join(away["attributes"]))
    if parts:
        print(
            f"note: {path.name} is written to {suffix} as one merged mesh of positions: "
            f"{', '.join(parts)} are not kept (-o x.glb or x.gltf keeps them)",
            file=sys.stderr,
        )


def _bound_text(result: Any, certify: bool) -> float | str:
    """A compress result's certified error bound, or why it has none."""
    if result.error_upper is not None:
        return float(result.error_upper)
    if not certify:
        return "none (--no-certify)"
    if result.constraint == "error":
        return "none (an error budget's answer is certified once met; this one was not)"
    return f"none (it did not converge within {ANSWER_REFINE_BUDGET:,} refinement points)"


def _budget_in_units(result: Any, unit: str) -> str:
    """A result's budget in the user's units: bytes, the length unit, or vertices."""
    if result.constraint == "size":
        return f"{result.budget / 8:.6g} bytes"
    if result.constraint == "error":
        return f"{result.budget:.6g} {unit}"
    return f"{result.budget:.0f} vertices"


def _run_compress(args: argparse.Namespace) -> int:
    """Run ``meshbits compress``; returns the exit code."""
    budget = budget_from_args(args, length_unit_of(args.mesh))
    check_size_model(args)
    output = args.output
    suffix = output.suffix.lower() if output else ".drc"
    if suffix in _SCENE_FORMATS or (output is None and _is_scene_file(args.mesh)):
        return _run_compress_scene(args, budget)
    if args.codec not in ("auto", "draco"):
        raise UserError("--codec applies to .glb and .gltf outputs")
    if args.normal_tolerance is not None:
        raise UserError("--normal-tolerance applies to .glb and .gltf outputs")
    if suffix not in _FORMATS and suffix not in _UNSIZED_FORMATS:
        raise UserError(
            f"cannot write {output}: use .glb, .gltf, .drc, .ply, " + ", ".join(_UNSIZED_FORMATS)
        )
    if suffix in _UNSIZED_FORMATS and budget.kind == "size":
        raise UserError(
            f"--size needs a .glb, .gltf, .drc or .ply output; {suffix} sizes are not measured"
        )
    output_file(output, args.mesh, *(args.lods or []))
    for path in [args.mesh, *(args.lods or [])]:
        input_file(path)
    note_unit(args, args.mesh)
    unit = length_unit_of(args.mesh)
    mesh = load_mesh(args.mesh)
    lods = [load_mesh(path) for path in args.lods] if args.lods else None
    away = merged_away(args.mesh)
    if away is not None and not args.quiet:
        _note_merged_away(args.mesh, suffix, away)
    # OBJ and OFF hold float64 text: far from the origin they are compressed about a centre.
    run = compress_in_frame if suffix in _FLOAT64_FORMATS else compress
    result = run(
        mesh,
        **budget.options(),
        lods=lods,
        method=args.method,
        format=_FORMATS.get(suffix, "draco"),
        alpha=DRACO_ALPHA if args.alpha is None else args.alpha,
        connectivity_bits=(
            DRACO_CONNECTIVITY_BITS if args.connectivity_bits is None else args.connectivity_bits
        ),
        max_iterations=args.max_iterations,
        samples=args.samples,
        seed=args.seed,
        estimator=args.estimator,
        certify=args.certify,
        progress=_progress_lines(args.quiet, unit),
    )
    file_bytes = None
    unheld = _unheld(result, suffix, mesh[0]) if output is not None else ""
    if unheld:
        result = replace(result, message=f"{result.message}; {unheld}")
        output = None
    if output is not None:
        if suffix in _FORMATS:
            result.write(output)
        else:
            save_mesh(output, result.vertices, result.faces)
        file_bytes = output.stat().st_size
    input_bytes = args.mesh.stat().st_size
    payload = {
        "mesh": str(args.mesh),
        "output": str(output) if output else None,
        "file_bytes": file_bytes,
        **budget.to_dict(),
        **({} if away is None else {"merged_away": away}),
        **result.to_dict(),
    }
    payload["message"] = in_unit(payload["message"], unit)
    larger = file_bytes is not None and file_bytes > input_bytes
    if larger:
        payload["notes"] = [
            f"the file is larger than its input ({file_bytes} > {input_bytes} bytes)"
        ]
    if args.json:
        print_json(payload, args.mesh)
    else:
        _print_compress(args, mesh, result, budget, file_bytes)
        if larger:
            print(f"note: {payload['notes'][0]}")
    return EXIT_OK if result.met else EXIT_UNMET


def _unheld(result: CompressResult, suffix: str, vertices: Any) -> str:
    """Why nothing is written, when an error budget was missed by an output of float32
    positions that float32 alone, where the mesh lies, rounds by more than the budget and
    by more than :data:`meshbits.compress.FLOAT32_LIKENESS` of the mesh's size (the
    closest result there is no likeness of the mesh); else ``""``."""
    if result.met or result.constraint != "error" or suffix not in _FLOAT32_FORMATS:
        return ""
    rounding = float32_rounding(vertices)
    side = float(np.ptp(vertices, axis=0).max()) if len(vertices) else 0.0
    if rounding <= result.budget or rounding <= FLOAT32_LIKENESS * side:
        return ""
    return (
        f"nothing written: {suffix} stores float32 positions, which float32 alone moves by "
        f"up to {rounding:.4g} (mesh units) where this mesh lies, more than the budget of "
        f"{result.budget:.4g} and {rounding / side:.3g} of the mesh's largest side; write "
        ".glb, .gltf, .obj or .off"
    )


def _progress_lines(quiet: bool, unit: str) -> Callable[[Progress], None]:
    """A progress callback printing each event on stderr (lengths in ``unit``), or
    nothing with ``--quiet``."""

    def report(event: Progress) -> None:
        if not quiet:
            print(f"  {in_unit(str(event), unit)}", file=sys.stderr)

    return report


def _print_compress(
    args: argparse.Namespace,
    mesh: tuple[Any, Any],
    result: CompressResult,
    budget: Budget,
    file_bytes: int | None,
) -> None:
    """The text report of a single-mesh compress."""
    output, unit = args.output, length_unit_of(args.mesh)
    suffix = output.suffix.lower() if output else ".drc"
    first = result.plan
    print_table(
        f"{args.mesh}: {vertices_text(len(mesh[0]), result.complexity.merged_vertices)}, "
        f"{len(mesh[1])} faces; "
        f"K = {result.complexity.k:.4g}, S = {result.complexity.grid_size:.6g}",
        [
            ("budget", f"{budget.text} ({_budget_in_units(result, unit)})"),
            (
                "first plan",
                "none (the smallest output)"
                if first is None
                else f"B = {first.whole_bits}, V = {first.whole_vertices:.0f}",
            ),
            (
                "chosen",
                f"B = {result.bits}, V = {result.vertex_count}, {len(result.faces)} faces",
            ),
            (f"measured error ({unit})", result.error),
            (f"certified error bound ({unit})", _bound_text(result, args.certify)),
            ("measured error / S", result.error / result.complexity.grid_size),
            ("size", f"{result.size_bytes} bytes ({result.format})"),
            ("passes", len(result.iterations)),
            (
                "output",
                _output_text(output, result, file_bytes),
            ),
        ],
    )
    print(in_unit(result.message, unit))
    if suffix in _UNSIZED_FORMATS and file_bytes is not None:
        print(
            f"wrote {output}: {file_bytes} bytes ({suffix[1:]} of the decoded mesh; "
            f"the bytes above are the {result.format} encoding the search sized)"
        )


def _output_text(output: Path | None, result: CompressResult, file_bytes: int | None) -> str:
    if output is None:
        return "(not written: use -o)"
    if file_bytes is None:
        return f"{output} not written (below)"
    return str(output) + ("" if result.met else " (the closest result: the budget was not met)")


def _is_scene_file(path: Path) -> bool:
    """A .glb or .gltf input: compressed as a scene, as ``-o x.glb`` would write it."""
    return path.suffix.lower() in _SCENE_FORMATS


def _run_compress_scene(args: argparse.Namespace, budget: Budget) -> int:
    """compress to .glb / .gltf (or, without ``-o``, a .glb / .gltf input, nothing
    written): the whole scene, primitive by primitive."""
    _check_scene_options(args, budget)
    output_file(args.output, args.mesh)
    input_file(args.mesh)
    note_unit(args, args.mesh)
    unit = length_unit_of(args.mesh)
    result = compress_scene(
        args.mesh,
        **budget.options(),
        codec=args.codec,
        normal_tolerance=(
            NORMAL_TOLERANCE_DEGREES if args.normal_tolerance is None else args.normal_tolerance
        ),
        output=args.output,
        seed=args.seed,
        certify=args.certify,
        progress=_progress_lines(args.quiet, unit),
    )
    payload = {
        "input": str(args.mesh),
        "output": None if args.output is None else str(args.output),
        **result.to_dict(),
        **budget.to_dict(),
    }
    payload["message"] = in_unit(payload["message"], unit)
    if args.json:
        print_json(payload, args.mesh)
        return EXIT_OK if result.met else EXIT_UNMET
    _print_scene(args, result, budget)
    return EXIT_OK if result.met else EXIT_UNMET


def _print_scene(args: argparse.Namespace, result: SceneResult, budget: Budget) -> None:
    """The text report of a scene compress: a line, a table row per primitive, the
    message."""
    unit = length_unit_of(args.mesh)
    target = "(not written: use -o x.glb)" if args.output is None else str(args.output)
    if args.output is not None and args.output.suffix.lower() == ".gltf":
        target += f" and {args.output.with_suffix('.bin').name}"
    print(
        f"{args.mesh} -> {target} ({result.codec}): {result.input_bytes} -> "
        f"{result.size_bytes} bytes; budget {budget.text}"
    )
    header = (
        "mesh",
        "prim",
        "name",
        "inst",
        "scale",
        "B",
        "normal",
        "uv",
        "V in",
        "V out",
        "bytes",
        f"error ({unit})",
        f"bound ({unit})",
        "met",
    )
    rows = [
        (
            str(p.mesh),
            str(p.primitive),
            str(p.name or "-"),
            str(p.instances),
            f"{p.scale:.3g}",
            str(p.bits) if p.kept is None else "kept",
            str(p.normal_bits or "-"),
            str(p.uv_bits or "-"),
            str(p.input_vertices)
            if p.input_distinct_vertices in (None, p.input_vertices)
            else f"{p.input_vertices} ({p.input_distinct_vertices} welded)",
            str(p.vertices),
            str(p.bytes),
            f"{p.world_error:.4g}",
            "-" if p.world_error_upper is None else f"{p.world_error_upper:.4g}",
            "yes" if p.met else "no",
        )
        for p in result.primitives
    ]
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header))]
    for row in [header, *rows]:
        print("  " + "  ".join(c.rjust(w) for c, w in zip(row, widths, strict=True)))
    print(in_unit(result.message, unit))


def _check_scene_options(args: argparse.Namespace, budget: Budget) -> None:
    """Refuse what a scene does not take: --vertices, --lods and the single-mesh
    search's options."""
    merged = (
        " (-o x.drc or -o x.ply compresses the scene's meshes merged into one)"
        if args.output is None
        else ""
    )
    if budget.kind == "vertices":
        raise UserError("a scene takes --error or --size, not --vertices" + merged)
    if args.lods:
        raise UserError("--lods applies to single meshes (.drc and .ply outputs)" + merged)
    unused = {
        "--samples": args.samples is not None,
        "--method": args.method != "auto",
        "--alpha": args.alpha is not None,
        "--connectivity-bits": args.connectivity_bits is not None,
        "--max-iterations": args.max_iterations != 6,
        "--estimator": args.estimator != "circumsphere",
    }
    given = [name for name, used in unused.items() if used]
    if given:
        raise UserError(
            f"{', '.join(given)} {'applies' if len(given) == 1 else 'apply'} to single meshes "
            "(.drc and .ply outputs); a scene's "
            "primitives are searched with meshoptimizer and their own sample counts" + merged
        )
