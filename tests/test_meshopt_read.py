"""Reading glTF compressed with meshoptimizer's codecs (``EXT_meshopt_compression``,
``KHR_meshopt_compression``): scenes meshbits writes with ``codec="meshopt"``, and a
document the ``meshopt`` package writes with every mode and filter, read back by meshbits
(``load_mesh``, the scene reader, the CLI) and compared with an independent decode:
pygltflib for the document, the ``meshopt`` package's decoders for the streams, numpy for
the accessors and the node transforms."""

from __future__ import annotations

import json
import struct
import warnings
from pathlib import Path

import numpy as np
import pygltflib
import pytest
import trimesh
from conftest import GLTF_DTYPES, GLTF_WIDTHS
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import meshbits
from meshbits import _core
from meshbits.cli import main
from meshbits.formats import example_mesh_path, load_document
from meshbits.formats.gltf.write import write_document
from meshbits.scene import compress as scene_compress

meshopt = pytest.importorskip("meshopt")

MESHOPT = ("EXT_meshopt_compression", "KHR_meshopt_compression")
ERROR = 0.002  # of the scene's size


# --- the independent reader: pygltflib, the meshopt package, numpy ---------------------------


def read_independently(path: Path) -> tuple[dict, list[bytes]]:
    """The document (pygltflib) and each buffer's bytes (a fallback buffer's: none)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        gltf = pygltflib.GLTF2().load(str(path))
        doc = json.loads(gltf.to_json())
        blob = gltf.binary_blob() or b""
    buffers = []
    for i, buffer in enumerate(doc["buffers"]):
        if buffer.get("uri"):
            buffers.append((path.parent / buffer["uri"]).read_bytes())
        else:
            buffers.append(blob if i == 0 else b"")
    return doc, buffers


def view_data(doc: dict, buffers: list[bytes], index: int) -> bytes:
    """A bufferView's bytes, a meshopt stream decoded by the meshopt package."""
    view = doc["bufferViews"][index]
    extensions = view.get("extensions") or {}
    for name in MESHOPT:
        if name in extensions:
            ext = extensions[name]
            start = ext.get("byteOffset", 0)
            data = buffers[ext["buffer"]][start : start + ext["byteLength"]]
            decoded = meshopt.decode_gltf_buffer(
                data, ext["count"], ext["byteStride"], ext["mode"], ext.get("filter", "NONE")
            )
            return np.ascontiguousarray(decoded).tobytes()
    start = view.get("byteOffset", 0)
    return buffers[view["buffer"]][start : start + view["byteLength"]]


def accessor_values(doc: dict, buffers: list[bytes], index: int, normalize=True) -> np.ndarray:
    spec = doc["accessors"][index]
    dtype = np.dtype(GLTF_DTYPES[spec["componentType"]])
    width, count = GLTF_WIDTHS[spec["type"]], spec["count"]
    view = doc["bufferViews"][spec["bufferView"]]
    data = view_data(doc, buffers, spec["bufferView"])
    element = dtype.itemsize * width
    stride = view.get("byteStride") or element
    offset = spec.get("byteOffset", 0)
    rows = [data[offset + i * stride : offset + i * stride + element] for i in range(count)]
    values = np.frombuffer(b"".join(rows), dtype=dtype).reshape(count, width)
    if normalize and spec.get("normalized"):
        top = {np.int8: 127, np.uint8: 255, np.int16: 32767, np.uint16: 65535}[dtype.type]
        return np.maximum(values / top, -1.0)
    return values


def node_matrix(node: dict) -> np.ndarray:
    if "matrix" in node:
        return np.asarray(node["matrix"], dtype=np.float64).reshape(4, 4).T
    x, y, z, w = node.get("rotation", [0, 0, 0, 1])
    m = np.eye(4)
    m[:3, :3] = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    ) * np.asarray(node.get("scale", [1, 1, 1]))
    m[:3, 3] = node.get("translation", [0, 0, 0])
    return m


def mesh_worlds(doc: dict) -> dict[int, list[np.ndarray]]:
    """mesh -> the world matrices of the nodes that show it, in node order."""
    parents = {c: i for i, node in enumerate(doc["nodes"]) for c in node.get("children", [])}
    out: dict[int, list[np.ndarray]] = {}
    for i, node in enumerate(doc["nodes"]):
        if node.get("mesh") is None:
            continue
        world, at = node_matrix(node), i
        while at in parents:
            at = parents[at]
            world = node_matrix(doc["nodes"][at]) @ world
        out.setdefault(node["mesh"], []).append(world)
    return out


