"""Validation of a glTF document before it is read: every reference, then every value.

:func:`check_references` refuses a document whose indices a reader would trip on, then
(:func:`check_values`) one whose counts, offsets, lengths, strides, accessor types, node
transforms, node trees, primitive modes or animation paths break the specification.
Each refusal is a :class:`MeshFileError` naming the offending field, e.g.
``meshes[0].primitives[0].material is 3, past the end of materials (0)``.
:func:`finite_or_fail` refuses positions holding NaN or infinity.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ...errors import MeshFileError
from .spec import (
    ANIMATION_PATHS,
    ATTRIBUTE_TYPES,
    COLLECTIONS,
    COMPONENT_DTYPES,
    DRACO,
    MESHOPT_EXTENSIONS,
    TYPE_WIDTHS,
)

__all__ = ["check_references", "check_values", "finite_or_fail"]

#: Component types an index may have: unsigned byte, short and int.
INDEX_COMPONENTS = (5121, 5123, 5125)


# --- references ---------------------------------------------------------------------


def _object(value: Any, where: str) -> dict[str, Any]:
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise MeshFileError(f"{where} is not an object")
    return value


def _array(value: Any, where: str) -> list[Any]:
    if value is None:
        return []
    if not isinstance(value, list):
        raise MeshFileError(f"{where} is not an array")
    return value


class _References:
    """The sizes of a document's collections, against which each index is checked."""

    def __init__(self, document: dict[str, Any]) -> None:
        self.sizes: dict[str, int] = {}
        for kind in COLLECTIONS:
            items = document.get(kind, [])
            if not isinstance(items, list) or not all(isinstance(i, dict) for i in items):
                raise MeshFileError(f"{kind} is not an array of objects")
            self.sizes[kind] = len(items)

    def ref(self, value: Any, kind: str, where: str, required: bool = False) -> None:
        """Refuse ``value`` unless it is an index into ``kind`` (or absent, when not
        ``required``)."""
        if value is None:
            if required:
                raise MeshFileError(f"{where} is missing: it must name one of the {kind}")
            return
        if isinstance(value, bool) or not isinstance(value, int):
            raise MeshFileError(f"{where} is {value!r}, not an index into {kind}")
        if not 0 <= value < self.sizes[kind]:
            raise MeshFileError(f"{where} is {value}, past the end of {kind} ({self.sizes[kind]})")

    def need(self, container: dict[str, Any], key: str, kind: str, where: str) -> None:
        """``container[key]`` must be an index into ``kind``."""
        self.ref(container.get(key), kind, f"{where}.{key}", True)


def check_references(document: Any) -> None:
    """Refuse a glTF document whose structure a reader would trip on: not a JSON object,
    a top-level collection that is not an array of objects, or an index (glTF 2.0 Sec.
    3.7.2 and 5: a scene's nodes, a node's mesh, children, skin and camera, a
    primitive's attributes, indices, material and morph targets, an accessor's and an
    image's bufferView, a sparse accessor's views, a bufferView's buffer, a texture's
    source and sampler and its extensions' sources, a material's textures, a skin's
    joints, skeleton and matrices, an animation's samplers, targets and accessors, the
    Draco and meshopt extensions' views and buffers) that is not an integer naming an
    existing item; then its values (:func:`check_values`). Raises
    :class:`MeshFileError` naming the reference, e.g. ``meshes[0].primitives[0].material
    is 3, past the end of materials (0)``."""
    if not isinstance(document, dict):
        raise MeshFileError("the glTF JSON is not an object")
    refs = _References(document)
    _scene_references(document, refs)
    _mesh_references(document, refs)
    _accessor_references(document, refs)
    _texture_references(document, refs)
    _skin_references(document, refs)
    _animation_references(document, refs)
    check_values(document)


def _scene_references(document: dict[str, Any], refs: _References) -> None:
    """The default scene, the scenes' nodes, and each node's mesh, skin, camera and
    children."""
    refs.ref(document.get("scene"), "scenes", "scene")
    for i, scene in enumerate(document.get("scenes", [])):
        for k, node in enumerate(_array(scene.get("nodes"), f"scenes[{i}].nodes")):
            refs.ref(node, "nodes", f"scenes[{i}].nodes[{k}]", True)
    for i, node in enumerate(document.get("nodes", [])):
        where = f"nodes[{i}]"
        for key, kind in (("mesh", "meshes"), ("skin", "skins"), ("camera", "cameras")):
            refs.ref(node.get(key), kind, f"{where}.{key}")
        for k, child in enumerate(_array(node.get("children"), f"{where}.children")):
            refs.ref(child, "nodes", f"{where}.children[{k}]", True)


