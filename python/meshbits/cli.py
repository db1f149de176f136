"""The ``meshbits`` command line.

Every subcommand prints a short human-readable report, or one JSON object with
``--json`` (strict JSON: a value that is not a finite number is ``null``). Exit codes:

- 0: done (``compress``: the budget was met);
- 1: a budget could not be met (the closest result is still reported, and written);
- 2: bad arguments, or an input file that cannot be used (one line on stderr);
- 3: an internal error, a bug in meshbits (one line on stderr; ``--debug`` shows the
  traceback);
- 130: interrupted (Ctrl-C);
- 141: the reader of stdout closed it (``meshbits ... | head``), silently.

With ``--json`` a failure (2, 3, 130; usage errors too) is also one JSON object on stdout,
``{"error": message, "exit_code": code}``.

A JSON report of a file names the unit of its lengths in ``length_unit``: ``"m"`` for
glTF (whose unit is the meter), else ``"mesh units"`` (the file's own coordinates, which
carry no unit); areas are in that unit squared.

Arguments and output folders are checked before any file is read.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import traceback
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, NoReturn

import numpy as np

from . import __version__, model
from .complexity import shape_complexity
from .constants import (
    BOUNDS_RELATIVE_TOLERANCE,
    DRACO_ALPHA,
    DRACO_CONNECTIVITY_BITS,
    DUPLICATES,
    ESTIMATORS,
    FORMAT_MAX_BITS,
    GRIDS,
    HAUSDORFF_REFINE_BUDGET,
    MAX_BITS,
    MODEL_MIN_VERTICES,
)
from .encode import fixed_width_size_bits
from .errors import MeshbitsError
from .files import check_not_an_input, check_writable
from .formats import example_mesh_path, load_mesh, save_mesh
from .hausdorff import hausdorff
from .model import METHODS, plan_for_error, plan_for_size, plan_for_vertices
from .quantize import cluster
from .results import Progress, json_ready
from .units import in_unit, length_unit_of, parse_length, parse_size

__all__ = ["main"]

EXIT_OK, EXIT_UNMET, EXIT_BAD_INPUT, EXIT_INTERNAL, EXIT_INTERRUPTED = 0, 1, 2, 3, 130
#: The reader of stdout closed it (``| head``): the code of a process ended by SIGPIPE.
EXIT_BROKEN_PIPE = 141


class UserError(Exception):
    """A problem with the command's input, reported in one line with exit code 2."""


def _print_json(payload: dict[str, Any], lengths_of: Path | None = None) -> None:
    """Print ``payload`` as strict JSON; with ``lengths_of``, after its first key the unit
    of the lengths reported on that file (``length_unit``)."""
    if lengths_of is not None:
        first, *rest = payload.items()
        payload = dict([first, ("length_unit", length_unit_of(lengths_of)), *rest])
    print(json.dumps(json_ready(payload), indent=2, allow_nan=False))


