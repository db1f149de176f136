"""``meshbits k`` (a mesh's shape complexity K) and ``meshbits info`` (what a scene or mesh
file holds)."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..constants import ESTIMATORS
from ..scene import scene_info
from ..units import length_unit_of
from .common import (
    EXIT_OK,
    complexity_report,
    input_file,
    print_json,
    print_table,
    vertices_text,
)


def add_k(sub: argparse._SubParsersAction) -> None:
    """The ``k`` subcommand."""
    p = sub.add_parser("k", help="shape complexity K of a mesh (paper Sec. 4)")
    p.add_argument("mesh", type=Path, help="mesh file (OBJ, PLY, STL, OFF, GLB, ...)")
    p.add_argument("--estimator", choices=ESTIMATORS, default="circumsphere", help="estimator of K")
    p.add_argument("--no-merge", action="store_true", help="do not weld identical vertices")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(run=_run_k)


def _run_k(args: argparse.Namespace) -> int:
    """Run ``meshbits k``; returns the exit code."""
    report = complexity_report(args.mesh, args)
    if args.json:
        print_json(report, args.mesh)
        return EXIT_OK
    unit = length_unit_of(args.mesh)
    print_table(
        f"{report['mesh']}: {vertices_text(report['vertices'], report['merged_vertices'])}, "
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
            *(
                [("polygons (fan-triangulated)", report["polygons"])]
                if report.get("polygons")
                else []
            ),
            *(
                [("lines and points (skipped)", report["skipped_elements"])]
                if report.get("skipped_elements")
                else []
            ),
        ],
    )
    return EXIT_OK


def add_info(sub: argparse._SubParsersAction) -> None:
    """The ``info`` subcommand."""
    p = sub.add_parser(
        "info",
        help="what a scene or mesh file holds: meshes, primitives, attributes, materials, "
        "images, extensions, bytes by part",
    )
    p.add_argument("file", type=Path, help="glTF (.glb/.gltf), OBJ, PLY, STL, ...")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(run=_run_info)


def _run_info(args: argparse.Namespace) -> int:
    """Run ``meshbits info``; returns the exit code."""
    info = scene_info(input_file(args.file))
    # Another format is read as the glTF scene trimesh converts it to: its counts are the
    # file's, its bytes by part and JSON those of that scene.
    converted = args.file.suffix.lower() not in (".glb", ".gltf")
    if args.json:
        print_json({**info, "converted_to_gltf": converted}, args.file)
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
                f"{vertices_text(prim['vertices'], prim['vertices'] - distinct)}, "
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