def _mesh_references(document: dict[str, Any], refs: _References) -> None:
    """Each primitive's attributes, indices, material, morph targets and Draco view."""
    for m, mesh in enumerate(document.get("meshes", [])):
        for p, prim in enumerate(_array(mesh.get("primitives"), f"meshes[{m}].primitives")):
            where = f"meshes[{m}].primitives[{p}]"
            prim = _object(prim, where)
            for name, index in _object(prim.get("attributes"), f"{where}.attributes").items():
                refs.ref(index, "accessors", f"{where}.attributes.{name}", True)
            refs.ref(prim.get("indices"), "accessors", f"{where}.indices")
            refs.ref(prim.get("material"), "materials", f"{where}.material")
            for t, target in enumerate(_array(prim.get("targets"), f"{where}.targets")):
                for name, index in _object(target, f"{where}.targets[{t}]").items():
                    refs.ref(index, "accessors", f"{where}.targets[{t}].{name}", True)
            extensions = _object(prim.get("extensions"), f"{where}.extensions")
            draco = _object(extensions.get(DRACO), f"{where}.extensions.{DRACO}")
            if DRACO in extensions:
                refs.need(draco, "bufferView", "bufferViews", f"{where}.extensions.{DRACO}")


def _accessor_references(document: dict[str, Any], refs: _References) -> None:
    """Each accessor's count, types, view and sparse views; each bufferView's buffer and
    meshopt buffer; each image's view."""
    for i, accessor in enumerate(document.get("accessors", [])):
        count = accessor.get("count")
        if isinstance(count, bool) or not isinstance(count, int) or count < 0:
            raise MeshFileError(f"accessors[{i}].count is {count!r}, not a count")
        if accessor.get("componentType") not in COMPONENT_DTYPES:
            raise MeshFileError(
                f"accessors[{i}].componentType is {accessor.get('componentType')!r}, not a "
                f"glTF component type"
            )
        if accessor.get("type") not in TYPE_WIDTHS:
            raise MeshFileError(f"accessors[{i}].type is {accessor.get('type')!r}, not a glTF type")
        refs.ref(accessor.get("bufferView"), "bufferViews", f"accessors[{i}].bufferView")
        sparse = _object(accessor.get("sparse"), f"accessors[{i}].sparse")
        for part in ("indices", "values") if sparse else ():
            inner = _object(sparse.get(part), f"accessors[{i}].sparse.{part}")
            refs.need(inner, "bufferView", "bufferViews", f"accessors[{i}].sparse.{part}")
    for i, view in enumerate(document.get("bufferViews", [])):
        refs.ref(view.get("buffer"), "buffers", f"bufferViews[{i}].buffer", True)
        extensions = _object(view.get("extensions"), f"bufferViews[{i}].extensions")
        for name in MESHOPT_EXTENSIONS:
            inner = _object(extensions.get(name), f"bufferViews[{i}].extensions.{name}")
            if name in extensions:
                refs.need(inner, "buffer", "buffers", f"bufferViews[{i}].extensions.{name}")
    for i, image in enumerate(document.get("images", [])):
        refs.ref(image.get("bufferView"), "bufferViews", f"images[{i}].bufferView")


def _texture_references(document: dict[str, Any], refs: _References) -> None:
    """Each texture's source, sampler and extensions' sources; each material's textures
    (any ``...Texture`` object, at any depth, extensions included)."""
    for i, texture in enumerate(document.get("textures", [])):
        refs.ref(texture.get("source"), "images", f"textures[{i}].source")
        refs.ref(texture.get("sampler"), "samplers", f"textures[{i}].sampler")
        extensions = _object(texture.get("extensions"), f"textures[{i}].extensions")
        for name, inner in extensions.items():
            if isinstance(inner, dict):
                refs.ref(inner.get("source"), "images", f"textures[{i}].extensions.{name}.source")

    def texture_infos(value: Any, where: str) -> None:
        if isinstance(value, dict):
            for key, inner in value.items():
                here = f"{where}.{key}"
                if key.endswith(("Texture", "texture")) and isinstance(inner, dict):
                    refs.ref(inner.get("index"), "textures", f"{here}.index", True)
                texture_infos(inner, here)
        elif isinstance(value, list):
            for k, inner in enumerate(value):
                texture_infos(inner, f"{where}[{k}]")

    for i, material in enumerate(document.get("materials", [])):
        texture_infos(material, f"materials[{i}]")


