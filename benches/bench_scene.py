"""Scenes against the habit of fixed bits: meshbits's compress_scene next to gltfpack
(positions 14 bits, UVs 12, normals 8; meshopt codec) and Draco at fixed 14/12/8 bits, at
the same measured world-space error.

The scene: bunny, horse, armadillo and Spot from ../shared/meshes, with vertex normals,
under nodes with scales 1 to 4 (the armadillo shown twice). For each fixed-bits tool the
output is read back without meshbits (gltfpack's own decoder, ``-noq``, then trimesh; or
DracoPy), flattened to world space, and its Hausdorff distance to the input measured with
Open3D (``hausdorff_open3d`` of ../shared/bench-refs/refs.py, stated in
docs/benchmarks.md). compress_scene then gets
that distance as its world-space error budget, with the same codec, and its output is
measured the same way.

    python benches/bench_scene.py [--gltfpack PATH]

gltfpack is not a dependency: build it from meshoptimizer's sources (``make gltfpack``)
and pass its path; without it, only the Draco rows are printed.
"""

from __future__ import annotations

import argparse
import json
import struct
import subprocess
import tempfile
import time
from pathlib import Path

import DracoPy
import numpy as np
import trimesh
from _shared import SHARED, import_refs

from meshbits.formats import load_document
from meshbits.scene import compress_scene

ROOT = Path(__file__).resolve().parents[1]

PLACEMENTS = [
    ("bunny", [[2.0, 0, 0, 0], [0, 2.0, 0, 0], [0, 0, 2.0, 0], [0, 0, 0, 1]]),
    ("horse", [[1.0, 0, 0, 0.5], [0, 1.0, 0, 0], [0, 0, 1.0, 0], [0, 0, 0, 1]]),
    ("armadillo", [[0.4, 0, 0, -0.5], [0, 0.4, 0, 0], [0, 0, 0.4, 0], [0, 0, 0, 1]]),
    ("armadillo", [[0.1, 0, 0, -1.0], [0, 0.1, 0, 0], [0, 0, 0.1, 0], [0, 0, 0, 1]]),
    ("spot", [[0.25, 0, 0, 1.0], [0, 0.25, 0, 0], [0, 0, 0.25, 0], [0, 0, 0, 1]]),
]


def build_scene(path: Path) -> None:
    """The benchmark scene as a GLB: one mesh per model (POSITION, NORMAL), nodes with
    the placements' matrices."""
    doc = {
        "asset": {"version": "2.0"},
        "buffers": [],
        "bufferViews": [],
        "accessors": [],
        "meshes": [],
        "nodes": [],
        "scenes": [{"nodes": []}],
        "scene": 0,
    }
    blob = bytearray()
    meshes: dict[str, int] = {}

    def accessor(values: np.ndarray, kind: str, target: int, bounds: bool = False) -> int:
        nonlocal blob
        blob += b"\0" * ((-len(blob)) % 4)
        doc["bufferViews"].append(
            {"buffer": 0, "byteOffset": len(blob), "byteLength": values.nbytes, "target": target}
        )
        blob += values.tobytes()
        spec = {
            "bufferView": len(doc["bufferViews"]) - 1,
            "count": len(values),
            "type": kind,
            "componentType": 5126 if values.dtype == np.float32 else 5125,
        }
        if bounds:
            spec["min"], spec["max"] = values.min(0).tolist(), values.max(0).tolist()
        doc["accessors"].append(spec)
        return len(doc["accessors"]) - 1

    for name, matrix in PLACEMENTS:
        if name not in meshes:
            mesh = trimesh.load(SHARED / "meshes" / f"{name}.ply", process=False)
            mesh.remove_unreferenced_vertices()
            v = np.asarray(mesh.vertices, dtype=np.float32)
            n = np.asarray(mesh.vertex_normals, dtype=np.float32)
            attributes = {
                "POSITION": accessor(v, "VEC3", 34962, True),
                "NORMAL": accessor(n, "VEC3", 34962),
            }
            indices = accessor(np.asarray(mesh.faces, dtype=np.uint32).reshape(-1), "SCALAR", 34963)
            doc["meshes"].append(
                {"name": name, "primitives": [{"attributes": attributes, "indices": indices}]}
            )
            meshes[name] = len(doc["meshes"]) - 1
        column_major = np.asarray(matrix, dtype=np.float64).T.reshape(-1).tolist()
        doc["nodes"].append({"name": name, "mesh": meshes[name], "matrix": column_major})
        doc["scenes"][0]["nodes"].append(len(doc["nodes"]) - 1)
    blob += b"\0" * ((-len(blob)) % 4)
    doc["buffers"] = [{"byteLength": len(blob)}]
    text = json.dumps(doc).encode()
    text += b" " * ((-len(text)) % 4)
    total = 12 + 8 + len(text) + 8 + len(blob)
    path.write_bytes(
        struct.pack("<4sII", b"glTF", 2, total)
        + struct.pack("<I4s", len(text), b"JSON")
        + text
        + struct.pack("<I4s", len(blob), b"BIN\0")
        + bytes(blob)
    )


