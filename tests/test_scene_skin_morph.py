"""Skinned positions and morph targets with meshopt (issue 33, item 2), read back without
meshbits: pygltflib for the document, the meshopt package for the streams, numpy for the
skinning, the morphing and the node transforms (tests/independent.py).

- A skinned mesh's positions are integer codes (``KHR_mesh_quantization``), their
  dequantization folded into its skin's inverse bind matrices; posed by its skin at the
  rest transforms, the output is within the certified world bound of the input posed the
  same way.
- A primitive with morph targets is compressed, its targets quantized; the morphed output
  is within the certified bound at weights 0, each target at 1, and all at 1 (the bound
  holds for every weight in [0, 1] per target).

Assets: tests/data/gltf (Khronos glTF Sample Assets; tests/data/ATTRIBUTION.md), and
CesiumMan from the project's corpus when it is there (/work/corpus).
"""

from __future__ import annotations

import json
import struct
import warnings
from pathlib import Path

import numpy as np
import pygltflib
import pytest
from independent import (
    accessor,
    decode_primitive,
    gltf_world_mesh,
    hausdorff_lower,
    node_world_matrices,
    read_gltf,
)

from meshbits.scene import compress_scene

pytest.importorskip("meshopt")

DATA = Path(__file__).parent / "data" / "gltf"
CORPUS = Path("/work/corpus")

SKINNED = [
    DATA / "SimpleSkin" / "SimpleSkin.gltf",
    DATA / "RiggedSimple.glb",
    DATA / "Fox.glb",
    CORPUS / "CesiumMan" / "CesiumMan.glb",
]

#: KHR_mesh_quantization's component types (5120 byte, 5121 unsigned byte, 5122 short,
#: 5123 unsigned short, 5126 float) for each attribute, with whether normalized:
#: ``name -> {(componentType, normalized)}``.
QUANTIZED_TYPES = {
    "POSITION": {(t, n) for t in (5120, 5121, 5122, 5123) for n in (False, True)} | {(5126, False)},
    "NORMAL": {(5120, True), (5122, True), (5126, False)},
    "TANGENT": {(5120, True), (5122, True), (5126, False)},
}
TARGET_TYPES = {
    "POSITION": {(t, n) for t in (5120, 5122) for n in (False, True)} | {(5126, False)},
    "NORMAL": {(5120, True), (5122, True), (5126, False)},
    "TANGENT": {(5120, True), (5122, True), (5126, False)},
}


def _present(path: Path, folder: Path) -> Path:
    """The asset, a ``.gltf`` with several buffers made one GLB by pygltflib (the
    independent reader reads one buffer)."""
    if not path.exists():
        pytest.skip(f"{path} is not here")
    if path.suffix == ".glb":
        return path
    gltf = pygltflib.GLTF2().load(str(path))
    with warnings.catch_warnings():
        # It warns that the .bin files are left in place (they are the test's data).
        warnings.simplefilter("ignore", UserWarning)
        gltf.convert_buffers(pygltflib.BufferFormat.BINARYBLOB)
    glb = folder / f"{path.stem}.glb"
    gltf.save_binary(str(glb))
    return glb


def _check_quantization(doc: dict, blob: bytes) -> None:
    """The rules of KHR_mesh_quantization and glTF checked by hand: the extensions
    declared, every POSITION (targets' too) of an allowed type with min and max equal to
    its values' range, every normal and tangent of an allowed type, and inverse bind
    matrices float MAT4 with (0, 0, 0, 1) as their last row."""
    assert {"KHR_mesh_quantization", "EXT_meshopt_compression"} <= set(doc["extensionsRequired"])
    for mesh in doc["meshes"]:
        for prim in mesh["primitives"]:
            groups = [(prim["attributes"], QUANTIZED_TYPES)]
            groups += [(target, TARGET_TYPES) for target in prim.get("targets") or []]
            for attributes, allowed in groups:
                for name, index in attributes.items():
                    spec = doc["accessors"][index]
                    kind = (spec["componentType"], bool(spec.get("normalized", False)))
                    if name in allowed:
                        assert kind in allowed[name], (name, kind)
                    if name == "POSITION":
                        values = accessor(doc, blob, index)
                        np.testing.assert_array_equal(spec["min"], values.min(axis=0))
                        np.testing.assert_array_equal(spec["max"], values.max(axis=0))
    for skin in doc.get("skins", []):
        if skin.get("inverseBindMatrices") is None:
            continue
        spec = doc["accessors"][skin["inverseBindMatrices"]]
        assert (spec["componentType"], spec["type"], spec["count"]) == (
            5126,
            "MAT4",
            len(skin["joints"]),
        )
        matrices = accessor(doc, blob, skin["inverseBindMatrices"]).reshape(-1, 4, 4)
        np.testing.assert_array_equal(matrices[:, :, 3], np.tile([0, 0, 0, 1], (len(matrices), 1)))