def _skin_references(document: dict[str, Any], refs: _References) -> None:
    """Each skin's joints, skeleton and inverse bind matrices."""
    for i, skin in enumerate(document.get("skins", [])):
        for k, joint in enumerate(_array(skin.get("joints"), f"skins[{i}].joints")):
            refs.ref(joint, "nodes", f"skins[{i}].joints[{k}]", True)
        refs.ref(skin.get("skeleton"), "nodes", f"skins[{i}].skeleton")
        refs.ref(skin.get("inverseBindMatrices"), "accessors", f"skins[{i}].inverseBindMatrices")


def _animation_references(document: dict[str, Any], refs: _References) -> None:
    """Each animation's samplers' accessors and its channels' samplers and nodes."""
    for a, animation in enumerate(document.get("animations", [])):
        samplers = _array(animation.get("samplers"), f"animations[{a}].samplers")
        for k, sampler in enumerate(samplers):
            sampler = _object(sampler, f"animations[{a}].samplers[{k}]")
            for key in ("input", "output"):
                refs.ref(
                    sampler.get(key), "accessors", f"animations[{a}].samplers[{k}].{key}", True
                )
        channels = _array(animation.get("channels"), f"animations[{a}].channels")
        for k, channel in enumerate(channels):
            where = f"animations[{a}].channels[{k}]"
            channel = _object(channel, where)
            index = channel.get("sampler")
            if (
                isinstance(index, bool)
                or not isinstance(index, int)
                or not 0 <= index < len(samplers)
            ):
                raise MeshFileError(
                    f"{where}.sampler is {index!r}, but the animation has {len(samplers)} samplers"
                )
            refs.ref(
                _object(channel.get("target"), f"{where}.target").get("node"),
                "nodes",
                f"{where}.target.node",
            )


# --- values -------------------------------------------------------------------------


def _integer(
    container: dict[str, Any], key: str, where: str, least: int, *, required: bool = False
) -> int | None:
    """``container[key]``, an integer >= ``least`` (None when absent and not
    ``required``)."""
    if key not in container and not required:
        return None
    value = container.get(key)
    if isinstance(value, bool) or not isinstance(value, int) or value < least:
        raise MeshFileError(f"{where}.{key} is {value!r}, not an integer >= {least}")
    return value


def _numbers(container: dict[str, Any], key: str, count: int | None, where: str) -> None:
    """``container[key]``, when present, is a list of ``count`` finite numbers (any number
    of them when ``count`` is None)."""
    if key not in container:
        return
    value = container[key]
    if count is None:
        count = len(value) if isinstance(value, list) else -1
    if (
        not isinstance(value, list)
        or len(value) != count
        or not all(
            isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
            for x in value
        )
    ):
        size = "a list of" if count < 0 else str(count)
        raise MeshFileError(f"{where}.{key} is not {size} finite numbers")


def check_values(document: dict[str, Any]) -> None:
    """The values :func:`check_references` does not cover and the readers rely on, once
    every index is known to be valid: counts, offsets, lengths and strides that are
    non-negative integers and fit their buffer view and buffer, accessor types that fit
    their attribute, node transforms of the right number of finite numbers, a node
    hierarchy of disjoint trees, primitive modes and animation paths of the
    specification."""
    _buffer_values(document)
    _accessor_values(document)
    _mesh_values(document)
    _node_values(document)
    for a, animation in enumerate(document.get("animations", [])):
        for k, channel in enumerate(animation.get("channels") or []):
            path = (channel.get("target") or {}).get("path")
            if path not in ANIMATION_PATHS:
                raise MeshFileError(
                    f"animations[{a}].channels[{k}].target.path is {path!r}, not one of "
                    f"{', '.join(ANIMATION_PATHS)}"
                )


