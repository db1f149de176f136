"""What a scene keeps as it was: morph targets, data shared between primitives, and
anything whose compression would make it larger; what ``info`` says of morph targets,
skins and animations; Draco refusals skipped, not fatal (the encoder's own fallback is
tested in test_codecs.py). Outputs read back with
pygltflib, DracoPy and the meshopt package (tests/independent.py)."""

from __future__ import annotations

import importlib
import json
from pathlib import Path

import numpy as np
import pytest
import trimesh
from independent import hausdorff_lower, read_gltf, read_output
from test_scene import _Builder, uv_sphere

import meshbits
from meshbits.cli import main
from meshbits.scene import compress_scene

batch_module = importlib.import_module("meshbits.batch")

DATA = Path(__file__).parent / "data"


def morph_cube(path: Path) -> Path:
    """One indexed cube primitive with two morph targets and a weights animation."""
    b = _Builder()
    cube = trimesh.creation.box()
    v = cube.vertices.astype(np.float32)
    targets = []
    for k in range(2):
        delta = np.zeros_like(v)
        delta[:, k] = 0.3 * (v[:, k] > 0)
        targets.append({"POSITION": b.accessor(delta, "VEC3", bounds=True)})
    b.doc["meshes"] = [
        {
            "name": "Cube",
            "weights": [0, 0],
            "primitives": [
                {
                    "attributes": {"POSITION": b.accessor(v, "VEC3", bounds=True)},
                    "indices": b.accessor(
                        cube.faces.astype(np.uint16).reshape(-1), "SCALAR", target=34963
                    ),
                    "targets": targets,
                }
            ],
        }
    ]
    times = np.array([[0.0], [1.0]], dtype=np.float32)
    weights = np.array([[0.0], [1.0], [1.0], [0.0]], dtype=np.float32)
    b.doc["animations"] = [
        {
            "name": "Square",
            "samplers": [
                {
                    "input": b.accessor(times, "SCALAR", target=None, bounds=True),
                    "output": b.accessor(weights, "SCALAR", target=None),
                }
            ],
            "channels": [{"sampler": 0, "target": {"node": 0, "path": "weights"}}],
        }
    ]
    b.doc["nodes"] = [{"mesh": 0}]
    b.doc["scenes"] = [{"nodes": [0]}]
    return b.write(path)