@pytest.mark.parametrize("path", SKINNED, ids=lambda p: p.stem)
def test_skinned_positions_are_integers_and_the_posed_mesh_keeps_its_bound(path, tmp_path):
    source = _present(path, tmp_path)
    out = tmp_path / "out.glb"
    result = compress_scene(source, error=0.002, relative=True, codec="meshopt", output=out)
    assert result.met, result.message
    if out.read_bytes() == source.read_bytes():
        # SimpleSkin (8 triangles): compressed, the file would be larger; written as it was.
        assert "larger than its input" in result.message
        return
    doc, blob = read_gltf(out)
    _check_quantization(doc, blob)
    skinned = [n for n in doc["nodes"] if n.get("skin") is not None and "mesh" in n]
    assert skinned
    for node in skinned:
        for prim in doc["meshes"][node["mesh"]]["primitives"]:
            spec = doc["accessors"][prim["attributes"]["POSITION"]]
            # Integer codes, not float32: the dequantization is in the skin.
            assert spec["componentType"] in (5121, 5123) and not spec.get("normalized")
    # Posed at the rest transforms, independently, input and output.
    before = gltf_world_mesh(source, skinned=True)
    after = gltf_world_mesh(out, skinned=True)
    error = hausdorff_lower(before, after, samples=20_000)
    assert result.world_error_upper is not None
    assert error <= result.world_error_upper, (error, result.world_error_upper)
    assert result.world_error_upper <= result.budget * (1 + 1e-12)


def test_a_skin_carries_one_grid_for_every_mesh_it_poses(tmp_path):
    """Two skinned nodes showing two meshes with one skin: one frame in the skin's
    matrices, both meshes on the same grid, posed within the bound."""
    source = _two_meshes_one_skin(tmp_path)
    out = tmp_path / "out.glb"
    result = compress_scene(source, error=0.002, relative=True, codec="meshopt", output=out)
    assert result.met
    doc, blob = read_gltf(out)
    _check_quantization(doc, blob)
    assert len(doc["skins"]) == 1
    kinds = {doc["accessors"][m["primitives"][0]["attributes"]["POSITION"]]["componentType"]
             for m in doc["meshes"]}  # fmt: skip
    assert kinds <= {5121, 5123}
    before = gltf_world_mesh(source, skinned=True)
    after = gltf_world_mesh(out, skinned=True)
    assert hausdorff_lower(before, after, samples=20_000) <= result.world_error_upper


