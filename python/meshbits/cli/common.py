"""What every ``meshbits`` command shares: exit codes, the one-line refusal
(:class:`UserError`), printing (strict JSON, tables), argument types, input and output
checks, and the ONE budget argument group (``--size``/``--error``/``--vertices``/
``--relative``) with the :class:`meshbits.budget.Budget` built from it."""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from ..budget import Budget
from ..complexity import shape_complexity
from ..errors import MeshbitsError
from ..files import check_not_an_input, check_writable
from ..formats import read_mesh
from ..results import json_ready
from ..units import length_unit_of, parse_length, parse_size

EXIT_OK, EXIT_UNMET, EXIT_BAD_INPUT, EXIT_INTERNAL, EXIT_INTERRUPTED = 0, 1, 2, 3, 130


#: Ended by SIGTERM (128 + 15), after removing what it was writing.
EXIT_TERMINATED = 143

#: The reader of stdout closed it (``| head``): the code of a process ended by SIGPIPE.
EXIT_BROKEN_PIPE = 141


class UserError(Exception):
    """A problem with the command's input, reported in one line with exit code 2."""


def print_json(payload: dict[str, Any], lengths_of: Path | None = None) -> None:
    """Print ``payload`` as strict JSON; with ``lengths_of``, after its first key the unit
    of the lengths reported on that file (``length_unit``)."""
    if lengths_of is not None:
        first, *rest = payload.items()
        payload = dict([first, ("length_unit", length_unit_of(lengths_of)), *rest])
    print(json.dumps(json_ready(payload), indent=2, allow_nan=False))