def world_mesh(doc: dict, buffers: list[bytes]) -> tuple[np.ndarray, np.ndarray]:
    """Every triangle primitive at every instance, in world coordinates, as one mesh."""
    worlds = mesh_worlds(doc)
    vertices, faces, offset = [], [], 0
    for m, mesh in enumerate(doc["meshes"]):
        for prim in mesh["primitives"]:
            local = accessor_values(doc, buffers, prim["attributes"]["POSITION"])
            triangles = accessor_values(doc, buffers, prim["indices"]).reshape(-1, 3)
            for matrix in worlds.get(m, [np.eye(4)]):
                vertices.append(local.astype(np.float64) @ matrix[:3, :3].T + matrix[:3, 3])
                faces.append(triangles.astype(np.int64) + offset)
                offset += len(local)
    return np.concatenate(vertices), np.concatenate(faces)


def glb_bytes(doc: dict, blob: bytes) -> bytes:
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    blob += b"\0" * (-len(blob) % 4)
    return b"".join(
        [
            struct.pack("<4sII", b"glTF", 2, 28 + len(text) + len(blob)),
            struct.pack("<I4s", len(text), b"JSON"),
            text,
            struct.pack("<I4s", len(blob), b"BIN\0"),
            blob,
        ]
    )


def canonical(triangles: np.ndarray) -> np.ndarray:
    """Each triangle as the smallest (lexicographically) of its three rotations: the same
    for every rotation of it, its winding kept."""
    triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    rotations = np.stack([np.roll(triangles, -k, axis=1) for k in range(3)], axis=1)
    keys = (rotations[..., 0] * 2**21 + rotations[..., 1]) * 2**21 + rotations[..., 2]
    return rotations[np.arange(len(triangles)), keys.argmin(axis=1)]


def one_line(text: str) -> str:
    lines = text.strip().splitlines()
    assert len(lines) == 1, text
    return lines[0]


# --- scenes written by meshbits ---------------------------------------------------------------


def textured_scene(path: Path) -> Path:
    """Three meshes from trimesh: Spot with UVs, a texture and normals (twice, the second
    turned, scaled and moved), and an icosphere with vertex colours."""
    from PIL import Image

    v, f = meshbits.load_mesh(example_mesh_path())
    uv = np.stack(
        [
            np.arctan2(v[:, 0], v[:, 2]) / (2 * np.pi) + 0.5,
            (v[:, 1] - v[:, 1].min()) / np.ptp(v[:, 1]),
        ],
        axis=1,
    )
    checker = (np.indices((16, 16)).sum(axis=0) % 2 * 255).astype(np.uint8)
    visual = trimesh.visual.TextureVisuals(uv=uv, image=Image.fromarray(checker).convert("RGB"))
    spot = trimesh.Trimesh(v, f, visual=visual, process=False)
    assert spot.vertex_normals.shape == v.shape  # cached: exported as NORMAL
    ball = trimesh.creation.icosphere(subdivisions=3)
    ball.visual.vertex_colors = (np.abs(ball.vertices) * 255).astype(np.uint8)
    compose = trimesh.transformations.compose_matrix
    s = trimesh.Scene()
    s.add_geometry(spot, node_name="spot", geom_name="spot")
    s.add_geometry(
        ball,
        node_name="ball",
        geom_name="ball",
        transform=compose(scale=[0.3] * 3, translate=[2, 0, 0]),
    )
    s.add_geometry(
        spot,
        node_name="spot2",
        geom_name="spot",
        transform=compose(scale=[2] * 3, angles=[0, 0.5, 0], translate=[-3, 0, 0]),
    )
    s.export(path)
    return path


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """The scene compressed with the meshopt codec (as .glb and as .gltf), with what the
    writer was given: the jobs and their encodings (the quantized positions, the grid)."""
    folder = tmp_path_factory.mktemp("meshopt")
    source = textured_scene(folder / "scene.glb")
    calls = []
    original = scene_compress.scene_document

    def recording(document, jobs, encodings, codec, animations=None):
        calls.append((document, jobs, encodings))
        return original(document, jobs, encodings, codec, animations)

    out = folder / "scene_meshopt.glb"
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(scene_compress, "scene_document", recording)
        result = meshbits.compress_scene(
            source, error=ERROR, relative=True, codec="meshopt", output=out
        )
    assert result.met and len(calls) == 1
    document, jobs, encodings = calls[0]
    gltf = folder / "scene_meshopt.gltf"
    write_document(*original(document, jobs, encodings, "meshopt"), gltf)
    return {
        "source": source,
        "glb": out,
        "gltf": gltf,
        "result": result,
        "input": document,
        "jobs": jobs,
        "encodings": encodings,
    }


