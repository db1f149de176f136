"""What a scene file holds (:func:`scene_info`: meshes, primitives and their attributes,
materials, images, animations, bytes by part), and what writing it as one merged mesh
leaves out (:func:`omitted_by_merging`, :func:`merged_away`)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import MeshbitsError
from ..files import asset_bytes
from ..formats.gltf.document import Document
from ..formats.gltf.spec import COMPONENT_DTYPES, MESHOPT_EXTENSIONS
from ..formats.obj import missing_material_libraries
from ..formats.open import load_document
from ..formats.sniff import image_size
from .primitives import decoded_primitives, distinct_vertices

__all__ = ["RICH_INPUT_SUFFIXES", "merged_away", "omitted_by_merging", "scene_info"]


#: Inputs that can hold more than positions and faces (materials, textures, UVs, normals,
#: a node hierarchy): a merged-mesh output says what it leaves out of them
#: (:func:`omitted_by_merging`). An OBJ's MTL materials and textures count.
RICH_INPUT_SUFFIXES = (".glb", ".gltf", ".obj")


def merged_away(path: str | Path) -> dict[str, Any] | None:
    """:func:`omitted_by_merging` for an input of :data:`RICH_INPUT_SUFFIXES`; None for
    another file, and for an OBJ whose materials cannot be read as a scene (its mesh
    was read: trimesh's glTF export of it failed, so nothing of it is known to be lost)."""
    suffix = Path(path).suffix.lower()
    if suffix not in RICH_INPUT_SUFFIXES:
        return None
    try:
        return omitted_by_merging(path)
    except MeshbitsError:
        if suffix == ".obj":
            return None
        raise


def omitted_by_merging(path: str | Path) -> dict[str, Any]:
    """What writing a glTF scene (or an OBJ, read as one) as one merged mesh of positions
    (what :func:`meshbits.load_mesh` reads, written to ``.drc``, ``.ply``...) leaves out,
    counted:
    materials, textures, images, skins, animations and morph targets (those present), and
    ``attributes``, the names of the vertex attributes other than ``POSITION``, and for an
    OBJ whose ``mtllib`` files are not beside it, ``missing_material_libraries``. The node
    hierarchy is flattened: every instance is placed in world space."""
    j = load_document(path).json
    attributes: set[str] = set()
    targets = 0
    for mesh in j.get("meshes") or []:
        for primitive in mesh.get("primitives") or []:
            attributes.update(a for a in primitive.get("attributes") or {} if a != "POSITION")
            targets += len(primitive.get("targets") or [])
    counts = {
        key: len(j.get(key) or [])
        for key in ("materials", "textures", "images", "skins", "animations")
    }
    counts["morph_targets"] = targets
    missing = missing_material_libraries(Path(path))
    return {**{k: n for k, n in counts.items() if n}, "attributes": sorted(attributes)} | (
        {"missing_material_libraries": missing} if missing else {}
    )


def scene_info(path: str | Path) -> dict[str, Any]:
    """What a scene file holds: meshes, primitives with their attributes, materials,
    textures and images, nodes, animations, skins, extensions, and bytes by part."""
    document = load_document(path)
    j = document.json
    geometry_views: set[int] = set()
    meshes = [
        {
            "mesh": m,
            "name": mesh.get("name"),
            "primitives": [
                _primitive_info(document, p, prim, geometry_views)
                for p, prim in enumerate(mesh.get("primitives", []))
            ],
        }
        for m, mesh in enumerate(j.get("meshes", []))
    ]
    for data in decoded_primitives(document, f"{path}: "):
        finite = np.isfinite(data.positions).all(axis=1)
        prim_info = meshes[data.mesh]["primitives"][data.index]
        prim_info["non_finite_positions"] = int(len(finite) - finite.sum())
        corners = data.positions[data.faces]
        with np.errstate(invalid="ignore"):
            doubled = np.linalg.norm(
                np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1
            )
        prim_info["zero_area_faces"] = int((doubled == 0).sum())
        prim_info["distinct_vertices"] = distinct_vertices(data.positions, data.attributes)
    sizes = _bytes_by_part(j, geometry_views)
    images = []
    for i, image in enumerate(j.get("images", [])):
        image_data, mime = document.image_bytes(i)
        if image.get("bufferView") is None:
            sizes["images"] += len(image_data)
        images.append(
            {
                "image": i,
                "name": image.get("name"),
                "mimeType": mime,
                "bytes": len(image_data),
                "size": image_size(image_data),
            }
        )
    return {
        "file": str(path),
        "bytes": asset_bytes(path),
        "meshes": meshes,
        "nodes": len(j.get("nodes", [])),
        "scenes": len(j.get("scenes", [])),
        "materials": len(j.get("materials", [])),
        "textures": len(j.get("textures", [])),
        "images": images,
        "samplers": len(j.get("samplers", [])),
        "skins": len(j.get("skins", [])),
        "animations": len(j.get("animations", [])),
        "skin_details": [
            {"skin": i, "name": skin.get("name"), "joints": len(skin.get("joints", []))}
            for i, skin in enumerate(j.get("skins", []))
        ],
        "animation_details": [
            _animation_info(document, i) for i in range(len(j.get("animations", [])))
        ],
        "cameras": len(j.get("cameras", [])),
        "extensions_used": j.get("extensionsUsed", []),
        "extensions_required": j.get("extensionsRequired", []),
        "bytes_by_part": sizes,
        "json_bytes": _json_bytes(Path(path), j),
    }


def _animation_info(document: Document, index: int) -> dict[str, Any]:
    """An animation's name, its channels by target path, its keyframes (the samplers'
    inputs, counted) and its duration (seconds, the largest input time)."""
    animation = document.json["animations"][index]
    paths: dict[str, int] = {}
    for channel in animation.get("channels", []):
        path = (channel.get("target") or {}).get("path", "?")
        paths[path] = paths.get(path, 0) + 1
    keyframes, duration = 0, 0.0
    for sampler in animation.get("samplers", []):
        times = document.accessor(sampler["input"])
        keyframes += len(times)
        if len(times):
            duration = max(duration, float(np.max(times)))
    return {
        "animation": index,
        "name": animation.get("name"),
        "channels": len(animation.get("channels", [])),
        "paths": paths,
        "keyframes": keyframes,
        "duration": duration,
    }


def _json_bytes(path: Path, document_json: dict) -> int:
    """Bytes of a file's glTF JSON: a .gltf's own size, a .glb's JSON chunk (padding
    included); for another format (converted on reading), the JSON as serialised here."""
    suffix = path.suffix.lower()
    if suffix == ".gltf":
        return path.stat().st_size
    if suffix == ".glb":
        with open(path, "rb") as file:
            header = file.read(20)
        if len(header) == 20 and header[:4] == b"glTF" and header[16:20] == b"JSON":
            return int.from_bytes(header[12:16], "little")
    return len(json.dumps(document_json))


def _primitive_info(
    document: Document, index: int, prim: dict[str, Any], geometry_views: set[int]
) -> dict[str, Any]:
    """A primitive as the document declares it: mode, counts, attributes (type and
    component), material, morph targets, extensions; the bufferViews it reads are added
    to ``geometry_views``."""
    j = document.json
    attributes = {}
    for name, acc in prim.get("attributes", {}).items():
        spec = j["accessors"][acc]
        dtype: Any = COMPONENT_DTYPES[spec["componentType"]]
        attributes[name] = f"{spec['type']} {np.dtype(dtype).name}" + (
            " normalized" if spec.get("normalized") else ""
        )
        exact = document.exact_positions.get(acc) if name == "POSITION" else None
        if exact is not None and not np.array_equal(
            exact.astype(np.float32).astype(np.float64), exact
        ):
            # A PLY, OBJ... read as a glTF scene: meshbits measures and keeps the
            # file's own float64 coordinates, not the float32 accessor.
            attributes[name] = f"{spec['type']} float64"
        if spec.get("bufferView") is not None:
            geometry_views.add(spec["bufferView"])
    if (
        prim.get("indices") is not None
        and j["accessors"][prim["indices"]].get("bufferView") is not None
    ):
        geometry_views.add(j["accessors"][prim["indices"]]["bufferView"])
    extensions = sorted((prim.get("extensions") or {}).keys())
    draco = (prim.get("extensions") or {}).get("KHR_draco_mesh_compression")
    if draco:
        geometry_views.add(draco["bufferView"])
    vertices = (
        j["accessors"][prim["attributes"]["POSITION"]]["count"]
        if "POSITION" in prim.get("attributes", {})
        else 0
    )
    faces = (
        (j["accessors"][prim["indices"]]["count"] // 3)
        if prim.get("indices") is not None
        else vertices // 3
    )
    return {
        "primitive": index,
        "mode": prim.get("mode", 4),
        "vertices": vertices,
        "faces": faces,
        "attributes": attributes,
        "material": prim.get("material"),
        "morph_targets": len(prim.get("targets", [])),
        "morph_target_attributes": sorted(
            {name for target in prim.get("targets", []) for name in target}
        ),
        "extensions": extensions,
    }


def _bytes_by_part(j: dict[str, Any], geometry_views: set[int]) -> dict[str, int]:
    """The bufferViews' bytes as the file holds them (a meshopt view's compressed bytes),
    by part: geometry, images, animation, other."""
    image_views = {
        im["bufferView"] for im in j.get("images", []) if im.get("bufferView") is not None
    }
    animation_views = set()
    for animation in j.get("animations", []):
        for sampler in animation.get("samplers", []):
            for key in ("input", "output"):
                view = j["accessors"][sampler[key]].get("bufferView")
                if view is not None:
                    animation_views.add(view)
    sizes = {"geometry": 0, "images": 0, "animation": 0, "other": 0}
    for v, view in enumerate(j.get("bufferViews", [])):
        part = (
            "geometry"
            if v in geometry_views
            else "images"
            if v in image_views
            else "animation"
            if v in animation_views
            else "other"
        )
        # What the file holds: a meshopt bufferView's compressed bytes.
        compressed = next(
            (
                view["extensions"][name]
                for name in MESHOPT_EXTENSIONS
                if name in (view.get("extensions") or {})
            ),
            view,
        )
        sizes[part] += int(compressed.get("byteLength", 0))
    return sizes