def _buffer_values(document: dict[str, Any]) -> None:
    """Buffer lengths; bufferView offsets, lengths and strides within their buffer."""
    buffers = document.get("buffers", [])
    for i, buffer in enumerate(buffers):
        _integer(buffer, "byteLength", f"buffers[{i}]", 1, required=True)
    for i, view in enumerate(document.get("bufferViews", [])):
        where = f"bufferViews[{i}]"
        offset = _integer(view, "byteOffset", f"{where}", 0) or 0
        length = _integer(view, "byteLength", f"{where}", 1, required=True)
        stride = _integer(view, "byteStride", f"{where}", 4)
        if stride is not None and (stride > 252 or stride % 4):
            raise MeshFileError(f"{where}.byteStride is {stride}: not a multiple of 4 up to 252")
        available = buffers[view["buffer"]]["byteLength"]
        if offset + length > available:
            raise MeshFileError(
                f"{where} ends at byte {offset + length:,}, past its buffer's byteLength "
                f"({available:,})"
            )


def _accessor_values(document: dict[str, Any]) -> None:
    """Each accessor's offset, normalized flag and elements within its bufferView, and
    its sparse part."""
    views = document.get("bufferViews", [])
    for i, accessor in enumerate(document.get("accessors", [])):
        where = f"accessors[{i}]"
        offset = _integer(accessor, "byteOffset", f"{where}", 0) or 0
        if "normalized" in accessor and not isinstance(accessor["normalized"], bool):
            raise MeshFileError(f"{where}.normalized is {accessor['normalized']!r}, not a boolean")
        count = accessor["count"]
        element = (
            COMPONENT_DTYPES[accessor["componentType"]].itemsize * TYPE_WIDTHS[accessor["type"]]
        )
        if accessor.get("bufferView") is not None and count > 0:
            view = views[accessor["bufferView"]]
            stride = view.get("byteStride") or element
            if stride < element:
                raise MeshFileError(
                    f"{where}: elements of {element} bytes in bufferViews"
                    f"[{accessor['bufferView']}] whose byteStride is {stride}"
                )
            end = offset + stride * (count - 1) + element
            if end > view["byteLength"]:
                raise MeshFileError(
                    f"{where} ends at byte {end:,} of bufferViews[{accessor['bufferView']}], "
                    f"past its byteLength ({view['byteLength']:,})"
                )
        sparse = accessor.get("sparse")
        if sparse:
            _sparse_values(sparse, views, where, count, element)


def _sparse_values(
    sparse: dict[str, Any], views: list[dict[str, Any]], where: str, count: int, element: int
) -> None:
    """A sparse accessor's count, index type, and indices and values within their views."""
    stored = int(_integer(sparse, "count", f"{where}.sparse", 1, required=True) or 0)
    if stored > count:
        raise MeshFileError(f"{where}.sparse.count is {stored}, over the count {count}")
    kind = sparse["indices"].get("componentType")
    if kind not in INDEX_COMPONENTS:
        raise MeshFileError(
            f"{where}.sparse.indices.componentType is {kind!r}, not an unsigned integer type"
        )
    sizes = {"indices": COMPONENT_DTYPES[kind].itemsize, "values": element}
    for part in ("indices", "values"):
        start = _integer(sparse[part], "byteOffset", f"{where}.sparse.{part}", 0)
        view = views[sparse[part]["bufferView"]]
        end = (start or 0) + stored * sizes[part]
        if end > view["byteLength"]:
            raise MeshFileError(
                f"{where}.sparse.{part} ends at byte {end:,} of bufferViews"
                f"[{sparse[part]['bufferView']}], past its byteLength "
                f"({view['byteLength']:,})"
            )