def test_the_output_really_is_meshopt_with_every_mode_and_filter_we_write(written):
    doc, _ = read_independently(written["glb"])
    assert {"EXT_meshopt_compression", "KHR_mesh_quantization"} <= set(doc["extensionsRequired"])
    streams = [
        v["extensions"]["EXT_meshopt_compression"] for v in doc["bufferViews"] if "extensions" in v
    ]
    assert {(s["mode"], s.get("filter", "NONE")) for s in streams} == {
        ("ATTRIBUTES", "NONE"),
        ("ATTRIBUTES", "OCTAHEDRAL"),
        ("TRIANGLES", "NONE"),
    }
    assert doc["buffers"][1]["extensions"]["EXT_meshopt_compression"]["fallback"]
    assert "uri" not in doc["buffers"][1]  # no uncompressed copy: only a decoder reads it


@pytest.mark.parametrize("form", ["glb", "gltf"])
def test_every_stream_decodes_as_the_meshopt_package_decodes_it(written, form):
    doc, buffers = read_independently(written[form])
    document = load_document(written[form])
    compressed = [i for i, v in enumerate(doc["bufferViews"]) if "extensions" in v]
    # Spot's two meshes share their accessors: one set of streams serves both; the 7
    # streams of the scene's two geometries share a view where mode, stride and filter
    # agree (gltfpack's layout), each accessor at its byteOffset in the decoded view.
    kinds = {
        tuple(
            doc["bufferViews"][i]["extensions"]["EXT_meshopt_compression"].get(k)
            for k in ("mode", "byteStride", "filter")
        )
        for i in compressed
    }
    assert len(compressed) == len(kinds) == 4
    assert set(document.decoded_views) == set(compressed)
    assert any(a.get("byteOffset", 0) for a in doc["accessors"])
    for i in compressed:
        assert bytes(document.view_bytes(i)) == view_data(doc, buffers, i), f"bufferView {i}"


def test_primitives_read_as_the_independent_decode(written):
    doc, buffers = read_independently(written["glb"])
    document = load_document(written["glb"])
    primitives = document.triangle_primitives()
    assert [(p.mesh, p.index) for p in primitives] == [(0, 0), (1, 0), (2, 0)]
    seen = set()
    for data in primitives:
        prim = doc["meshes"][data.mesh]["primitives"][data.index]
        positions = accessor_values(doc, buffers, prim["attributes"]["POSITION"])
        assert positions.dtype in (np.uint8, np.uint16)  # grid codes (KHR_mesh_quantization)
        np.testing.assert_array_equal(data.positions, positions.astype(np.float64))
        faces = accessor_values(doc, buffers, prim["indices"]).reshape(-1, 3)
        np.testing.assert_array_equal(data.faces, faces.astype(np.int64))
        for name, index in prim["attributes"].items():
            if name == "POSITION":
                continue
            expected = accessor_values(doc, buffers, index)
            if name == "NORMAL":
                expected = expected[:, :3]
                lengths = np.linalg.norm(data.attributes[name], axis=1)
                assert np.abs(lengths - 1).max() < 0.02  # the octahedral filter undone
            np.testing.assert_allclose(data.attributes[name], expected, rtol=0, atol=1e-12)
            assert data.source_types[name] == (
                doc["accessors"][index]["componentType"],
                bool(doc["accessors"][index].get("normalized")),
            )
            seen.add(name)
    assert seen == {"NORMAL", "TEXCOORD_0", "COLOR_0"}


def test_positions_read_back_are_the_written_quantized_positions(written):
    """The world positions meshbits reads (integer codes through the node transforms that
    carry their dequantization) are the grid positions the writer quantized, placed by the
    input's nodes: off by float64 rounding, far within a quantization step."""
    input_instances = written["input"].mesh_instances()
    document = load_document(written["glb"])
    instances = document.mesh_instances()
    by_primitive = {(p.mesh, p.index): p for p in document.triangle_primitives()}
    worst = 0.0
    for job, encoding in zip(written["jobs"], written["encodings"], strict=True):
        step = encoding.dequantize[1]
        data = by_primitive[(job.data.mesh, job.data.index)]
        assert data.positions.min() >= 0 and data.positions.max() <= 2**encoding.bits - 1
        np.testing.assert_array_equal(data.positions, np.round(data.positions))
        for (_, written_matrix), (_, matrix) in zip(
            input_instances[job.data.mesh], instances[job.data.mesh], strict=True
        ):
            expected = encoding.vertices @ written_matrix[:3, :3].T + written_matrix[:3, 3]
            read = data.positions @ matrix[:3, :3].T + matrix[:3, 3]
            world_step = step * np.linalg.svd(written_matrix[:3, :3], compute_uv=False).max()
            error = np.abs(read - expected).max()
            assert error < 1e-6 * world_step, (error, world_step)
            worst = max(worst, error / world_step)
    assert worst < 1e-6