def world_mesh(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Every triangle of a glTF scene in world space, read by trimesh."""
    scene = trimesh.load(path)
    mesh = scene.to_mesh() if isinstance(scene, trimesh.Scene) else scene
    return np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces)


def world_error(original: tuple, path: Path, gltfpack: str | None = None) -> float:
    """Open3D's symmetric Hausdorff distance between the input and a written scene, the
    scene decoded without meshbits (meshopt files by gltfpack -noq first)."""
    hausdorff_open3d = import_refs().hausdorff_open3d

    if gltfpack is not None:
        plain = path.with_name(path.stem + "_plain.glb")
        subprocess.run(
            [gltfpack, "-i", str(path), "-o", str(plain), "-noq"], check=True, capture_output=True
        )
        path = plain
    return hausdorff_open3d(*original, *world_mesh(path), samples=300_000, seed=1)


def draco_fixed(source: Path, out: Path, bits: tuple[int, int]) -> int:
    """A GLB of every primitive Draco-encoded (DracoPy) at fixed position and normal
    bits, without simplification, as a fixed-bits pipeline writes it; returns its bytes."""
    document = load_document(source)
    doc = json.loads(json.dumps(document.json))
    blob = bytearray()
    views = []
    for m, mesh in enumerate(doc["meshes"]):
        data = document.primitive(m, 0)
        encoded = DracoPy.encode(
            data.positions,
            data.faces.astype(np.uint32),
            quantization_bits=bits[0],
            compression_level=7,
            normals=data.attributes["NORMAL"],
            normal_quantization_bits=bits[1],
        )
        decoded = DracoPy.decode(encoded)
        ids = {a["attribute_type"]: a["unique_id"] for a in decoded.attributes}
        blob += b"\0" * ((-len(blob)) % 4)
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(encoded)})
        blob += encoded
        prim = mesh["primitives"][0]
        count = len(np.asarray(decoded.points).reshape(-1, 3))
        pos, nor = prim["attributes"]["POSITION"], prim["attributes"]["NORMAL"]
        points = np.asarray(decoded.points).reshape(-1, 3)
        doc["accessors"][pos] = {
            "count": count,
            "componentType": 5126,
            "type": "VEC3",
            "min": points.min(0).tolist(),
            "max": points.max(0).tolist(),
        }
        doc["accessors"][nor] = {"count": count, "componentType": 5126, "type": "VEC3"}
        doc["accessors"][prim["indices"]] = {
            "count": int(np.asarray(decoded.faces).size),
            "componentType": 5125,
            "type": "SCALAR",
        }
        prim["extensions"] = {
            "KHR_draco_mesh_compression": {
                "bufferView": len(views) - 1,
                "attributes": {"POSITION": ids[0], "NORMAL": ids[1]},
            }
        }
    doc["bufferViews"] = views
    blob += b"\0" * ((-len(blob)) % 4)
    doc["buffers"] = [{"byteLength": len(blob)}]
    doc["extensionsUsed"] = doc["extensionsRequired"] = ["KHR_draco_mesh_compression"]
    text = json.dumps(doc).encode()
    text += b" " * ((-len(text)) % 4)
    total = 12 + 8 + len(text) + 8 + len(blob)
    out.write_bytes(
        struct.pack("<4sII", b"glTF", 2, total)
        + struct.pack("<I4s", len(text), b"JSON")
        + text
        + struct.pack("<I4s", len(blob), b"BIN\0")
        + bytes(blob)
    )
    return out.stat().st_size


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--gltfpack", help="path of a gltfpack executable")
    args = parser.parse_args()
    folder = Path(tempfile.mkdtemp(prefix="meshbits-scene-"))
    source = folder / "scene.glb"
    build_scene(source)
    original = world_mesh(source)
    print(
        f"scene: {source.stat().st_size} bytes, {len(original[1])} world triangles "
        f"({len(PLACEMENTS)} nodes)\n"
    )
    print(
        "| fixed bits | codec | bytes | world error (Open3D) | meshbits bytes at that error | "
        "meshbits error (Open3D) | meshbits / fixed | meshbits seconds |"
    )
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    runs = []
    for bits in ((14, 8), (11, 8)):
        fixed = folder / f"draco_{bits[0]}.glb"
        size = draco_fixed(source, fixed, bits)
        runs.append(
            (
                f"Draco {bits[0]}/{bits[1]} (positions/normals)",
                "draco",
                size,
                world_error(original, fixed),
            )
        )
    if args.gltfpack:
        for vp in (14, 11):
            out = folder / f"gltfpack_{vp}.glb"
            subprocess.run(
                [args.gltfpack, "-i", str(source), "-o", str(out), "-c", "-vp", str(vp)],
                check=True,
                capture_output=True,
            )
            runs.append(
                (
                    f"gltfpack -c -vp {vp} (-vt 12 -vn 8)",
                    "meshopt",
                    out.stat().st_size,
                    world_error(original, out, args.gltfpack),
                )
            )
    for label, codec, size, error in runs:
        out = folder / f"meshbits_{codec}_{size}.glb"
        start = time.perf_counter()
        compress_scene(source, error=error, codec=codec, output=out)
        seconds = time.perf_counter() - start
        ours = world_error(original, out, args.gltfpack if codec == "meshopt" else None)
        mine = out.stat().st_size
        print(
            f"| {label} | {codec} | {size} | {error:.3g} | {mine} | {ours:.3g} | "
            f"{mine / size:.3f} | {seconds:.1f} |"
        )


if __name__ == "__main__":
    main()