def _mesh_values(document: dict[str, Any]) -> None:
    """Each mesh's weights and primitives: modes, and accessor types that fit their
    attributes, indices and morph targets."""
    accessors = document.get("accessors", [])

    def accessor_type(index: int, allowed: tuple[str, ...], where: str) -> None:
        kind = accessors[index]["type"]
        if kind not in allowed:
            raise MeshFileError(f"{where} is a {kind} accessor, not {' or '.join(allowed)}")

    for m, mesh in enumerate(document.get("meshes", [])):
        _numbers(mesh, "weights", None, f"meshes[{m}]")
        primitives = mesh.get("primitives")
        if not isinstance(primitives, list) or not primitives:
            raise MeshFileError(f"meshes[{m}].primitives is not a non-empty array")
        for p, prim in enumerate(primitives):
            where = f"meshes[{m}].primitives[{p}]"
            mode = _integer(prim, "mode", f"{where}", 0)
            if mode is not None and mode > 6:
                raise MeshFileError(f"{where}.mode is {mode}, not a glTF primitive mode (0-6)")
            if DRACO in (prim.get("extensions") or {}):
                continue  # Draco's attributes are described by its own stream
            for name, index in prim.get("attributes", {}).items():
                allowed = ATTRIBUTE_TYPES.get(name.split("_")[0] if "_" in name else name)
                if allowed is not None and not name.startswith("_"):
                    accessor_type(index, allowed, f"{where}.attributes.{name}")
            if prim.get("indices") is not None:
                accessor_type(prim["indices"], ("SCALAR",), f"{where}.indices")
                kind = accessors[prim["indices"]]["componentType"]
                if kind not in INDEX_COMPONENTS:
                    raise MeshFileError(
                        f"{where}.indices has componentType {kind}, not an unsigned integer type"
                    )
            for t, target in enumerate(prim.get("targets") or []):
                for name, index in target.items():
                    if name in ("POSITION", "NORMAL", "TANGENT"):
                        accessor_type(index, ("VEC3",), f"{where}.targets[{t}].{name}")
            _same_counts(accessors, prim, where)


def _same_counts(accessors: list[dict[str, Any]], prim: dict[str, Any], where: str) -> None:
    """Every attribute and morph target accessor of a primitive holds one row per vertex:
    the same count (glTF 2.0, 3.7.2.1 and 3.7.2.2); a NORMAL of 0 rows beside 3 positions
    reached the meshopt encoder as an IndexError."""
    named = [(f"attributes.{k}", v) for k, v in prim.get("attributes", {}).items()]
    for t, target in enumerate(prim.get("targets") or []):
        named += [(f"targets[{t}].{k}", v) for k, v in target.items()]
    if not named:
        return
    first, index = named[0]
    count = accessors[index]["count"]
    for name, other in named[1:]:
        if accessors[other]["count"] != count:
            raise MeshFileError(
                f"{where}.{name} has {accessors[other]['count']} rows, {where}.{first} "
                f"{count}: a primitive's attributes and targets hold one row per vertex"
            )


def _node_values(document: dict[str, Any]) -> None:
    """Node transforms and weights of finite numbers, and nodes forming disjoint trees."""
    nodes = document.get("nodes", [])
    parent: dict[int, int] = {}
    for i, node in enumerate(nodes):
        where = f"nodes[{i}]"
        for key, count in (("matrix", 16), ("translation", 3), ("rotation", 4), ("scale", 3)):
            _numbers(node, key, count, where)
        _numbers(node, "weights", None, where)
        for child in node.get("children") or []:
            if child == i or child in parent:
                raise MeshFileError(
                    f"{where}.children holds node {child}, "
                    + ("itself" if child == i else f"already a child of node {parent[child]}")
                    + ": the nodes must form trees"
                )
            parent[child] = i
    # Each node has at most one parent: walk up from each node until a root or a node
    # already known to reach one, so every node is walked once.
    rooted: set[int] = set()
    for start in range(len(nodes)):
        path, node = {start}, start
        while node in parent and node not in rooted:
            node = parent[node]
            if node in path:
                raise MeshFileError(
                    f"nodes[{start}] is its own ancestor: the nodes must form trees"
                )
            path.add(node)
        rooted.update(path)


def finite_or_fail(name: str, values: np.ndarray) -> None:
    """Refuse positions (rows of coordinates) holding NaN or infinity, naming the first
    such row as :func:`meshbits.shape_complexity` and ``load_mesh`` do."""
    if values.size and not np.isfinite(values).all():
        rows = values.reshape(len(values), -1)
        bad = ~np.isfinite(rows).all(axis=1)
        first = int(np.flatnonzero(bad)[0])
        raise MeshFileError(
            f"{name}[{first}] = {rows[first].tolist()} is not finite ({int(bad.sum())} "
            f"row{'s have' if bad.sum() > 1 else ' has'} NaN or infinite coordinates)"
        )