@pytest.mark.parametrize("form", ["glb", "gltf"])
def test_load_mesh_reads_the_world_mesh(written, form):
    vertices, faces = meshbits.load_mesh(written[form])
    doc, buffers = read_independently(written[form])
    expected_vertices, expected_faces = world_mesh(doc, buffers)
    np.testing.assert_allclose(vertices, expected_vertices, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(faces, expected_faces)
    # ...and it is the input within the error the compression certified.
    result = written["result"]
    distance = meshbits.hausdorff(meshbits.load_mesh(written["source"]), (vertices, faces)).distance
    assert 0 < distance <= result.world_error_upper


def test_the_cli_reads_meshopt_files(written, capsys):
    out, source = str(written["glb"]), str(written["source"])
    doc, buffers = read_independently(written["glb"])
    vertices, faces = world_mesh(doc, buffers)

    assert main(["info", out, "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert "EXT_meshopt_compression" in info["extensions_required"]
    for m, mesh in enumerate(info["meshes"]):
        prim = doc["meshes"][m]["primitives"][0]
        row = mesh["primitives"][0]
        assert row["vertices"] == doc["accessors"][prim["attributes"]["POSITION"]]["count"]
        assert row["faces"] * 3 == len(accessor_values(doc, buffers, prim["indices"]))
        assert row["non_finite_positions"] == 0
    # The geometry is counted at its compressed size: the parts, the JSON and the GLB's
    # headers make up the file (up to each bufferView's padding to 4 bytes).
    parts = sum(info["bytes_by_part"].values()) + info["json_bytes"] + 28
    assert parts <= info["bytes"] == written["glb"].stat().st_size < parts + 4 * 16

    assert main(["k", out, "--json"]) == 0
    k = json.loads(capsys.readouterr().out)
    assert (k["vertices"], k["faces"]) == (len(vertices), len(faces))
    assert k["k"] == pytest.approx(meshbits.shape_complexity(vertices, faces).k, rel=1e-12)

    assert main(["hausdorff", source, out, "--json", "--quiet"]) == 0
    h = json.loads(capsys.readouterr().out)
    expected = meshbits.hausdorff(meshbits.load_mesh(source), (vertices, faces))
    assert h["distance"] == pytest.approx(expected.distance, rel=1e-12)
    assert h["distance"] <= written["result"].world_error_upper


def test_a_meshopt_scene_compresses_again(written, tmp_path):
    """The scene reader takes meshbits's meshopt output as input; the copy written with
    Draco uses meshopt no more."""
    out = tmp_path / "again.glb"
    result = meshbits.compress_scene(written["glb"], error=0.01, relative=True, output=out)
    assert result.met
    doc, _ = read_independently(out)
    assert not set(MESHOPT) & set(doc["extensionsUsed"] + doc["extensionsRequired"])
    assert all("extensions" not in view for view in doc["bufferViews"])
    assert len(doc["buffers"]) == 1
    a, b = meshbits.load_mesh(written["source"]), meshbits.load_mesh(out)
    assert (
        meshbits.hausdorff(a, b).distance
        <= result.world_error_upper + written["result"].world_error_upper
    )


# --- damaged files ------------------------------------------------------------------------------


def _damaged(source: Path, target: Path, change) -> Path:
    doc, buffers = read_independently(source)
    blob = bytearray(buffers[0])
    change(doc, blob)
    target.write_bytes(glb_bytes(doc, bytes(blob)))
    return target


def _first_stream(doc: dict) -> tuple[int, dict]:
    for i, view in enumerate(doc["bufferViews"]):
        if "extensions" in view:
            return i, view["extensions"]["EXT_meshopt_compression"]
    raise AssertionError("no meshopt stream")


def test_a_corrupt_stream_is_refused_in_one_line(written, tmp_path, capsys):
    def bad_header(doc, blob):
        _, ext = _first_stream(doc)
        blob[ext["byteOffset"]] = 0x33

    def truncated(doc, blob):
        _, ext = _first_stream(doc)
        ext["byteLength"] -= 9

    def wrong_count(doc, blob):
        # Twice the rows the data holds: a few more can decode from a long stream's
        # last block without running out of data (the codec does not store its count).
        i, ext = _first_stream(doc)
        ext["count"] = 2 * ext["count"] + 16
        doc["bufferViews"][i]["byteLength"] = ext["count"] * ext["byteStride"]

    def outside(doc, blob):
        _, ext = _first_stream(doc)
        ext["byteOffset"] = len(blob) + 100

    def wrong_mode(doc, blob):
        _, ext = _first_stream(doc)
        ext["mode"] = "STRIPS"

    def layout(doc, blob):
        i, _ = _first_stream(doc)
        doc["bufferViews"][i]["byteLength"] += 4

    cases = {
        bad_header: "header byte (0x33)",
        truncated: "cannot be decoded",
        wrong_count: "cannot be decoded",
        outside: "past its buffer",
        wrong_mode: 'unknown meshopt mode "STRIPS"',
        layout: "but the bufferView's byteLength is",
    }
    for change, words in cases.items():
        path = _damaged(written["glb"], tmp_path / f"{change.__name__}.glb", change)
        with pytest.raises(meshbits.MeshbitsError) as caught:
            meshbits.load_mesh(path)
        message = one_line(str(caught.value))
        assert str(path) in message and "bufferView 1 (EXT_meshopt_compression)" in message
        assert words in message, message
        with pytest.raises(meshbits.MeshbitsError, match="bufferView 1"):
            load_document(path)
        assert main(["info", str(path)]) == 2
        assert words in one_line(capsys.readouterr().err)


def test_the_extension_object_is_checked(written, tmp_path):
    def color_in_ext(doc, blob):
        _, ext = _first_stream(doc)
        ext["filter"] = "COLOR"

    def negative(doc, blob):
        _, ext = _first_stream(doc)
        ext["byteStride"] = -4

    def missing(doc, blob):
        _, ext = _first_stream(doc)
        del ext["count"]

    for change, words in (
        (color_in_ext, "belongs to KHR_meshopt_compression"),
        (negative, "byteStride is -4, not a whole number >= 0"),
        (missing, "has no count"),
    ):
        path = _damaged(written["glb"], tmp_path / f"{change.__name__}.glb", change)
        with pytest.raises(meshbits.MeshbitsError, match=words):
            meshbits.load_mesh(path)


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(where=st.floats(0, 1, exclude_max=True), flip=st.integers(1, 255), stream=st.integers(0, 6))
def test_damage_anywhere_in_a_stream_is_read_or_refused(written, tmp_path, where, flip, stream):
    """A stream damaged anywhere decodes to something (meshoptimizer's decoders are safe on
    any input) or is refused with a MeshbitsError: never a crash, never another error."""
    doc, buffers = read_independently(written["glb"])
    views = [v for v in doc["bufferViews"] if "extensions" in v]
    ext = views[stream % len(views)]["extensions"]["EXT_meshopt_compression"]
    blob = bytearray(buffers[0])
    blob[ext["byteOffset"] + int(where * ext["byteLength"])] ^= flip
    path = tmp_path / "flipped.glb"
    path.write_bytes(glb_bytes(doc, bytes(blob)))
    try:
        vertices, faces = meshbits.load_mesh(path)
    except meshbits.MeshbitsError as err:
        one_line(str(err))
    else:
        assert np.isfinite(vertices).all() and faces.max() < len(vertices)


def test_draco_files_read_as_before(written, tmp_path):
    out = tmp_path / "draco.glb"
    result = meshbits.compress_scene(written["source"], error=ERROR, relative=True, output=out)
    doc, buffers = read_independently(out)
    assert "KHR_draco_mesh_compression" in doc["extensionsRequired"]
    import DracoPy

    document = load_document(out)
    for data in document.triangle_primitives():
        draco = doc["meshes"][data.mesh]["primitives"][data.index]["extensions"]
        view = doc["bufferViews"][draco["KHR_draco_mesh_compression"]["bufferView"]]
        start = view.get("byteOffset", 0)
        decoded = DracoPy.decode(buffers[0][start : start + view["byteLength"]])
        np.testing.assert_array_equal(data.positions, np.asarray(decoded.points, dtype=np.float64))
    vertices, faces = meshbits.load_mesh(out)
    assert len(faces) == sum(r.faces * (1 + len(r.shared_with)) for r in result.primitives)
    assert meshbits.hausdorff(
        meshbits.load_mesh(written["source"]), (vertices, faces)
    ).distance <= (result.world_error_upper)


def test_a_draco_primitive_that_does_not_decode_is_refused(written, tmp_path, capsys):
    """One byte changed in the middle of a GLB's Draco data: trimesh read the primitive as
    zeros with only a log message, so ``k`` and ``hausdorff`` measured a mesh at the
    origin (exit 0) while ``info`` refused the file."""
    out = tmp_path / "draco.glb"
    meshbits.compress_scene(written["source"], error=ERROR, relative=True, output=out)
    doc, buffers = read_independently(out)
    draco = doc["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]
    view = doc["bufferViews"][draco["bufferView"]]
    import DracoPy

    start, length = view.get("byteOffset", 0), view["byteLength"]
    for where in range(length // 2, length):
        blob = bytearray(buffers[0])
        blob[start + where] ^= 0xFF
        try:
            DracoPy.decode(bytes(blob[start : start + length]))
        except Exception:
            break  # DracoPy refuses it: a byte that breaks the data
    else:
        pytest.fail("no byte of the second half breaks the Draco data")
    flipped = tmp_path / "flipped.glb"
    flipped.write_bytes(glb_bytes(doc, bytes(blob)))
    with pytest.raises(meshbits.MeshbitsError, match="Draco"):
        meshbits.load_mesh(flipped)
    for argv in (["k", str(flipped)], ["hausdorff", str(out), str(flipped), "--quiet"]):
        assert main(argv) == 2
        one_line(capsys.readouterr().err)


def test_an_unknown_required_extension_is_still_refused(written, tmp_path):
    def require(name):
        def change(doc, blob):
            doc["extensionsUsed"] = [*doc.get("extensionsUsed", []), name]
            doc["extensionsRequired"] = [*doc.get("extensionsRequired", []), name]

        return change

    path = _damaged(written["source"], tmp_path / "unknown.glb", require("EXT_made_up_compression"))
    with pytest.raises(
        meshbits.MeshbitsError, match="requires the extension EXT_made_up_compression"
    ):
        meshbits.load_mesh(path)
    # An extension that leaves the geometry alone is no reason to refuse.
    path = _damaged(written["source"], tmp_path / "variants.glb", require("KHR_materials_variants"))
    assert len(meshbits.load_mesh(path)[1]) == len(meshbits.load_mesh(written["source"])[1])


# --- KHR_meshopt_compression, written by the meshopt package --------------------------------------


@pytest.fixture(scope="module")
def khr_file(tmp_path_factory):
    """Spot as the meshopt package writes it under KHR_meshopt_compression: positions as
    float32 through the EXPONENTIAL filter, normals through OCTAHEDRAL (16-bit), colours
    through COLOR, all with the vertex codec's version 1; indices with the index sequence
    codec (INDICES); the icosphere's triangles with the index codec (TRIANGLES, version 0
    vertices); an animation's rotations through QUATERNION."""
    v, f = meshbits.load_mesh(example_mesh_path())
    normals = trimesh.Trimesh(v, f, process=False).vertex_normals
    rng = np.random.default_rng(7)
    colours = rng.random((len(v), 4))
    ball = trimesh.creation.icosphere(subdivisions=2)
    turns = rng.normal(size=(9, 4))
    turns /= np.linalg.norm(turns, axis=1, keepdims=True)
    times = np.arange(9, dtype=np.float32)[:, None] / 8

    blob, fallback, views, accessors = bytearray(), [0], [], []

    def add(stream: bytes, count: int, stride: int, mode: str, filter: str, **accessor):
        while len(blob) % 4:
            blob.append(0)
        ext = {
            "buffer": 0,
            "byteOffset": len(blob),
            "byteLength": len(stream),
            "byteStride": stride,
            "count": count,
            "mode": mode,
        }
        if filter != "NONE":
            ext["filter"] = filter
        blob.extend(stream)
        view = {
            "buffer": 1,
            "byteOffset": fallback[0],
            "byteLength": count * stride,
            "extensions": {"KHR_meshopt_compression": ext},
        }
        if mode == "ATTRIBUTES":
            view["byteStride"] = stride
        fallback[0] += count * stride
        views.append(view)
        accessors.append({"bufferView": len(views) - 1, "count": int(count), **accessor})
        return len(accessors) - 1

    rows = meshopt.encode_filter_exp(v.astype(np.float32), 20)
    position = add(
        meshopt.encode_vertex_buffer_level(rows, 3, 1), len(v), 12, "ATTRIBUTES", "EXPONENTIAL",
        componentType=5126, type="VEC3",
        min=v.min(axis=0).tolist(), max=v.max(axis=0).tolist(),
    )  # fmt: skip
    rows = meshopt.encode_filter_oct(np.hstack([normals, np.zeros((len(v), 1))]), 8, 14)
    normal = add(
        meshopt.encode_vertex_buffer_level(rows, 2, 1), len(v), 8, "ATTRIBUTES", "OCTAHEDRAL",
        componentType=5122, type="VEC3", normalized=True,
    )  # fmt: skip
    rows = meshopt.encode_filter_color(colours, 4, 8)
    colour = add(
        meshopt.encode_vertex_buffer_level(rows, 2, 1), len(v), 4, "ATTRIBUTES", "COLOR",
        componentType=5121, type="VEC4", normalized=True,
    )  # fmt: skip
    sequence = meshopt.encode_index_sequence(f.astype(np.uint32).reshape(-1))
    indices = add(sequence, f.size, 4, "INDICES", "NONE", componentType=5125, type="SCALAR")
    ball_v = np.hstack([ball.vertices, np.zeros((len(ball.vertices), 1))]).astype(np.float32)
    ball_position = add(
        meshopt.encode_vertex_buffer_level(ball_v, 2, 0), len(ball_v), 16, "ATTRIBUTES", "NONE",
        componentType=5126, type="VEC3",
        min=ball_v[:, :3].min(axis=0).tolist(), max=ball_v[:, :3].max(axis=0).tolist(),
    )  # fmt: skip
    ball_indices = add(
        meshopt.encode_index_buffer(ball.faces.astype(np.uint32).reshape(-1)), ball.faces.size, 2,
        "TRIANGLES", "NONE", componentType=5123, type="SCALAR",
    )  # fmt: skip
    time_input = add(
        meshopt.encode_vertex_buffer_level(times, 2, 1), 9, 4, "ATTRIBUTES", "NONE",
        componentType=5126, type="SCALAR", min=[0.0], max=[1.0],
    )  # fmt: skip
    rows = meshopt.encode_filter_quat(turns, 8, 12)
    rotation = add(
        meshopt.encode_vertex_buffer_level(rows, 2, 1), 9, 8, "ATTRIBUTES", "QUATERNION",
        componentType=5122, type="VEC4", normalized=True,
    )  # fmt: skip
    extensions = ["KHR_meshopt_compression", "KHR_mesh_quantization"]
    doc = {
        "asset": {"version": "2.0", "generator": "the meshopt package, by hand"},
        "extensionsUsed": extensions,
        "extensionsRequired": extensions,
        "scene": 0,
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [{"mesh": 0}, {"mesh": 1, "translation": [2.0, 0.0, 0.0], "scale": [0.5] * 3}],
        "meshes": [
            {
                "primitives": [
                    {
                        "attributes": {"POSITION": position, "NORMAL": normal, "COLOR_0": colour},
                        "indices": indices,
                    }
                ]
            },
            {"primitives": [{"attributes": {"POSITION": ball_position}, "indices": ball_indices}]},
        ],
        "animations": [
            {
                "samplers": [{"input": time_input, "output": rotation}],
                "channels": [{"sampler": 0, "target": {"node": 1, "path": "rotation"}}],
            }
        ],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [
            {"byteLength": len(blob) + (-len(blob) % 4)},
            {
                "byteLength": fallback[0],
                "extensions": {"KHR_meshopt_compression": {"fallback": True}},
            },
        ],
    }
    path = tmp_path_factory.mktemp("khr") / "khr.glb"
    path.write_bytes(glb_bytes(doc, bytes(blob)))
    original = {
        "vertices": v,
        "faces": f,
        "normals": normals,
        "colours": colours,
        "ball": ball,
        "turns": turns,
        "rotation": rotation,
        "times": time_input,
    }
    return path, original


def test_a_khr_meshopt_document_reads_with_every_mode_and_filter(khr_file):
    path, original = khr_file
    doc, buffers = read_independently(path)
    document = load_document(path)
    assert len(document.decoded_views) == len(doc["bufferViews"]) == 8
    for i in range(len(doc["bufferViews"])):
        assert bytes(document.view_bytes(i)) == view_data(doc, buffers, i), f"bufferView {i}"
    spot, ball = document.triangle_primitives()
    v, f = original["vertices"], original["faces"]
    # EXPONENTIAL with 20-bit mantissas: float32 positions to about 2^-19 of their size.
    assert np.abs(spot.positions - v).max() < 4e-6 * np.abs(v).max()
    np.testing.assert_array_equal(spot.faces, f)
    normals = spot.attributes["NORMAL"]
    cosine = (normals * original["normals"]).sum(axis=1) / np.linalg.norm(normals, axis=1)
    assert np.degrees(np.arccos(np.clip(cosine, -1, 1))).max() < 0.05
    assert np.abs(spot.attributes["COLOR_0"] - original["colours"]).max() < 2 / 255
    np.testing.assert_allclose(ball.positions, original["ball"].vertices, rtol=0, atol=1e-7)
    # The index codec may rotate a triangle's corners (its winding stays).
    np.testing.assert_array_equal(canonical(ball.faces), canonical(original["ball"].faces))
    turns = document.accessor(original["rotation"])
    same_turn = np.abs((turns * original["turns"]).sum(axis=1))
    assert np.abs(same_turn - 1).max() < 1e-3
    np.testing.assert_array_equal(document.accessor(original["times"])[:, 0], np.arange(9) / 8)

    vertices, faces = meshbits.load_mesh(path)
    expected_vertices, expected_faces = world_mesh(doc, buffers)
    np.testing.assert_allclose(vertices, expected_vertices, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(faces, expected_faces)
    assert len(vertices) == len(v) + len(original["ball"].vertices)


def test_the_filters_decode_as_the_meshopt_package_decodes_them():
    rng = np.random.default_rng(3)
    n = 1001
    units = rng.normal(size=(n, 4))
    units /= np.linalg.norm(units, axis=1, keepdims=True)
    cases = [
        ("OCTAHEDRAL", 4, meshopt.encode_filter_oct(units, 4, 8)),
        ("OCTAHEDRAL", 8, meshopt.encode_filter_oct(units, 8, 13)),
        ("QUATERNION", 8, meshopt.encode_filter_quat(units, 8, 11)),
        ("EXPONENTIAL", 12, meshopt.encode_filter_exp(rng.normal(size=(n, 3)) * 1e3, 15)),
        ("COLOR", 4, meshopt.encode_filter_color(rng.random((n, 4)), 4, 8)),
        ("COLOR", 8, meshopt.encode_filter_color(rng.random((n, 4)), 8, 12)),
    ]
    for name, stride, rows in cases:
        stream = meshopt.encode_vertex_buffer(rows)
        ours = _core.meshopt_decode(stream, n, stride, "ATTRIBUTES", name)
        theirs = meshopt.decode_vertex_buffer(stream, n, stride, name)
        assert ours == np.ascontiguousarray(theirs).tobytes(), (name, stride)
        assert ours != rows.tobytes()  # the filter was undone, not skipped


# --- the binding, as a property -----------------------------------------------------------------


@settings(max_examples=80, deadline=None)
@given(
    stride=st.sampled_from([4, 8, 12, 16, 20, 64, 256]),
    count=st.integers(0, 700),
    version=st.sampled_from([0, 1]),
    seed=st.integers(0, 2**32 - 1),
    smooth=st.booleans(),
)
def test_vertex_streams_round_trip_through_the_binding(stride, count, version, seed, smooth):
    rng = np.random.default_rng(seed)
    if smooth:  # slowly varying records, what the codec is for
        records = np.cumsum(rng.integers(0, 3, size=(count, stride)), axis=0).astype(np.uint8)
    else:
        records = rng.integers(0, 256, size=(count, stride), dtype=np.uint8)
    if count == 0:
        stream = _core.meshopt_encode_vertices(np.zeros(0, dtype=np.uint8), stride)
    else:
        stream = meshopt.encode_vertex_buffer_level(records, 2, version)
    assert _core.meshopt_decode(stream, count, stride, "ATTRIBUTES") == records.tobytes()
    if count:
        with pytest.raises(meshbits.MeshbitsError, match=r"cannot be decoded|fewer than"):
            _core.meshopt_decode(stream[:-1], count, stride, "ATTRIBUTES")


@settings(max_examples=60, deadline=None)
@given(
    triangles=st.lists(st.tuples(*[st.integers(0, 500)] * 3), max_size=300),
    size=st.sampled_from([2, 4]),
)
def test_index_streams_round_trip_through_the_binding(triangles, size):
    indices = np.asarray(triangles, dtype=np.uint32).reshape(-1)
    dtype = np.uint16 if size == 2 else np.uint32
    sequence = meshopt.encode_index_sequence(indices)
    decoded = _core.meshopt_decode(sequence, len(indices), size, "INDICES")
    np.testing.assert_array_equal(np.frombuffer(decoded, dtype=dtype), indices)
    stream = meshopt.encode_index_buffer(indices)
    decoded = _core.meshopt_decode(stream, len(indices), size, "TRIANGLES")
    # The index codec may rotate a triangle's corners: the same as the package's decoder.
    expected = meshopt.decode_index_buffer(stream, len(indices), size)
    assert decoded == np.ascontiguousarray(expected).tobytes()
    rotated = np.frombuffer(decoded, dtype=dtype).reshape(-1, 3).astype(np.int64)
    np.testing.assert_array_equal(canonical(rotated), canonical(indices.reshape(-1, 3)))


def test_the_binding_refuses_what_the_extension_forbids():
    stream = meshopt.encode_vertex_buffer(np.zeros((10, 8), dtype=np.uint8))
    for args, words in [
        ((10, 6, "ATTRIBUTES"), "multiple of 4"),
        ((10, 8, "TRIANGLES"), "2 or 4 bytes"),
        ((10, 4, "TRIANGLES"), "multiple of 3"),
        ((10, 8, "ATTRIBUTES", "SMOOTH"), "unknown meshopt filter"),
        ((10, 4, "ATTRIBUTES", "QUATERNION"), "byteStride of 8"),
        ((9, 4, "INDICES", "OCTAHEDRAL"), "ATTRIBUTES streams only"),
        ((10**15, 8, "ATTRIBUTES"), "fewer than"),
    ]:
        with pytest.raises(meshbits.MeshbitsError, match=words):
            _core.meshopt_decode(stream, *args)
