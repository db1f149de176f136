"""``meshbits plan``: the optimal bits per coordinate B and vertex count V of a mesh for a
budget (paper Sec. 6), for Draco's size model or a fixed-width output (glb, ply)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from .. import model
from ..budget import Budget
from ..constants import DRACO_ALPHA, DRACO_CONNECTIVITY_BITS, ESTIMATORS, MODEL_MIN_VERTICES
from ..errors import MeshbitsError
from ..model import METHODS, plan_for_error, plan_for_size, plan_for_vertices
from ..planning import FixedWidthSizes, plan_fixed_width
from ..units import length_unit_of
from .common import (
    EXIT_OK,
    UserError,
    add_budget_arguments,
    budget_from_args,
    check_size_model,
    complexity_report,
    note_unit,
    positive_number,
    print_json,
    print_table,
    vertices_text,
)


def _b0_arg(text: str) -> float | str:
    """An argparse type: ``derived``, ``paper`` or a number."""
    if text in ("derived", "paper"):
        return text
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected 'derived', 'paper' or a number, got {text!r}"
        ) from None


def add_plan(sub: argparse._SubParsersAction) -> None:
    """Add the ``plan`` subcommand to ``sub``."""
    p = sub.add_parser(
        "plan",
        help="optimal bits per coordinate B and vertex count V for a budget (paper Sec. 6)",
        description="Compute K of MESH, then the B and V of least error for a size, of least "
        "size for an error, or the best B for a vertex count.",
    )
    p.add_argument("mesh", type=Path, help="mesh file (OBJ, PLY, STL, OFF, GLB, ...)")
    add_budget_arguments(p, fractional_vertices=True)
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
        type=positive_number,
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
    """Run ``meshbits plan``; returns the exit code."""
    budget = budget_from_args(args, length_unit_of(args.mesh))
    check_size_model(args)
    note_unit(args, args.mesh)
    report = complexity_report(args.mesh, args)
    k, grid_size = report["k"], report["grid_size"]
    if k is None or not k > 0:
        raise UserError(f"K of {args.mesh} is {k}: a flat or open mesh has no plan")
    if args.format != "draco":
        if args.alpha is not None or args.connectivity_bits is not None:
            raise UserError(
                f"--alpha and --connectivity-bits model Draco; --format {args.format} stores "
                "fixed-width positions"
            )
        return _plan_fixed_width(args, budget, report)
    options = {
        "grid_size": grid_size,
        "alpha": DRACO_ALPHA if args.alpha is None else args.alpha,
        "connectivity_bits": (
            DRACO_CONNECTIVITY_BITS if args.connectivity_bits is None else args.connectivity_bits
        ),
        "method": args.method,
        "b0": args.b0,
    }
    if budget.kind == "size":
        try:
            plan = plan_for_size(budget.value, k, **options)
        except MeshbitsError as err:
            raise UserError(f"--size {args.size}: {err}") from None
    elif budget.kind == "error":
        error = budget.resolve(grid_size)
        if error >= grid_size:
            raise UserError(
                f"{_error_text(budget)} is not below the grid size S = "
                f"{grid_size:.6g}: any single vertex meets it"
            )
        plan = plan_for_error(error, k, **options)
    else:
        plan = plan_for_vertices(budget.value, k, **options)
    if args.json:
        print_json(
            {
                **_mesh_keys(report),
                **plan.to_dict(),
                **_size_units(plan.file_size, plan.whole_file_size, budget.unit),
            },
            args.mesh,
        )
        return EXIT_OK
    _print_plan(args, report, plan, _plan_text(args, budget))
    return EXIT_OK


def _error_text(budget: Budget) -> str:
    """An error budget as its refusals name it: ``--error 0.5`` (``--relative``)."""
    return f"--error {budget.value:g}" + (" --relative" if budget.relative else "")


def _plan_text(args: argparse.Namespace, budget: Budget) -> str:
    """The budget as a plan states it: the size as typed, ``0.002 x S``, ``0.002 (m)``,
    or the vertex count."""
    if budget.kind == "size":
        return args.size
    if budget.kind == "error":
        return f"{budget.value:g}" + (" x S" if budget.relative else f" ({budget.unit})")
    return f"{budget.value:g}"


def _mesh_keys(report: dict[str, Any]) -> dict[str, Any]:
    """The JSON keys of a plan that describe its mesh."""
    return {
        "mesh": report["mesh"],
        "mesh_vertices": report["vertices"],
        "mesh_faces": report["faces"],
        "estimator": report["estimator"],
    }


def _print_plan(args: argparse.Namespace, report: dict[str, Any], plan: Any, text: str) -> None:
    """The text report of a Draco plan: K and S, the continuous and whole-bit optima."""
    k, grid_size = report["k"], report["grid_size"]
    counts = vertices_text(report["vertices"], report.get("merged_vertices"))
    print(f"{report['mesh']}: {counts}, {report['faces']} faces")
    unit = length_unit_of(args.mesh)
    print(f"  K = {k:.6g} (grid, {report['estimator']}), S = {grid_size:.6g} ({unit})")
    method = plan.method if plan.b0 is None else f"{plan.method}, B0 = {plan.b0:.4g}"
    print(f"  constraint: {plan.constraint} = {text} (method {method})")
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


def _size_units(file_size: float, whole: float | None, budget_unit: str | None) -> dict[str, Any]:
    """The JSON keys that name the unit of a plan's sizes (bits, the paper's F) and of its
    budget, with the sizes in bytes too."""
    units: dict[str, Any] = {"size_unit": "bits", "file_size_bytes": file_size / 8}
    if whole is not None:
        units["whole_file_size_bytes"] = whole / 8
    if budget_unit is not None:
        units["budget_unit"] = budget_unit
    return units


def _plan_fixed_width(args: argparse.Namespace, budget: Budget, report: dict[str, Any]) -> int:
    """``plan --format glb|ply``: positions stored in fixed-width fields cost the same at
    every ``B`` up to the format's most, so ``B`` is that most and the budget buys ``V``
    (:func:`meshbits.planning.plan_fixed_width`)."""
    k, grid_size, fmt = report["k"], report["grid_size"], args.format
    # A triangle soup (STL) counts each vertex once per face: its welded vertices are the
    # mesh's.
    welded = report["vertices"] - (report.get("merged_vertices") or 0)
    sizes = FixedWidthSizes(fmt, report["faces"] / max(welded, 1))
    unit = length_unit_of(args.mesh)
    if budget.kind == "size" and budget.value < sizes.size_bits(MODEL_MIN_VERTICES):
        raise UserError(
            f"--size {args.size} cannot hold a tetrahedron in {fmt}: the smallest is "
            f"{sizes.size_bits(MODEL_MIN_VERTICES) / 8:,.0f} bytes"
        )
    if budget.kind == "error":
        error = budget.resolve(grid_size)
        quantization = float(model.quantization_error(sizes.bits, grid_size))
        if error <= quantization:
            raise UserError(
                f"--error {budget.value:g} is not above {fmt}'s quantization error at "
                f"{sizes.bits} bits, {quantization:.4g} ({unit})"
            )
        if error >= grid_size:
            raise UserError(
                f"{_error_text(budget)} is not below the grid size S = {grid_size:.6g}: any "
                "single vertex meets it"
            )
    plan = plan_fixed_width(budget, k, grid_size, fmt, sizes.faces_per_vertex)
    text = _plan_text(args, budget)
    if args.json:
        print_json(
            {
                **_mesh_keys(report),
                "format": fmt,
                "constraint": plan.constraint,
                "budget": plan.budget,
                "budget_text": text,
                "bits": plan.bits,
                "vertices": plan.vertices,
                "file_size": plan.file_size,
                **_size_units(plan.file_size, None, budget.unit),
                "quantization_error": plan.quantization_error,
                "tessellation_error": plan.tessellation_error,
                "error": plan.error,
                "k": k,
                "grid_size": grid_size,
            },
            args.mesh,
        )
        return EXIT_OK
    counts = vertices_text(report["vertices"], report.get("merged_vertices"))
    print(f"{report['mesh']}: {counts}, {report['faces']} faces")
    print(f"  K = {k:.6g} (grid, {report['estimator']}), S = {grid_size:.6g} ({unit})")
    print(f"  constraint: {plan.constraint} = {text} ({fmt}: fixed-width positions)")
    print_table(
        f"  {fmt} stores any B up to {plan.bits} in the same bytes: B = {plan.bits}",
        [
            ("V", f"{plan.vertices:.1f}"),
            ("F (bits)", f"{plan.file_size:.6g}"),
            (f"E_Q ({unit})", f"{plan.quantization_error:.4g}"),
            (f"E_T ({unit})", f"{plan.tessellation_error:.4g}"),
            (f"E ({unit})", f"{plan.error:.4g}"),
            ("E/S", f"{plan.error / grid_size:.4g}"),
        ],
    )
    print(
        f"  plan: keep about {round(plan.vertices)} vertices at {plan.bits} bits per coordinate "
        f"({plan.file_size / 8000:.4g} kB)"
    )
    if plan.vertices > report["vertices"]:
        print(f"  note: the mesh has only {report['vertices']} vertices")
    return EXIT_OK