def test_a_scene_of_morph_targets_only_goes_through_as_it_was(tmp_path, capsys):
    """AnimatedMorphCube was refused: "the scene has no triangle primitive to compress"."""
    source = morph_cube(tmp_path / "morph.glb")
    out = tmp_path / "out.glb"
    assert main(["compress", str(source), "-o", str(out), "--error", "0.001", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["met"] and report["primitives"][0]["kept"].startswith("morph targets")
    doc, _ = read_gltf(out)
    assert len(doc["meshes"][0]["primitives"][0]["targets"]) == 2
    assert doc["animations"][0]["channels"][0]["target"]["path"] == "weights"
    assert out.stat().st_size <= source.stat().st_size


def test_info_lists_morph_targets_skins_and_animations(tmp_path, capsys):
    source = morph_cube(tmp_path / "morph.glb")
    assert main(["info", str(source)]) == 0
    text = capsys.readouterr().out
    assert "2 morph targets (POSITION)" in text
    assert "animation 0 Square: 1 channel (weights 1), 2 keyframes, 1 s" in text
    assert main(["info", str(source), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["animation_details"][0]["duration"] == 1.0
    assert info["meshes"][0]["primitives"][0]["morph_target_attributes"] == ["POSITION"]


def shared_scene(path: Path, meshes: int = 4) -> Path:
    """``meshes`` meshes whose one primitive each reads the same accessors (a sphere),
    each with its own material, shown at different places."""
    b = _Builder()
    v, f, uv, n = uv_sphere(24, 48)
    attributes = {
        "POSITION": b.accessor(v.astype(np.float32), "VEC3", bounds=True),
        "NORMAL": b.accessor(n.astype(np.float32), "VEC3"),
        "TEXCOORD_0": b.accessor(uv.astype(np.float32), "VEC2"),
    }
    indices = b.accessor(f.astype(np.uint32).reshape(-1), "SCALAR", target=34963)
    b.doc["materials"] = [{"name": f"m{i}"} for i in range(meshes)]
    b.doc["meshes"] = [
        {"primitives": [{"attributes": attributes, "indices": indices, "material": i}]}
        for i in range(meshes)
    ]
    b.doc["nodes"] = [{"mesh": i, "translation": [3.0 * i, 0, 0]} for i in range(meshes)]
    b.doc["scenes"] = [{"nodes": list(range(meshes))}]
    return b.write(path)


@pytest.mark.parametrize("codec", ["draco", "meshopt"])
def test_shared_accessors_are_compressed_once_and_stay_shared(tmp_path, codec):
    """A scene whose 7 primitives share one set of accessors grew from 86,399 to 93,604
    bytes: each primitive was compressed apart."""
    source = shared_scene(tmp_path / "shared.glb")
    one = shared_scene(tmp_path / "one.glb", meshes=1)
    out, alone = tmp_path / "out.glb", tmp_path / "alone.glb"
    result = compress_scene(source, error=0.002, relative=True, codec=codec, output=out)
    compress_scene(one, error=0.002, relative=True, codec=codec, output=alone)
    assert result.met and len(result.primitives) == 1
    assert result.primitives[0].shared_with == ((1, 0), (2, 0), (3, 0))
    # The data of one; the JSON of four.
    assert out.stat().st_size < alone.stat().st_size + 1500
    doc, _ = read_gltf(out)
    firsts = [m["primitives"][0] for m in doc["meshes"]]
    assert all(p["attributes"] == firsts[0]["attributes"] for p in firsts)
    assert [p["material"] for p in firsts] == [0, 1, 2, 3]
    # Every instance within the budget, in world space.
    vertices, faces = meshbits.load_mesh(source)
    assert hausdorff_lower((vertices, faces), read_output(out)) <= result.world_error_upper


@pytest.mark.parametrize("codec", ["draco", "meshopt"])
def test_no_output_is_larger_than_its_input(tmp_path, codec):
    """meshopt on a 12-triangle box grew 1,664 bytes to 1,944: the input's own encoding is
    kept, and said."""
    b = _Builder()
    box = trimesh.creation.box()
    b.doc["meshes"] = [
        {
            "primitives": [
                {
                    "attributes": {
                        "POSITION": b.accessor(box.vertices.astype(np.float32), "VEC3", bounds=True)
                    },
                    "indices": b.accessor(
                        box.faces.astype(np.uint16).reshape(-1), "SCALAR", target=34963
                    ),
                }
            ]
        }
    ]
    b.doc["nodes"] = [{"mesh": 0}]
    b.doc["scenes"] = [{"nodes": [0]}]
    source = b.write(tmp_path / "box.glb")
    out = tmp_path / "out.glb"
    result = compress_scene(source, error=1e-4, codec=codec, output=out)
    assert result.met and result.size_bytes == out.stat().st_size
    assert out.stat().st_size <= source.stat().st_size
    if result.primitives[0].kept is not None:
        assert "kept as they were" in result.message
        assert result.world_error == 0.0


def test_a_tight_textured_budget_through_draco_is_met(tmp_path):
    """The search through B = 18 to 21 on a textured mesh, end to end."""
    vertices, faces = meshbits.load_mesh(DATA / "bunny_res3.ply")
    lo, side = vertices.min(axis=0), float(np.ptp(vertices, axis=0).max())
    mesh = trimesh.Trimesh(
        vertices,
        faces,
        visual=trimesh.visual.TextureVisuals(uv=(vertices[:, :2] - lo[:2]) / side),
        process=False,
    )
    source = tmp_path / "textured.glb"
    mesh.export(source)
    result = compress_scene(source, error=3e-6, relative=True, output=tmp_path / "out.glb")
    assert result.met and 17 <= result.primitives[0].bits <= 22


def test_an_obj_without_its_material_library_gains_no_texture(tmp_path, capsys):
    """pirate.obj names pirate.mtl, which is not there: its output had a 2x2 PNG."""
    vertices, faces = meshbits.load_mesh(DATA / "bunny_res4.ply")
    lines = ["mtllib missing.mtl", "usemtl skin"]
    lines += [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in vertices]
    lines += [f"vt {x:.6f} {y:.6f}" for x, y, _ in (vertices - vertices.min(0)) / 0.2]
    lines += [f"f {a}/{a} {b}/{b} {c}/{c}" for a, b, c in faces + 1]
    source = tmp_path / "nomtl.obj"
    source.write_text("\n".join(lines) + "\n")
    out = tmp_path / "out.glb"
    assert main(["compress", str(source), "-o", str(out), "--error", "0.01", "--relative"]) == 0
    assert "material library missing.mtl not found: written without materials" in (
        capsys.readouterr().out
    )
    doc, _ = read_gltf(out)
    assert not doc.get("images") and not doc.get("textures") and not doc.get("materials")


def test_a_draco_point_cloud_is_said_to_hold_no_triangles(tmp_path, capsys):
    """batch and info called a valid Draco point cloud "damaged or not a valid DRC file
    (AttributeError ...)"."""
    import DracoPy

    cloud = tmp_path / "cloud.drc"
    cloud.write_bytes(DracoPy.encode(np.random.default_rng(0).random((50, 3))))
    for command in ("info", "k"):
        assert main([command, str(cloud)]) == 2
        err = capsys.readouterr().err
        assert "Draco point cloud (50 points, no faces)" in err and "damaged" not in err


def test_an_objs_material_library_and_textures_count_in_its_bytes_and_digest(tmp_path):
    """A changed texture of an OBJ was not redone by a resumed batch."""
    from test_scene import textured_obj

    folder = tmp_path / "in"
    folder.mkdir()
    obj = textured_obj(folder, 8, 16, 8)
    whole = sum(p.stat().st_size for p in folder.iterdir())
    assert meshbits.files.asset_bytes(obj) == whole
    before = batch_module.input_digest(obj)
    (folder / "checker.png").write_bytes((folder / "checker.png").read_bytes() + b"\0")
    assert batch_module.input_digest(obj) != before
    out = tmp_path / "out"
    first = meshbits.batch(folder, out, error=0.01, relative=True, format="glb", workers=1)
    assert first.rows[0].input_bytes == whole + 1
    (folder / "checker.png").write_bytes((folder / "checker.png").read_bytes() + b"\0")
    again = meshbits.batch(folder, out, error=0.01, relative=True, format="glb", workers=1)
    assert again.ran == 1 and again.resumed == 0


def test_batch_takes_an_error_with_a_unit_as_compress_does(tmp_path):
    folder = tmp_path / "in"
    folder.mkdir()
    (folder / "bunny.ply").write_bytes((DATA / "bunny_res4.ply").read_bytes())
    result = meshbits.batch(folder, tmp_path / "out", error="5mm", workers=1)
    assert result.rows[0].budget == pytest.approx(0.005)
    with pytest.raises(meshbits.MeshbitsError, match="has a unit"):
        meshbits.batch(folder, tmp_path / "out2", error="5mm", relative=True, workers=1)


def test_a_scenes_report_names_its_budget_as_given(tmp_path):
    source = shared_scene(tmp_path / "s.glb", meshes=1)
    report = compress_scene(source, error=0.01, relative=True).to_dict()
    assert (report["budget_text"], report["budget_unit"]) == ("0.01 x S", "m")
    report = compress_scene(source, size=8 * 20_000).to_dict()
    assert (report["budget_text"], report["budget_unit"]) == ("20000 bytes", "bits")


def test_the_reported_vertex_count_never_exceeds_the_inputs():
    """Draco decodes the bunny's 453 vertices as 649 or more points (it splits the
    vertices of boundaries and non-manifold edges): V counts positions."""
    vertices, faces = meshbits.load_mesh(DATA / "bunny_res4.ply")
    result = meshbits.compress((vertices, faces), error=1e-4, relative=True)
    assert result.source == "original" and len(result.vertices) > len(vertices)
    assert result.vertex_count <= len(vertices)
    assert result.to_dict()["vertices"] == result.vertex_count
    assert result.iterations[-1].vertices <= len(vertices)


def test_a_texture_whose_name_has_a_space_counts_in_the_objs_bytes(tmp_path):
    """trimesh's fuze.obj names ``map_Kd fuze uv.jpg``: its 88 kB texture was left out of
    the input's bytes, and the output looked larger than the input."""
    (tmp_path / "a.obj").write_text("mtllib a.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (tmp_path / "a.mtl").write_text("newmtl m\nmap_Kd -bm 1 fuze uv.jpg\n")
    (tmp_path / "fuze uv.jpg").write_bytes(b"\xff\xd8" + b"\0" * 1000)
    names = [name for name, _ in meshbits.files.external_files(tmp_path / "a.obj")]
    assert names == ["a.mtl", "fuze uv.jpg"]
    whole = sum(p.stat().st_size for p in tmp_path.iterdir())
    assert meshbits.files.asset_bytes(tmp_path / "a.obj") == whole