def positive_number(text: str) -> float:
    """An argparse type: a positive finite number, refused with the text as typed."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a positive finite number, got {text!r}")
    return value


class Length(float):
    """A length read from the command line, with the text it was given as."""

    text: str = ""


def length(text: str) -> float:
    """An argparse type: a positive length, plain (the file's units) or with a unit
    (meters, glTF's unit: 1mm = 0.001)."""
    try:
        value = Length(parse_length(text))
    except MeshbitsError as err:
        raise argparse.ArgumentTypeError(str(err)) from None
    value.text = text.strip()
    return value


def count(smallest: int) -> Callable[[str], int]:
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


def size_text(text: str) -> str:
    """An argparse type: a size with a unit, checked and kept as typed."""
    try:
        parse_size(text)
    except MeshbitsError as err:
        raise argparse.ArgumentTypeError(str(err)) from None
    return text


def bit_depth(largest: int) -> Callable[[str], int]:
    """An argparse type: bits per coordinate, 1 to ``largest``."""
    whole = count(1)

    def parse(text: str) -> int:
        value = whole(text)
        if value > largest:
            raise argparse.ArgumentTypeError(f"must be at most {largest}, got {text!r}")
        return value

    return parse


#: The help of the budget arguments, one text each for every command that takes them.
BUDGET_HELP = {
    "size": "file size budget with a unit: 100KB, 2MiB, 800kbit (B = bytes)",
    "error": "Hausdorff error budget: a length in the file's units (0.002), or with a unit "
    "for files in meters, as glTF is (1mm, 0.5cm, 2in); a fraction of S with --relative",
    "vertices": "vertex count V (at least 4)",
    "relative": "--error is a fraction of S, the largest bounding-box side",
}


def add_budget_arguments(
    parser: argparse.ArgumentParser, *, vertices: bool = True, fractional_vertices: bool = False
) -> None:
    """The budget of a command: exactly one of ``--size``, ``--error`` and (with
    ``vertices``) ``--vertices``, and ``--relative``. ``fractional_vertices``: V is a real
    number of the model (``plan``), else a whole count of at least 4."""
    group = parser.add_mutually_exclusive_group(required=True)
    group.add_argument("--size", type=size_text, help=BUDGET_HELP["size"])
    group.add_argument("--error", type=length, help=BUDGET_HELP["error"])
    if vertices:
        group.add_argument(
            "--vertices",
            type=positive_number if fractional_vertices else count(4),
            help=BUDGET_HELP["vertices"],
        )
    parser.add_argument("--relative", action="store_true", help=BUDGET_HELP["relative"])


def budget_from_args(args: argparse.Namespace, length_unit: str = "mesh units") -> Budget:
    """The budget of the command line (``--relative`` checked first), reported as typed
    (``budget_text``: ``"--error 1mm --relative"``) in ``length_unit`` for an error."""
    check_relative(args)
    vertices = getattr(args, "vertices", None)
    return Budget.from_options(
        error=args.error,
        size=None if args.size is None else parse_size(args.size),
        vertices=vertices,
        relative=args.relative,
        length_unit=length_unit,
        text=budget_options_text(args),
    )


def budget_options_text(args: argparse.Namespace) -> str:
    """The budget as the user typed it (an error with a unit, in meters)."""
    if args.size is not None:
        return f"--size {args.size}"
    if args.error is not None:
        typed = getattr(args.error, "text", f"{args.error:g}")
        return f"--error {typed}" + (" --relative" if args.relative else "")
    return f"--vertices {args.vertices}"


def check_relative(args: argparse.Namespace) -> None:
    """``--relative`` only with an ``--error`` typed without a unit."""
    if args.relative and args.error is None:
        raise UserError("--relative applies to --error only")
    text = getattr(args.error, "text", "")
    if args.relative and text[-1:].isalpha():
        raise UserError(
            f"--error {text} has a unit, and --relative makes it a fraction of S: "
            "give a plain number with --relative, or drop --relative"
        )


def note_unit(args: argparse.Namespace, path: Path) -> None:
    """Say how an error given with a unit is read from a file format without units."""
    text = getattr(args.error, "text", "")
    if text and text[-1:].isalpha() and path.suffix.lower() not in (".glb", ".gltf"):
        print(
            f"note: --error {text} is read as {float(args.error):g} in the units of "
            f"{path.name}, taken as meters (glTF's unit): this format carries no unit",
            file=sys.stderr,
        )


def output_file(path: Path | None, *inputs: Path | None) -> Path | None:
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


def check_size_model(args: argparse.Namespace) -> None:
    """``--alpha`` in (0, 1] and ``--connectivity-bits`` >= 0, when given."""
    if args.alpha is not None and args.alpha > 1:
        raise UserError(f"--alpha must be in (0, 1], got {args.alpha:g}")
    t = args.connectivity_bits
    if t is not None and not (math.isfinite(t) and t >= 0):
        raise UserError(f"--connectivity-bits must be a number >= 0, got {t:g}")


def input_file(path: Path) -> Path:
    """``path``, a mesh file that exists (a folder is refused: batch takes those)."""
    if path.is_dir():
        raise UserError(f"{path} is a folder, not a mesh file (meshbits batch takes folders)")
    if not path.is_file():
        raise UserError(f"no such mesh file: {path}")
    return path


def print_table(title: str, rows: Sequence[tuple[str, Any]]) -> None:
    """``title``, then a row per line: its name, padded, and its value (floats to 6
    significant digits)."""
    print(title)
    width = max(len(name) for name, _ in rows)
    for name, value in rows:
        if isinstance(value, float):
            value = f"{value:.6g}"
        print(f"  {name:<{width}}  {value}")


def complexity_report(path: Path, args: argparse.Namespace) -> dict[str, Any]:
    """K and its statistics for the mesh at ``path`` (``--estimator``, ``--no-merge``):
    the file read straight into the kernel's arrays (see :func:`read_mesh`), with what
    reading changed (``reader``; ``polygons`` fan-triangulated into ``polygon_triangles``
    and ``skipped_elements`` left out, when the Rust reader read it)."""
    read = read_mesh(input_file(path))
    result = shape_complexity(
        read.vertices, read.faces, estimator=args.estimator, merge_vertices=not args.no_merge
    )
    counts = {
        name: getattr(read, name)
        for name in ("polygons", "polygon_triangles", "skipped_elements")
        if getattr(read, name) is not None
    }
    return {
        "mesh": str(path),
        "vertices": len(read.vertices),
        "faces": len(read.faces),
        **result.to_dict(),
        "reader": read.reader,
        **counts,
    }


def vertices_text(vertices: int, merged: int | None) -> str:
    """ "N vertices", with the count once identical positions are welded when that differs
    (an STL stores every face's corners apart)."""
    welded = f" ({vertices - merged} once welded)" if merged else ""
    return f"{vertices} vertices{welded}"


def need_matplotlib(what: str) -> None:
    """Refuse, before any work, an option that draws when matplotlib is missing."""
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise UserError(f"{what} needs matplotlib: pip install 'meshbits[plot]'") from None