def _positive_number(text: str) -> float:
    """An argparse type: a positive finite number, refused with the text as typed."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a positive finite number, got {text!r}")
    return value


class _Length(float):
    """A length read from the command line, with the text it was given as."""

    text: str = ""


def _length(text: str) -> float:
    """An argparse type: a positive length, plain (the file's units) or with a unit
    (meters, glTF's unit: 1mm = 0.001)."""
    try:
        value = _Length(parse_length(text))
    except MeshbitsError as err:
        raise argparse.ArgumentTypeError(str(err)) from None
    value.text = text.strip()
    return value


def _check_relative(args: argparse.Namespace) -> None:
    if args.relative and args.error is None:
        raise UserError("--relative applies to --error only")
    text = getattr(args.error, "text", "")
    if args.relative and text[-1:].isalpha():
        raise UserError(
            f"--error {text} has a unit, and --relative makes it a fraction of S: "
            "give a plain number with --relative, or drop --relative"
        )


def _note_unit(args: argparse.Namespace, path: Path) -> None:
    """Say how an error given with a unit is read from a file format without units."""
    text = getattr(args.error, "text", "")
    if text and text[-1:].isalpha() and path.suffix.lower() not in (".glb", ".gltf"):
        print(
            f"note: --error {text} is read as {float(args.error):g} in the units of "
            f"{path.name}, taken as meters (glTF's unit): this format carries no unit",
            file=sys.stderr,
        )


def _budget_unit(args: argparse.Namespace, unit: str) -> str:
    """The unit of a compress report's ``budget``: bits, the length unit, or vertices."""
    if args.size is not None:
        return "bits"
    return unit if args.error is not None else "vertices"


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


def _count(smallest: int) -> Callable[[str], int]:
    """An argparse type: a whole number of at least ``smallest``."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
        if value < smallest:
            raise argparse.ArgumentTypeError(f"must be at least {smallest}, got {text!r}")
        return value

    return parse


def _size_text(text: str) -> str:
    """An argparse type: a size with a unit, checked and kept as typed."""
    try:
        parse_size(text)
    except MeshbitsError as err:
        raise argparse.ArgumentTypeError(str(err)) from None
    return text


def _output(path: Path | None, *inputs: Path | None) -> Path | None:
    """Check an output path before any work (``None``: nothing to write): its folder
    must be writable, and neither it nor a .gltf output's buffer file may be one of the
    ``inputs`` or the files a .gltf input refers to (that would destroy the input)."""
    if path is None:
        return None
    try:
        check_writable(path)
    except MeshbitsError as err:
        raise UserError(str(err)) from None
    try:
        return check_not_an_input(path, *inputs)
    except MeshbitsError as err:
        raise UserError(str(err)) from None


def _bits(largest: int) -> Callable[[str], int]:
    """An argparse type: bits per coordinate, 1 to ``largest``."""
    whole = _count(1)

    def parse(text: str) -> int:
        value = whole(text)
        if value > largest:
            raise argparse.ArgumentTypeError(f"must be at most {largest}, got {text!r}")
        return value

    return parse


def _check_size_model(args: argparse.Namespace) -> None:
    """``--alpha`` in (0, 1] and ``--connectivity-bits`` >= 0, when given."""
    if args.alpha is not None and args.alpha > 1:
        raise UserError(f"--alpha must be in (0, 1], got {args.alpha:g}")
    t = args.connectivity_bits
    if t is not None and not (math.isfinite(t) and t >= 0):
        raise UserError(f"--connectivity-bits must be a number >= 0, got {t:g}")


def _input(path: Path) -> Path:
    if path.is_dir():
        raise UserError(f"{path} is a folder, not a mesh file (meshbits batch takes folders)")
    if not path.is_file():
        raise UserError(f"no such mesh file: {path}")
    return path


def _print_table(title: str, rows: Sequence[tuple[str, Any]]) -> None:
    print(title)
    width = max(len(name) for name, _ in rows)
    for name, value in rows:
        if isinstance(value, float):
            value = f"{value:.6g}"
        print(f"  {name:<{width}}  {value}")


def _complexity_report(path: Path, args: argparse.Namespace) -> dict[str, Any]:
    vertices, faces = load_mesh(_input(path))
    result = shape_complexity(
        vertices, faces, estimator=args.estimator, merge_vertices=not args.no_merge
    )
    return {"mesh": str(path), "vertices": len(vertices), "faces": len(faces), **result.to_dict()}


def _add_k(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("k", help="shape complexity K of a mesh (paper Sec. 4)")
    p.add_argument("mesh", type=Path, help="mesh file (OBJ, PLY, STL, OFF, GLB, ...)")
    p.add_argument("--estimator", choices=ESTIMATORS, default="circumsphere", help="estimator of K")
    p.add_argument("--no-merge", action="store_true", help="do not weld identical vertices")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(run=_run_k)


def _vertices_text(vertices: int, merged: int | None) -> str:
    """ "N vertices", with the count once identical positions are welded when that differs
    (an STL stores every face's corners apart)."""
    welded = f" ({vertices - merged} once welded)" if merged else ""
    return f"{vertices} vertices{welded}"


def _run_k(args: argparse.Namespace) -> int:
    report = _complexity_report(args.mesh, args)
    if args.json:
        _print_json(report, args.mesh)
        return EXIT_OK
    unit = length_unit_of(args.mesh)
    _print_table(
        f"{report['mesh']}: {_vertices_text(report['vertices'], report['merged_vertices'])}, "
        f"{report['faces']} faces",
        [
            ("K (grid, /S)", report["k"]),
            ("K (area, /sqrt(A))", report["k_area"]),
            (f"K raw ({unit})", report["k_raw"]),
            (f"grid size S ({unit})", report["grid_size"]),
            (f"area ({unit}^2)" if unit == "m" else "area (mesh units^2)", report["area"]),
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


#: Budget of ``meshbits demo``: the symmetric Hausdorff error, relative to the grid size S.
DEMO_RELATIVE_ERROR = 0.002


def _add_demo(sub: argparse._SubParsersAction) -> None:
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


_FORMATS = {".drc": "draco", ".ply": "ply"}
_SCENE_FORMATS = (".glb", ".gltf")
_UNSIZED_FORMATS = (".obj", ".off", ".stl")
_FLOAT64_FORMATS = (".obj", ".off")
#: What ``save_mesh`` writes (``meshbits quantize -o``).
_MESH_OUTPUTS = (".ply", ".obj", ".off", ".stl", ".glb", ".gltf")


def _add_compress(sub: argparse._SubParsersAction) -> None:
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
    budget = p.add_mutually_exclusive_group(required=True)
    budget.add_argument(
        "--size",
        type=_size_text,
        help="file size budget with a unit: 100KB, 2MiB, 800kbit (B = bytes)",
    )
    budget.add_argument(
        "--error",
        type=_length,
        help="Hausdorff error budget: a length in the file's units (0.002), or with a unit "
        "for files in meters, as glTF is (1mm, 0.5cm, 2in); a fraction of S with --relative",
    )
    budget.add_argument("--vertices", type=_count(4), help="vertex count V (at least 4)")
    p.add_argument(
        "--relative", action="store_true", help="--error is a fraction of S (largest bbox side)"
    )
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
        choices=("draco", "meshopt"),
        default="draco",
        help="for .glb/.gltf: KHR_draco_mesh_compression (default) or EXT_meshopt_compression "
        "with KHR_mesh_quantization",
    )
    p.add_argument(
        "--normal-tolerance",
        type=_positive_number,
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
        type=_positive_number,
        help="size model alpha, bits per coordinate bit, in (0, 1] (default: fitted to Draco)",
    )
    p.add_argument(
        "--connectivity-bits",
        type=float,
        help="size model T, bits per vertex for connectivity, >= 0 (default: fitted to Draco)",
    )
    p.add_argument(
        "--max-iterations", type=_count(1), default=6, help="passes of the loop at most (default 6)"
    )
    p.add_argument(
        "--samples",
        type=_count(0),
        help="Hausdorff area samples per mesh (default: 10 per face of the finer mesh, "
        "within [10000, 1000000])",
    )
    p.add_argument("--seed", type=_count(0), default=0, help="seed of the samples (default 0)")
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


def _budget_text(args: argparse.Namespace) -> str:
    """The budget as the user typed it (an error with a unit, in meters)."""
    if args.size is not None:
        return f"--size {args.size}"
    if args.error is not None:
        typed = getattr(args.error, "text", f"{args.error:g}")
        return f"--error {typed}" + (" --relative" if args.relative else "")
    return f"--vertices {args.vertices}"


def _bound_text(result: Any, certify: bool) -> float | str:
    """A compress result's certified error bound, or why it has none."""
    from .search import ANSWER_REFINE_BUDGET

    if result.error_upper is not None:
        return float(result.error_upper)
    if not certify:
        return "none (--no-certify)"
    if result.constraint == "error":
        return "none (an error budget's answer is certified once met; this one was not)"
    return f"none (it did not converge within {ANSWER_REFINE_BUDGET:,} refinement points)"


def _run_compress(args: argparse.Namespace) -> int:
    from .compress import compress, compress_in_frame
    from .scene import merged_away

    _check_relative(args)
    _check_size_model(args)
    output = args.output
    suffix = output.suffix.lower() if output else ".drc"
    if suffix in _SCENE_FORMATS or (output is None and _is_scene_file(args.mesh)):
        return _run_compress_scene(args)
    if args.codec != "draco":
        raise UserError("--codec applies to .glb and .gltf outputs")
    if args.normal_tolerance is not None:
        raise UserError("--normal-tolerance applies to .glb and .gltf outputs")
    if suffix not in _FORMATS and suffix not in _UNSIZED_FORMATS:
        raise UserError(
            f"cannot write {output}: use .glb, .gltf, .drc, .ply, " + ", ".join(_UNSIZED_FORMATS)
        )
    if suffix in _UNSIZED_FORMATS and args.size is not None:
        raise UserError(
            f"--size needs a .glb, .gltf, .drc or .ply output; {suffix} sizes are not measured"
        )
    _output(output, args.mesh, *(args.lods or []))
    for path in [args.mesh, *(args.lods or [])]:
        _input(path)
    _note_unit(args, args.mesh)
    unit = length_unit_of(args.mesh)
    mesh = load_mesh(args.mesh)
    lods = [load_mesh(path) for path in args.lods] if args.lods else None
    away = merged_away(args.mesh)
    if away is not None and not args.quiet:
        _note_merged_away(args.mesh, suffix, away)

    def report(event: Progress) -> None:
        if not args.quiet:
            print(f"  {in_unit(str(event), unit)}", file=sys.stderr)

    # OBJ and OFF hold float64 text: far from the origin they are compressed about a centre.
    run = compress_in_frame if suffix in _FLOAT64_FORMATS else compress
    result = run(
        mesh,
        size=None if args.size is None else parse_size(args.size),
        error=args.error,
        vertices=args.vertices,
        relative=args.relative,
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
        progress=report,
    )
    file_bytes = None
    if output is not None:
        if suffix in _FORMATS:
            result.write(output)
        else:
            save_mesh(output, result.vertices, result.faces)
        file_bytes = output.stat().st_size
    payload = {
        "mesh": str(args.mesh),
        "output": str(output) if output else None,
        "file_bytes": file_bytes,
        "budget_text": _budget_text(args),
        "budget_unit": _budget_unit(args, unit),
        **({} if away is None else {"merged_away": away}),
        **result.to_dict(),
    }
    payload["message"] = in_unit(payload["message"], unit)
    if args.json:
        _print_json(payload, args.mesh)
    else:
        first = result.plan
        _print_table(
            f"{args.mesh}: {_vertices_text(len(mesh[0]), result.complexity.merged_vertices)}, "
            f"{len(mesh[1])} faces; "
            f"K = {result.complexity.k:.4g}, S = {result.complexity.grid_size:.6g}",
            [
                ("budget", f"{_budget_text(args)} ({_budget_in_units(result, unit)})"),
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
                    str(output)
                    + ("" if result.met else " (the closest result: the budget was not met)")
                    if output
                    else "(not written: use -o)",
                ),
            ],
        )
        print(in_unit(result.message, unit))
        if suffix in _UNSIZED_FORMATS and file_bytes is not None:
            print(
                f"wrote {output}: {file_bytes} bytes ({suffix[1:]} of the decoded mesh; "
                f"the bytes above are the {result.format} encoding the search sized)"
            )
    return EXIT_OK if result.met else EXIT_UNMET


def _is_scene_file(path: Path) -> bool:
    """A .glb or .gltf input: compressed as a scene, as ``-o x.glb`` would write it."""
    return path.suffix.lower() in _SCENE_FORMATS


def _run_compress_scene(args: argparse.Namespace) -> int:
    """compress to .glb / .gltf (or, without ``-o``, a .glb / .gltf input, nothing
    written): the whole scene, primitive by primitive."""
    from .scene import NORMAL_TOLERANCE_DEGREES, compress_scene

    merged = (
        " (-o x.drc or -o x.ply compresses the scene's meshes merged into one)"
        if args.output is None
        else ""
    )
    if args.vertices is not None:
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
    _output(args.output, args.mesh)
    _input(args.mesh)
    _note_unit(args, args.mesh)
    unit = length_unit_of(args.mesh)

    def report(event: Progress) -> None:
        if not args.quiet:
            print(f"  {in_unit(str(event), unit)}", file=sys.stderr)

    result = compress_scene(
        args.mesh,
        error=args.error,
        size=None if args.size is None else parse_size(args.size),
        relative=args.relative,
        codec=args.codec,
        normal_tolerance=(
            NORMAL_TOLERANCE_DEGREES if args.normal_tolerance is None else args.normal_tolerance
        ),
        output=args.output,
        seed=args.seed,
        certify=args.certify,
        progress=report,
    )
    payload = {
        "input": str(args.mesh),
        "output": None if args.output is None else str(args.output),
        **result.to_dict(),
        "budget_text": _budget_text(args),
        "budget_unit": _budget_unit(args, unit),
    }
    payload["message"] = in_unit(payload["message"], unit)
    if args.json:
        _print_json(payload, args.mesh)
        return EXIT_OK if result.met else EXIT_UNMET
    target = "(not written: use -o x.glb)" if args.output is None else str(args.output)
    if args.output is not None and args.output.suffix.lower() == ".gltf":
        target += f" and {args.output.with_suffix('.bin').name}"
    print(
        f"{args.mesh} -> {target} ({result.codec}): {result.input_bytes} -> "
        f"{result.size_bytes} bytes; budget {_budget_text(args)}"
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
    return EXIT_OK if result.met else EXIT_UNMET


def _add_batch(sub: argparse._SubParsersAction) -> None:
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
    budget = p.add_mutually_exclusive_group(required=True)
    budget.add_argument(
        "--error",
        type=_length,
        help="Hausdorff error budget of every input: a length in the files' units, or with "
        "a unit for files in meters (1mm); a fraction of each input's S with --relative",
    )
    budget.add_argument(
        "--size", type=_size_text, help="size budget of every output, with a unit: 100KB"
    )
    p.add_argument(
        "--relative", action="store_true", help="--error is a fraction of each input's S"
    )
    p.add_argument(
        "--format",
        choices=("drc", "ply", "glb", "gltf"),
        default="drc",
        help="output format: drc (Draco, default) or ply, one merged mesh per input; glb or "
        "gltf, the whole scene with --codec",
    )
    p.add_argument(
        "--codec",
        choices=("draco", "meshopt"),
        default="draco",
        help="for glb/gltf: KHR_draco_mesh_compression (default) or EXT_meshopt_compression",
    )
    p.add_argument(
        "--workers",
        type=_count(1),
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
    p.add_argument("--seed", type=_count(0), default=0, help="seed of the samples (default 0)")
    p.add_argument(
        "--max-iterations",
        type=_count(1),
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
    from .batch import BatchInterrupted, batch

    _check_relative(args)
    if args.dask is not None and args.workers is not None:
        raise UserError("give --workers or --dask, not both (--dask local:N sets the workers)")
    try:
        result = batch(
            args.input,
            args.output,
            error=args.error,
            size=args.size,
            relative=args.relative,
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


def _print_batch(result: Any, args: argparse.Namespace) -> None:
    from .batch.report import bytes_text as _bytes_text

    if args.json:
        _print_json(result.to_dict())
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
        f"  {_bytes_text(result.input_bytes)} -> {_bytes_text(result.output_bytes)} (saved "
        f"{_bytes_text(result.saved_bytes)}{ratio}) in {result.seconds:.1f} s {where}"
    )
    print(f"  report: {result.report}")
    plot = f", plot: {result.plot}" if result.plot else ", no plot (it needs matplotlib)"
    print(f"  summary: {result.summary}{plot}")
    failed = [r for r in result.rows if r.status != "met"]
    for row in failed[:_BATCH_LISTED]:
        print(f"  {row.status}: {row.relative}: {row.message}")
    if len(failed) > _BATCH_LISTED:
        print(f"  ... and {len(failed) - _BATCH_LISTED} more (see the report)")


def _add_info(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "info",
        help="what a scene or mesh file holds: meshes, primitives, attributes, materials, "
        "images, extensions, bytes by part",
    )
    p.add_argument("file", type=Path, help="glTF (.glb/.gltf), OBJ, PLY, STL, ...")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(run=_run_info)


def _run_info(args: argparse.Namespace) -> int:
    from .scene import scene_info

    info = scene_info(_input(args.file))
    # Another format is read as the glTF scene trimesh converts it to: its counts are the
    # file's, its bytes by part and JSON those of that scene.
    converted = args.file.suffix.lower() not in (".glb", ".gltf")
    if args.json:
        _print_json({**info, "converted_to_gltf": converted}, args.file)
        return EXIT_OK
    kind = f" ({args.file.suffix.lstrip('.').upper()}, read as a glTF scene)" if converted else ""
    print(f"{info['file']}: {info['bytes']} bytes{kind}")
    counts = {
        "mesh": len(info["meshes"]),
        "node": info["nodes"],
        "scene": info["scenes"],
        "material": info["materials"],
        "texture": info["textures"],
        "image": len(info["images"]),
        "skin": info["skins"],
        "animation": info["animations"],
        "camera": info["cameras"],
    }
    print(
        "  "
        + ", ".join(
            f"{n} {word if n == 1 else word + ('es' if word == 'mesh' else 's')}"
            for word, n in counts.items()
        )
    )
    if info["extensions_used"]:
        print(f"  extensions: {', '.join(info['extensions_used'])}")
    if not converted:
        parts = ", ".join(f"{k} {v}" for k, v in info["bytes_by_part"].items())
        print(f"  bytes by part: {parts}, JSON {info['json_bytes']}")
    for mesh in info["meshes"]:
        for prim in mesh["primitives"]:
            attributes = ", ".join(f"{k} ({v})" for k, v in prim["attributes"].items())
            extras = f"; {', '.join(prim['extensions'])}" if prim["extensions"] else ""
            if prim.get("non_finite_positions"):
                count = prim["non_finite_positions"]
                extras += f"; {count} position{'s' if count > 1 else ''} NaN or infinite"
            if prim.get("zero_area_faces"):
                count = prim["zero_area_faces"]
                extras += f"; {count} face{'s' if count > 1 else ''} of zero area"
            if prim["morph_targets"]:
                count = prim["morph_targets"]
                names = ", ".join(prim["morph_target_attributes"])
                extras += f"; {count} morph target{'s' if count > 1 else ''} ({names})"
            distinct = prim.get("distinct_vertices", prim["vertices"])
            print(
                f"  mesh {mesh['mesh']} {mesh['name'] or ''} primitive {prim['primitive']}: "
                f"{_vertices_text(prim['vertices'], prim['vertices'] - distinct)}, "
                f"{prim['faces']} face{'' if prim['faces'] == 1 else 's'}; {attributes}{extras}"
            )
    for skin in info["skin_details"]:
        print(f"  skin {skin['skin']} {skin['name'] or ''}: {skin['joints']} joints")
    for animation in info["animation_details"]:
        paths = ", ".join(f"{path} {n}" for path, n in animation["paths"].items())
        count = animation["channels"]
        print(
            f"  animation {animation['animation']} {animation['name'] or ''}: {count} "
            f"channel{'' if count == 1 else 's'} ({paths}), {animation['keyframes']} "
            f"keyframes, {animation['duration']:.4g} s"
        )
    for image in info["images"]:
        size = "x".join(map(str, image["size"])) if image["size"] else "?"
        print(f"  image {image['image']}: {image['mimeType']}, {size}, {image['bytes']} bytes")
    return EXIT_OK


def _budget_in_units(result: Any, unit: str) -> str:
    if result.constraint == "size":
        return f"{result.budget / 8:.6g} bytes"
    if result.constraint == "error":
        return f"{result.budget:.6g} {unit}"
    return f"{result.budget:.0f} vertices"


def _add_calibrate(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "calibrate",
        help="fit the size model's alpha and T to real Draco encodings of a mesh",
        description="Simplify MESH to a few vertex counts, encode each with Draco at several "
        "bit depths, and fit F = (3 alpha B + T) V (paper Eq. 1) to the measured sizes.",
    )
    p.add_argument("mesh", type=Path, help="mesh file (OBJ, PLY, STL, OFF, GLB, ...)")
    p.add_argument(
        "--vertices",
        type=_count(4),
        nargs="+",
        default=[500, 2000, 8000],
        help="vertex counts to simplify to (default 500 2000 8000)",
    )
    p.add_argument(
        "--bits",
        type=_bits(FORMAT_MAX_BITS["draco"]),
        nargs="+",
        default=[6, 8, 10, 12, 14, 16],
        help="bits per coordinate to encode each level at (default 6 8 10 12 14 16)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(run=_run_calibrate)


def _run_calibrate(args: argparse.Namespace) -> int:
    from .encode import encode_draco, fit_size_model
    from .simplify import simplify

    if len(set(args.bits)) < 2:
        raise UserError("--bits needs two or more distinct values to fit alpha and T")
    mesh = load_mesh(_input(args.mesh))
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
        _print_json(payload)
    else:
        _print_table(
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


def _b0_arg(text: str) -> float | str:
    if text in ("derived", "paper"):
        return text
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected 'derived', 'paper' or a number, got {text!r}"
        ) from None


def _add_plan(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "plan",
        help="optimal bits per coordinate B and vertex count V for a budget (paper Sec. 6)",
        description="Compute K of MESH, then the B and V of least error for a size, of least "
        "size for an error, or the best B for a vertex count.",
    )
    p.add_argument("mesh", type=Path, help="mesh file (OBJ, PLY, STL, OFF, GLB, ...)")
    budget = p.add_mutually_exclusive_group(required=True)
    budget.add_argument(
        "--size",
        type=_size_text,
        help="file size budget with a unit: 100KB, 2MiB, 800kbit (B = bytes)",
    )
    budget.add_argument(
        "--error",
        type=_length,
        help="error budget: a length in the file's units (0.002), or with a unit for files "
        "in meters, as glTF is (1mm); a fraction of S with --relative",
    )
    budget.add_argument("--vertices", type=_positive_number, help="vertex count V")
    p.add_argument(
        "--relative",
        action="store_true",
        help="--error is a fraction of S, the largest bounding-box side",
    )
    p.add_argument(
        "--format",
        choices=("draco", "glb", "ply"),
        default="draco",
        help="the output whose size is modelled: draco (default) for compress's .drc and "
        ".glb/.gltf with the Draco codec, F = (3 alpha B + T) V with Draco's fitted "
        "alpha = 0.595, T = 0, compress's own first plan; ply (compress -o x.ply) and glb "
        "(quantized positions without a codec, compress(format='glb') in Python) store "
        "fixed-width positions, so B costs nothing up to the format's most (24, 16) and the "
        "budget buys V. The meshopt codec has no size model here",
    )
    p.add_argument(
        "--alpha",
        type=_positive_number,
        default=None,
        help="draco: size model alpha, bits per coordinate bit, in (0, 1] "
        "(default: fitted to Draco, 0.595; the paper's is 1)",
    )
    p.add_argument(
        "--connectivity-bits",
        type=float,
        default=None,
        help="draco: size model T, bits per vertex for connectivity, >= 0 "
        "(default: fitted to Draco, 0; the paper's is 4)",
    )
    p.add_argument(
        "--method",
        choices=METHODS,
        default="exact",
        help="exact: the ridge of the exact E(B, V); asymptotic: the paper's closed forms",
    )
    p.add_argument(
        "--b0",
        type=_b0_arg,
        default="derived",
        help="B0 of the asymptotic method: derived (1.6412), paper (1.838) or a number",
    )
    p.add_argument("--estimator", choices=ESTIMATORS, default="circumsphere", help="estimator of K")
    p.add_argument("--no-merge", action="store_true", help="do not weld identical vertices")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(run=_run_plan)


def _run_plan(args: argparse.Namespace) -> int:
    _check_relative(args)
    _check_size_model(args)
    _note_unit(args, args.mesh)
    report = _complexity_report(args.mesh, args)
    k, grid_size = report["k"], report["grid_size"]
    if k is None or not k > 0:
        raise UserError(f"K of {args.mesh} is {k}: a flat or open mesh has no plan")
    if args.format != "draco":
        if args.alpha is not None or args.connectivity_bits is not None:
            raise UserError(
                f"--alpha and --connectivity-bits model Draco; --format {args.format} stores "
                "fixed-width positions"
            )
        return _plan_fixed_width(args, report)
    options = {
        "grid_size": grid_size,
        "alpha": DRACO_ALPHA if args.alpha is None else args.alpha,
        "connectivity_bits": (
            DRACO_CONNECTIVITY_BITS if args.connectivity_bits is None else args.connectivity_bits
        ),
        "method": args.method,
        "b0": args.b0,
    }
    if args.size is not None:
        budget_text = args.size
        try:
            plan = plan_for_size(parse_size(args.size), k, **options)
        except MeshbitsError as err:
            raise UserError(f"--size {args.size}: {err}") from None
    elif args.error is not None:
        error = args.error * grid_size if args.relative else args.error
        budget_text = f"{args.error:g}" + (
            " x S" if args.relative else f" ({length_unit_of(args.mesh)})"
        )
        if error >= grid_size:
            raise UserError(
                f"--error {args.error:g}{' --relative' if args.relative else ''} is not below "
                f"the grid size S = {grid_size:.6g}: any single vertex meets it"
            )
        plan = plan_for_error(error, k, **options)
    else:
        budget_text = f"{args.vertices:g}"
        plan = plan_for_vertices(args.vertices, k, **options)
    if args.json:
        _print_json(
            {
                "mesh": report["mesh"],
                "mesh_vertices": report["vertices"],
                "mesh_faces": report["faces"],
                "estimator": report["estimator"],
                **plan.to_dict(),
                **_size_units(
                    plan.file_size,
                    plan.whole_file_size,
                    {"size": "bits", "vertices": "vertices"}.get(
                        plan.constraint, length_unit_of(args.mesh)
                    ),
                ),
            },
            args.mesh,
        )
        return EXIT_OK
    counts = _vertices_text(report["vertices"], report.get("merged_vertices"))
    print(f"{report['mesh']}: {counts}, {report['faces']} faces")
    unit = length_unit_of(args.mesh)
    print(f"  K = {k:.6g} (grid, {report['estimator']}), S = {grid_size:.6g} ({unit})")
    method = plan.method if plan.b0 is None else f"{plan.method}, B0 = {plan.b0:.4g}"
    print(f"  constraint: {plan.constraint} = {budget_text} (method {method})")
    header = (
        "",
        "B (bits)",
        "V",
        "F (bits)",
        *(f"{e} ({unit})" for e in ("E_Q", "E_T", "E")),
        "E/S",
    )
    rows = [
        (
            "continuous",
            f"{plan.bits:.4f}",
            plan.vertices,
            plan.file_size,
            plan.quantization_error,
            plan.tessellation_error,
            plan.error,
        ),
        (
            "whole bits",
            str(plan.whole_bits),
            plan.whole_vertices,
            plan.whole_file_size,
            plan.whole_quantization_error,
            plan.whole_tessellation_error,
            plan.whole_error,
        ),
    ]
    table = [header] + [
        (
            name,
            b,
            f"{v:.1f}",
            f"{f:.6g}",
            f"{q:.4g}",
            f"{t:.4g}",
            f"{e:.4g}",
            f"{e / grid_size:.4g}",
        )
        for name, b, v, f, q, t, e in rows
    ]
    widths = [max(len(row[i]) for row in table) for i in range(len(header))]
    for row in table:
        print(
            "  "
            + "  ".join(
                cell.rjust(w) if i else cell.ljust(w)
                for i, (cell, w) in enumerate(zip(row, widths, strict=True))
            )
        )
    print(
        f"  plan: keep about {round(plan.whole_vertices)} vertices, quantize to "
        f"{plan.whole_bits} bit{'' if plan.whole_bits == 1 else 's'} per coordinate "
        f"({plan.whole_file_size / 8000:.4g} kB)"
    )
    if plan.whole_vertices > report["vertices"]:
        print(f"  note: the mesh has only {report['vertices']} vertices")
    if not plan.in_model_domain:
        print(f"  warning: outside the model's domain: {plan.domain_reason}")
    return EXIT_OK


def _size_units(file_size: float, whole: float | None, budget_unit: str | None) -> dict[str, Any]:
    """The JSON keys that name the unit of a plan's sizes (bits, the paper's F) and of its
    budget, with the sizes in bytes too."""
    units: dict[str, Any] = {"size_unit": "bits", "file_size_bytes": file_size / 8}
    if whole is not None:
        units["whole_file_size_bytes"] = whole / 8
    if budget_unit is not None:
        units["budget_unit"] = budget_unit
    return units


def _plan_fixed_width(args: argparse.Namespace, report: dict[str, Any]) -> int:
    """``plan --format glb|ply``: positions stored in fixed-width fields cost the same at
    every ``B`` up to the format's most, so ``B`` is that most and the budget buys ``V``
    (sizes from :func:`meshbits.encode.fixed_width_size_bits`, errors from Eq. 2 and 10)."""
    k, grid_size, fmt = report["k"], report["grid_size"], args.format
    bits = FORMAT_MAX_BITS[fmt]
    # A triangle soup (STL) counts each vertex once per face: its welded vertices are the
    # mesh's.
    welded = report["vertices"] - (report.get("merged_vertices") or 0)
    faces_per_vertex = report["faces"] / max(welded, 1)

    def size_at(v: float) -> float:
        return fixed_width_size_bits(fmt, bits, v, v * faces_per_vertex)

    quantization = float(model.quantization_error(bits, grid_size))
    unit = length_unit_of(args.mesh)
    if args.size is not None:
        budget_text, budget = args.size, parse_size(args.size)
        budget_value, budget_unit = budget, "bits"
        if budget < size_at(MODEL_MIN_VERTICES):
            raise UserError(
                f"--size {args.size} cannot hold a tetrahedron in {fmt}: the smallest is "
                f"{size_at(MODEL_MIN_VERTICES) / 8:,.0f} bytes"
            )
        lo, hi = MODEL_MIN_VERTICES, budget  # size_at is increasing in V
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if size_at(mid) <= budget else (lo, mid)
        vertices = lo
    elif args.error is not None:
        error = args.error * grid_size if args.relative else args.error
        budget_text = f"{args.error:g}" + (" x S" if args.relative else f" ({unit})")
        budget_value, budget_unit = float(error), unit
        if error <= quantization:
            raise UserError(
                f"--error {args.error:g} is not above {fmt}'s quantization error at {bits} "
                f"bits, {quantization:.4g} ({unit})"
            )
        if error >= grid_size:
            raise UserError(f"--error is not below the grid size S = {grid_size:.6g}")
        vertices = float(model.vertices_for_error(error - quantization, k, grid_size))
    else:
        budget_text, vertices = f"{args.vertices:g}", float(args.vertices)
        budget_value, budget_unit = float(args.vertices), "vertices"
    tessellation = float(model.tessellation_error(vertices, k, grid_size))
    plan = {
        "format": fmt,
        "constraint": "size" if args.size else "error" if args.error else "vertices",
        "budget": budget_value,
        "budget_text": budget_text,
        "bits": bits,
        "vertices": vertices,
        "file_size": size_at(vertices),
        **_size_units(size_at(vertices), None, budget_unit),
        "quantization_error": quantization,
        "tessellation_error": tessellation,
        "error": quantization + tessellation,
        "k": k,
        "grid_size": grid_size,
    }
    if args.json:
        _print_json(
            {
                "mesh": report["mesh"],
                "mesh_vertices": report["vertices"],
                "mesh_faces": report["faces"],
                "estimator": report["estimator"],
                **plan,
            },
            args.mesh,
        )
        return EXIT_OK
    counts = _vertices_text(report["vertices"], report.get("merged_vertices"))
    print(f"{report['mesh']}: {counts}, {report['faces']} faces")
    print(f"  K = {k:.6g} (grid, {report['estimator']}), S = {grid_size:.6g} ({unit})")
    print(f"  constraint: {plan['constraint']} = {budget_text} ({fmt}: fixed-width positions)")
    _print_table(
        f"  {fmt} stores any B up to {bits} in the same bytes: B = {bits}",
        [
            ("V", f"{vertices:.1f}"),
            ("F (bits)", f"{plan['file_size']:.6g}"),
            (f"E_Q ({unit})", f"{quantization:.4g}"),
            (f"E_T ({unit})", f"{tessellation:.4g}"),
            (f"E ({unit})", f"{plan['error']:.4g}"),
            ("E/S", f"{plan['error'] / grid_size:.4g}"),
        ],
    )
    print(
        f"  plan: keep about {round(vertices)} vertices at {bits} bits per coordinate "
        f"({plan['file_size'] / 8000:.4g} kB)"
    )
    if vertices > report["vertices"]:
        print(f"  note: the mesh has only {report['vertices']} vertices")
    return EXIT_OK


def _add_hausdorff(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "hausdorff",
        help="sampled Hausdorff distance between two meshes (paper Sec. 3.2, the error E)",
    )
    p.add_argument("a", type=Path, help="first mesh file")
    p.add_argument("b", type=Path, help="second mesh file")
    p.add_argument(
        "--samples",
        type=_count(0),
        default=None,
        help="area samples per mesh, on top of the vertices "
        "(default: 10 per face, clamped to [10000, 1000000])",
    )
    p.add_argument("--seed", type=_count(0), default=0, help="seed of the samples (default 0)")
    p.add_argument(
        "--tolerance",
        type=_positive_number,
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
        type=_count(0),
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
        type=_positive_number,
        default=None,
        help="distance of the top colour (default: largest)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(run=_run_hausdorff)


def _progress(message: object) -> None:
    print(f"meshbits hausdorff: {message}", file=sys.stderr, flush=True)


def _run_hausdorff(args: argparse.Namespace) -> int:
    _output(args.colors, args.a, args.b)
    if args.colors is not None and args.colors.suffix.lower() != ".ply":
        raise UserError(
            f"cannot write {args.colors}: --colors writes a PLY with vertex colours; name it .ply"
        )
    if args.colors is not None:
        _need_matplotlib("--colors")
        _output(args.colors.with_name(args.colors.stem + "_colorbar.png"))
    for path in (args.a, args.b):
        _input(path)
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
        _print_json(report, gltf[0] if gltf else args.a)
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
    _print_table(f"{args.a} vs {args.b} (seed {result.seed}; lengths in {unit})", rows)
    return EXIT_OK


def _add_quantize(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "quantize",
        help="quantize a mesh to B bits per coordinate and cluster its vertices (Sec. 1.1)",
    )
    p.add_argument("mesh", type=Path, help="mesh file (OBJ, PLY, STL, OFF, GLB, ...)")
    p.add_argument(
        "--bits", type=_bits(MAX_BITS), required=True, help=f"bits per coordinate, 1 to {MAX_BITS}"
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
    _output(args.output, args.mesh)
    if args.output is not None and args.output.suffix.lower() not in _MESH_OUTPUTS:
        raise UserError(
            f"{args.output}: cannot write {args.output.suffix or 'a file without a suffix'}; "
            f"write a mesh: {', '.join(_MESH_OUTPUTS)}"
        )
    vertices, faces = load_mesh(_input(args.mesh))
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
        _print_json(report, args.mesh)
        return EXIT_OK
    unit = length_unit_of(args.mesh)
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
            (f"grid size S ({unit})", result.grid_size),
            (f"step ({unit})", " ".join(f"{s:.6g}" for s in result.step)),
            (f"bound 0.5|step| ({unit})", result.bound),
            (f"max displacement ({unit})", result.max_displacement),
            ("written to", report["output"] or "-"),
        ],
    )
    return EXIT_OK


def _write_colors(
    a: tuple[Any, Any], b: tuple[Any, Any], args: argparse.Namespace
) -> dict[str, Any]:
    """Colour A's vertices by their exact distance to B (``meshbits plot.error_map``)."""
    from .hausdorff import ClosestPoints
    from .plot import error_map

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


def _add_plot(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "plot",
        help="draw the paper's Fig. 1 for a mesh: iso-error and iso-size curves over (V, B) "
        "with the optimal B(V) (needs matplotlib)",
    )
    p.add_argument("mesh", type=Path, help="mesh file")
    p.add_argument("-o", "--output", type=Path, required=True, help="PNG to write")
    p.add_argument(
        "--alpha",
        type=_positive_number,
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


def _need_matplotlib(what: str) -> None:
    """Refuse, before any work, an option that draws when matplotlib is missing."""
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise UserError(f"{what} needs matplotlib: pip install 'meshbits[plot]'") from None


def _run_plot(args: argparse.Namespace) -> int:
    from .compress import welded_vertex_count
    from .plot import error_surface

    _need_matplotlib("meshbits plot")
    _check_size_model(args)
    _output(args.output, args.mesh)
    if args.output.suffix.lower() != ".png":
        raise UserError(f"cannot write {args.output}: plot writes a PNG image; name it .png")
    vertices, faces = load_mesh(_input(args.mesh))
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
        _print_json(report)
    else:
        print(
            f"wrote {args.output} (K = {k.k:.4g}, V = {n}: the vertices its faces use, "
            f"identical positions welded; optimal B = {plan.bits:.2f})"
        )
    return EXIT_OK


_COMMANDS: tuple[Callable[[argparse._SubParsersAction], None], ...] = (
    _add_k,
    _add_info,
    _add_demo,
    _add_plan,
    _add_compress,
    _add_batch,
    _add_calibrate,
    _add_hausdorff,
    _add_quantize,
    _add_plot,
)


class _UsageError(Exception):
    """A command line that does not parse: its one-line message."""


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line on stderr, exit code 2 (and,
    with ``--json``, a JSON object on stdout: see :func:`main`)."""

    def error(self, message: str) -> NoReturn:
        raise _UsageError(f"{self.prog}: error: {message} (see {self.prog} --help)")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="meshbits",
        description="How many vertices, and how many bits per coordinate, should a mesh keep?",
        epilog="Exit codes: 0 done (budget met), 1 budget not met, 2 bad input, "
        "3 internal error, 130 interrupted.",
    )
    parser.add_argument("--version", action="version", version=f"meshbits {__version__}")
    debug_help = "on an internal error, print the whole traceback"
    parser.add_argument("--debug", action="store_true", help=debug_help)
    sub = parser.add_subparsers(dest="command", required=True)
    for add in _COMMANDS:
        add(sub)
    for command in sub.choices.values():
        # Also after the subcommand; SUPPRESS keeps the main parser's value when absent.
        command.add_argument(
            "--debug", action="store_true", default=argparse.SUPPRESS, help=debug_help
        )
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``meshbits`` program; returns the exit code (see the module
    docstring)."""
    parser = build_parser()
    words = list(sys.argv[1:] if argv is None else argv)
    try:
        args = parser.parse_args(words)
    except SystemExit as done:  # --help or --version, already printed
        return done.code if isinstance(done.code, int) else EXIT_BAD_INPUT
    except _UsageError as err:
        print(err, file=sys.stderr)
        if "--json" in words:
            _print_json({"error": str(err), "exit_code": EXIT_BAD_INPUT})
        return EXIT_BAD_INPUT
    where = f"meshbits {args.command}"
    try:
        return int(args.run(args))
    except BrokenPipeError:
        # The reader of stdout went away (``| head``): no traceback, nothing more to say.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_BROKEN_PIPE
    except KeyboardInterrupt:
        print(f"{where}: interrupted", file=sys.stderr)
        return _failed(args, "interrupted", EXIT_INTERRUPTED)
    except (UserError, MeshbitsError, OSError) as err:
        # Refused input, an unusable file, or a file system that refused a read or write.
        message = _one_line(err)
        mesh = getattr(args, "mesh", None)
        if isinstance(err, MeshbitsError) and isinstance(mesh, Path) and mesh.name not in message:
            # Found in the mesh once read (no surface, a budget it cannot meet...): name it.
            message = f"{mesh.name}: {message}"
        print(f"{where}: error: {message}", file=sys.stderr)
        return _failed(args, message, EXIT_BAD_INPUT)
    except Exception as err:
        if args.debug:
            traceback.print_exc()
        print(
            f"{where}: internal error (a bug in meshbits {__version__}, please report it): "
            f"{type(err).__name__}: {_one_line(err)}"
            + ("" if args.debug else "; rerun with --debug for the traceback"),
            file=sys.stderr,
        )
        return _failed(
            args, f"internal error: {type(err).__name__}: {_one_line(err)}", EXIT_INTERNAL
        )


def _failed(args: argparse.Namespace, message: str, code: int) -> int:
    """With ``--json``, a failure is a JSON object on stdout too (``error``, ``exit_code``),
    so that a pipeline reading stdout gets a document either way; returns ``code``."""
    if getattr(args, "json", False):
        _print_json({"error": message, "exit_code": code})
    return code


def _one_line(err: BaseException) -> str:
    text = " ".join(str(err).split())
    return text or type(err).__name__


if __name__ == "__main__":
    sys.exit(main())