def _two_meshes_one_skin(tmp_path: Path) -> Path:
    """RiggedSimple with a second mesh (its positions moved up by half its height, the
    same joints and weights) shown by a second node with the same skin: a GLB written
    here (its JSON and one buffer)."""
    doc, blob = read_gltf(DATA / "RiggedSimple.glb")
    mesh = doc["meshes"][0]
    positions = accessor(doc, blob, mesh["primitives"][0]["attributes"]["POSITION"])
    lift = np.ptp(positions[:, 1]) / 2
    moved = (positions + np.array([0.0, lift, 0.0])).astype(np.float32)
    blob = blob + b"\0" * (-len(blob) % 4)
    doc["bufferViews"].append({"buffer": 0, "byteOffset": len(blob), "byteLength": moved.nbytes})
    blob += moved.tobytes()
    doc["buffers"][0]["byteLength"] = len(blob)
    doc["accessors"].append(
        {
            "bufferView": len(doc["bufferViews"]) - 1,
            "componentType": 5126,
            "count": len(moved),
            "type": "VEC3",
            "min": moved.min(axis=0).tolist(),
            "max": moved.max(axis=0).tolist(),
        }
    )
    second = json.loads(json.dumps(mesh))
    second["primitives"][0]["attributes"]["POSITION"] = len(doc["accessors"]) - 1
    doc["meshes"].append(second)
    skinned = next(n for n in doc["nodes"] if n.get("skin") is not None)
    doc["nodes"].append({"mesh": len(doc["meshes"]) - 1, "skin": skinned["skin"]})
    doc["scenes"][doc.get("scene", 0)]["nodes"].append(len(doc["nodes"]) - 1)
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    path = tmp_path / "two.glb"
    path.write_bytes(
        struct.pack("<4sII", b"glTF", 2, 28 + len(text) + len(blob))
        + struct.pack("<I4s", len(text), b"JSON")
        + text
        + struct.pack("<I4s", len(blob), b"BIN\0")
        + blob
    )
    return path


# --- morph targets --------------------------------------------------------------------------


def morphed_world(path: Path, weights: list[float] | None) -> tuple[np.ndarray, np.ndarray]:
    """Every triangle primitive of an unskinned scene morphed at ``weights`` (one per
    target; None: the file's default weights) and placed by its nodes, in float64."""
    doc, blob = read_gltf(path)
    vertices, faces, offset = [], [], 0
    for index, world in node_world_matrices(doc).items():
        node = doc["nodes"][index]
        if "mesh" not in node:
            continue
        mesh = doc["meshes"][node["mesh"]]
        use = weights if weights is not None else node.get("weights", mesh.get("weights", []))
        for prim in mesh["primitives"]:
            data = decode_primitive(doc, blob, prim)
            local = np.asarray(data["POSITION"], dtype=np.float64)
            for weight, target in zip(use, prim.get("targets") or [], strict=False):
                if weight and "POSITION" in target:
                    local = local + weight * accessor(doc, blob, target["POSITION"])
            vertices.append(local @ world[:3, :3].T + world[:3, 3])
            faces.append(np.asarray(data["indices"], dtype=np.int64).reshape(-1, 3) + offset)
            offset += len(local)
    return np.concatenate(vertices), np.concatenate(faces)


def test_morph_targets_are_quantized_and_certified_at_every_weight(tmp_path):
    source = DATA / "AnimatedMorphCube.glb"
    out = tmp_path / "out.glb"
    result = compress_scene(source, error=0.002, relative=True, codec="meshopt", output=out)
    assert result.met and result.primitives[0].kept is None, result.message
    assert out.stat().st_size < source.stat().st_size
    doc, blob = read_gltf(out)
    _check_quantization(doc, blob)
    prim = doc["meshes"][0]["primitives"][0]
    assert len(prim["targets"]) == 2 and set(prim["targets"][0]) == {
        "POSITION",
        "NORMAL",
        "TANGENT",
    }
    for target in prim["targets"]:
        assert doc["accessors"][target["POSITION"]]["componentType"] in (5120, 5122)
    assert doc["animations"][0]["channels"][0]["target"]["path"] == "weights"
    # The weights animation still drives the node that shows the mesh.
    animated = doc["animations"][0]["channels"][0]["target"]["node"]
    assert doc["nodes"][animated]["mesh"] == 0
    bound = result.world_error_upper
    assert bound is not None and bound <= result.budget
    for weights in ([0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [0.5, 0.25]):
        error = hausdorff_lower(
            morphed_world(source, weights), morphed_world(out, weights), samples=5_000
        )
        assert error <= bound, (weights, error, bound)


def test_morph_targets_with_draco_are_kept_and_say_why(tmp_path):
    source = DATA / "AnimatedMorphCube.glb"
    result = compress_scene(source, error=0.002, relative=True, codec="draco")
    assert "KHR_draco_mesh_compression does not compress them" in result.primitives[0].kept
    assert "morph targets" in result.message
