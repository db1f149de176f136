"""meshbits.formats.gltf and meshbits.formats.sniff: a glTF document read into numpy (round
trips through save_mesh, node transforms, strips and fans, normalized and sparse
accessors, instancing), refused in words when a reference or value is broken, and the
header sniffing that comes before any parser."""

from __future__ import annotations

import base64
import json
import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import meshbits
from meshbits.errors import MeshFileError
from meshbits.files import asset_bytes, external_files
from meshbits.formats import Document, load_document, save_mesh
from meshbits.formats.gltf.spec import TRIANGLE_FAN, TRIANGLE_STRIP, trs_matrix
from meshbits.formats.gltf.validate import check_references, finite_or_fail
from meshbits.formats.gltf.write import (
    FRAME_DISTANCE,
    frame_centre,
    json_text,
    number_text,
    split_translation,
)
from meshbits.formats.open import check_structure
from meshbits.formats.sniff import file_type_of, image_size, mime_type

VERTICES = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
FACES = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])


def _uri(data: bytes) -> str:
    return "data:application/octet-stream;base64," + base64.b64encode(data).decode()


def square_document(**primitive) -> dict:
    """A unit square in the z = 0 plane: four float32 positions, six uint16 indices, one
    node; ``primitive`` overrides the primitive's fields."""
    positions = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype="<f4").tobytes()
    indices = np.array([0, 1, 2, 0, 2, 3], dtype="<u2").tobytes()
    blob = positions + indices
    return {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, **primitive}]}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3"},
            {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"},
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 12},
        ],
        "buffers": [{"byteLength": len(blob), "uri": _uri(blob)}],
    }


def write(tmp_path, document: dict, name: str = "doc.gltf"):
    path = tmp_path / name
    path.write_text(json.dumps(document))
    return path


# --- reading ----------------------------------------------------------------------------


@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
def test_a_saved_mesh_reads_back_as_a_document(tmp_path, suffix):
    path = save_mesh(tmp_path / f"tetra{suffix}", VERTICES, FACES)
    document = load_document(path)
    assert isinstance(document, Document)
    (primitive,) = document.triangle_primitives()
    assert primitive.positions.dtype == np.float64
    np.testing.assert_array_equal(primitive.positions, VERTICES)
    np.testing.assert_array_equal(primitive.faces, FACES)
    vertices, faces = document.world_triangles()
    loaded = meshbits.load_mesh(path)
    np.testing.assert_array_equal(vertices, loaded[0])
    np.testing.assert_array_equal(faces, loaded[1])


def test_a_gltf_is_written_with_its_buffer_named_after_it(tmp_path):
    path = save_mesh(tmp_path / "out.gltf", VERTICES, FACES)
    assert (tmp_path / "out.bin").is_file()
    assert external_files(path) == [("out.bin", tmp_path / "out.bin")]
    assert asset_bytes(path) == path.stat().st_size + (tmp_path / "out.bin").stat().st_size


def test_a_ply_far_from_the_origin_keeps_its_float64_positions(tmp_path):
    path = save_mesh(tmp_path / "far.ply", VERTICES * 1e-3 + 1e4, FACES)
    stored, _ = meshbits.load_mesh(path)  # as the PLY holds them (float32 or float64)
    document = load_document(path)
    (primitive,) = document.triangle_primitives()
    vertices, _ = document.world_triangles()
    np.testing.assert_array_equal(vertices, stored)
    root = document.json["nodes"][document.json["scenes"][0]["nodes"][0]]
    assert root["translation"] == list(frame_centre(stored))
    assert np.abs(primitive.positions).max() < 1


def test_node_transforms_place_the_triangles_in_the_world(tmp_path):
    document = square_document()
    turn = [0.0, 0.0, np.sin(np.pi / 4), np.cos(np.pi / 4)]  # 90 degrees about z
    document["nodes"] = [{"children": [1], "translation": [10, 0, 0]}, {"mesh": 0}]
    document["nodes"][1] |= {"rotation": turn, "scale": [2, 2, 2]}
    vertices, faces = load_document(write(tmp_path, document)).world_triangles()
    assert faces.shape == (2, 3)
    np.testing.assert_allclose(vertices[2], [10 - 2, 2, 0], atol=1e-12)
    np.testing.assert_allclose(trs_matrix([10, 0, 0], turn, [2, 2, 2])[:3, 3], [10, 0, 0])


def test_matrix_nodes_and_gpu_instances_each_give_a_copy(tmp_path):
    document = square_document()
    shifts = np.array([[0, 0, 0], [0, 0, 5], [0, 0, 9]], dtype="<f4").tobytes()
    document["buffers"].append({"byteLength": len(shifts), "uri": _uri(shifts)})
    document["bufferViews"].append({"buffer": 1, "byteLength": len(shifts)})
    document["accessors"].append(
        {"bufferView": 2, "componentType": 5126, "count": 3, "type": "VEC3"}
    )
    matrix = np.eye(4)
    matrix[3, :3] = [1, 2, 3]  # column-major: the translation's row
    document["nodes"] = [
        {
            "mesh": 0,
            "matrix": matrix.reshape(-1).tolist(),
            "extensions": {"EXT_mesh_gpu_instancing": {"attributes": {"TRANSLATION": 2}}},
        }
    ]
    loaded = load_document(write(tmp_path, document))
    assert loaded.instanced_meshes() == {0}
    vertices, faces = loaded.world_triangles()
    assert len(faces) == 6
    np.testing.assert_allclose(vertices[[0, 4, 8], 2], [3, 8, 12])
    np.testing.assert_allclose(vertices[0, :2], [1, 2])


@pytest.mark.parametrize(
    ("mode", "expected"),
    [(TRIANGLE_STRIP, [[0, 1, 2], [2, 1, 0], [2, 0, 2]]), (TRIANGLE_FAN, [[0, 1, 2], [0, 2, 0]])],
)
def test_strips_and_fans_become_triangle_lists(tmp_path, mode, expected):
    primitive = load_document(write(tmp_path, square_document(mode=mode))).primitive(0, 0)
    assert primitive is not None
    np.testing.assert_array_equal(primitive.faces[: len(expected)], expected)


def test_points_and_lines_are_not_triangle_primitives(tmp_path):
    document = load_document(write(tmp_path, square_document(mode=0)))
    assert document.primitive(0, 0) is None
    assert document.triangle_primitives() == []
    with pytest.raises(MeshFileError, match="holds no triangles"):
        document.world_triangles()


def test_normalized_and_sparse_accessors_read_as_the_spec_maps_them(tmp_path):
    document = square_document()
    colours = np.array([[0, 255], [51, 102], [255, 0], [0, 0]], dtype="u1").tobytes()
    ids, values = np.array([1], dtype="<u2").tobytes(), np.array([[7, 8, 9]], "<f4").tobytes()
    extra = colours + ids + b"\0\0" + values
    document["buffers"].append({"byteLength": len(extra), "uri": _uri(extra)})
    document["bufferViews"] += [
        {"buffer": 1, "byteLength": 8},
        {"buffer": 1, "byteOffset": 8, "byteLength": 2},
        {"buffer": 1, "byteOffset": 12, "byteLength": 12},
    ]
    document["accessors"] += [
        {"bufferView": 2, "componentType": 5121, "normalized": True, "count": 4, "type": "VEC2"},
        {
            "componentType": 5126,
            "count": 4,
            "type": "VEC3",
            "sparse": {
                "count": 1,
                "indices": {"bufferView": 3, "componentType": 5123},
                "values": {"bufferView": 4},
            },
        },
    ]
    loaded = load_document(write(tmp_path, document))
    np.testing.assert_allclose(loaded.accessor(2)[:2], [[0, 1], [0.2, 0.4]])
    np.testing.assert_array_equal(loaded.accessor(2, normalize=False)[0], [0, 255])
    np.testing.assert_array_equal(loaded.accessor(3), [[0, 0, 0], [7, 8, 9], [0, 0, 0], [0] * 3])


def test_a_document_that_is_not_gltf_2_is_refused():
    with pytest.raises(MeshFileError, match=r"not a glTF 2\.0 document \(asset.version '1.0'\)"):
        Document({"asset": {"version": "1.0"}}, [], None)


# --- validation -------------------------------------------------------------------------


def _set(document: dict, path: tuple, value) -> dict:
    parent = document
    for key in path[:-1]:
        parent = parent[key]
    parent[path[-1]] = value
    return document


@pytest.mark.parametrize(
    ("path", "value", "message"),
    [
        (
            ("meshes", 0, "primitives", 0, "material"),
            3,
            r"meshes\[0\]\.primitives\[0\]\.material is 3, past the end of materials \(0\)",
        ),
        (
            ("meshes", 0, "primitives", 0, "indices"),
            "1",
            r"primitives\[0\]\.indices is '1', not an index into accessors",
        ),
        (("scenes", 0, "nodes"), [5], r"scenes\[0\]\.nodes\[0\] is 5, past the end of nodes"),
        (("nodes", 0, "children"), [0], r"nodes\[0\]\.children holds node 0, itself"),
        (("accessors", 0, "count"), -1, r"accessors\[0\]\.count is -1, not a count"),
        (
            ("accessors", 1, "componentType"),
            5124,
            r"accessors\[1\]\.componentType is 5124, not a glTF",
        ),
        (("bufferViews", 1, "byteOffset"), 60, r"bufferViews\[1\] ends at byte 72, past its"),
        (
            ("bufferViews", 0, "byteStride"),
            6,
            r"bufferViews\[0\]\.byteStride is 6: not a multiple of 4",
        ),
        (("accessors", 0, "type"), "VEC2", r"attributes\.POSITION is a VEC2 accessor, not VEC3"),
        (("nodes", 0, "scale"), [1, 1], r"nodes\[0\]\.scale is not 3 finite numbers"),
        (
            ("meshes", 0, "primitives", 0, "mode"),
            7,
            r"primitives\[0\]\.mode is 7, not a glTF primitive mode",
        ),
        (("textures",), {}, r"textures is not an array of objects"),
    ],
)
def test_a_broken_reference_or_value_is_refused_naming_it(tmp_path, path, value, message):
    document = _set(square_document(), path, value)
    with pytest.raises(MeshFileError, match=message):
        check_references(document)
    with pytest.raises(MeshFileError, match=r"cannot read .*doc\.gltf: .*" + message):
        load_document(write(tmp_path, document))


def test_a_node_cycle_is_refused():
    document = square_document()
    document["nodes"] = [{"children": [1]}, {"children": [0], "mesh": 0}]
    with pytest.raises(MeshFileError, match=r"nodes\[0\] is its own ancestor"):
        check_references(document)


def test_the_valid_document_passes_the_checks():
    check_references(square_document())


def test_non_finite_positions_are_named_by_row():
    finite_or_fail("positions", np.zeros((3, 3)))
    with pytest.raises(MeshFileError, match=r"positions\[1\] = \[nan, 0\.0, 0\.0\] is not"):
        finite_or_fail("positions", np.array([[0, 0, 0], [np.nan, 0, 0], [np.inf, 0, 0]]))


def test_the_frame_centre_moves_only_a_far_mesh():
    assert not frame_centre(VERTICES).any()
    assert not frame_centre(np.zeros((0, 3))).any()
    far = VERTICES + (FRAME_DISTANCE + 1)
    np.testing.assert_array_equal(frame_centre(far), [18, 18, 18])


@settings(max_examples=400, deadline=None)
@given(st.floats(allow_nan=False, allow_infinity=False))
def test_a_number_is_written_exactly_and_never_longer_than_json_writes_it(value):
    text = number_text(value)
    assert float(json.loads(text)) == value
    assert len(text) <= len(json.dumps(value))


def test_numbers_the_writer_shortens():
    assert [number_text(x) for x in (420000.0, 5.4e6, -0.0, 100.0, 1e-05, 1.5e20)] == [
        "42e4",
        "54e5",
        "0",
        "100",
        "1e-5",
        "1.5e20",
    ]
    # Only a copied input's own JSON can hold one (Python's json reads NaN): kept as it was.
    assert [number_text(x) for x in (float("nan"), float("-inf"))] == ["NaN", "-Infinity"]


json_values = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(-(2**53), 2**53)
    | st.floats(allow_nan=False, allow_infinity=False)
    | st.text(max_size=8),
    lambda inner: (
        st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner, max_size=4)
    ),
    max_leaves=20,
)


@settings(max_examples=200, deadline=None)
@given(json_values)
def test_a_document_reads_back_as_it_was_written(document):
    """Equal values (a float integral in value may read back as an integer: JSON has one
    number type); an integer is written as an integer, never with an exponent."""
    assert json.loads(json_text(document)) == document
    if isinstance(document, int) and not isinstance(document, bool):
        assert json_text(document) == str(document).encode()


@settings(max_examples=300, deadline=None)
@given(
    st.lists(st.floats(-1e8, 1e8, allow_nan=False), min_size=3, max_size=3),
    st.floats(1e-9, 1e4),
)
def test_a_split_translation_is_a_short_float32_and_a_small_rest(translation, extent):
    """The outer part is a float32 exactly (a float32 reader of node transforms places it
    as a float64 reader does), within half a unit of the translation (the unit: the power
    of two at or above the extent and the float32 spacing there), and never written
    longer than the multiple of that unit nearest to it."""
    outer, inner = split_translation(np.array(translation), extent)
    largest = max(abs(x) for x in translation)
    unit = max(2.0 ** np.ceil(np.log2(extent)), float(np.spacing(np.float32(largest))))
    np.testing.assert_array_equal(outer.astype(np.float32).astype(np.float64), outer)
    assert np.abs(inner).max() <= unit / 2
    np.testing.assert_array_equal(outer + inner, translation)
    for part, value in zip(outer, translation, strict=True):
        assert len(number_text(part)) <= len(number_text(round(value / unit) * unit))


def test_a_georeferenced_centre_is_a_short_decimal():
    far = VERTICES * 0.1 + [4.2e5, 5.4e6, 0.0]
    centre = frame_centre(far)
    assert [number_text(x) for x in centre] == ["42e4", "54e5", "0"]


# --- sniffing ---------------------------------------------------------------------------


def test_a_glb_requiring_an_unread_extension_is_refused_before_parsing(tmp_path):
    document = {"asset": {"version": "2.0"}, "extensionsRequired": ["KHR_fancy_geometry"]}
    text = json.dumps(document).encode()
    text += b" " * (-len(text) % 4)
    data = b"glTF" + struct.pack("<II", 2, 20 + len(text)) + struct.pack("<I", len(text))
    data += b"JSON" + text
    with pytest.raises(MeshFileError, match="requires the extension KHR_fancy_geometry"):
        check_structure("glb", data, len(data))
    file = tmp_path / "x.glb"
    file.write_bytes(data)
    with pytest.raises(MeshFileError, match="requires the extension KHR_fancy_geometry"):
        meshbits.load_mesh(file)


@pytest.mark.parametrize(
    ("file_type", "data", "message"),
    [
        ("ply", b"", "the file is empty"),
        ("ply", b"ply\nformat ascii 1.0\nelement vertex 9\n", "no end_header line"),
        ("off", b"OFF\n3 1 0\n0 0 0\n", "declares 3 vertices and 1 face, but 1 line follow"),
        ("stl", b"x" * 10, "too short for a binary STL"),
        ("glb", b"glTF" + bytes(4), "does not start with a GLB header"),
    ],
)
def test_headers_are_checked_against_the_file(file_type, data, message):
    with pytest.raises(MeshFileError, match=message):
        check_structure(file_type, data, len(data))


def test_formats_without_a_header_pass_the_check():
    check_structure("obj", b"v 0 0 0\n", 8)


def test_the_file_type_comes_from_the_name(tmp_path):
    assert file_type_of(tmp_path / "a.PLY") == ("ply", False)
    assert file_type_of(tmp_path / "a.b.obj.gz") == ("obj", True)
    for name in ("a.gz", "noext"):
        with pytest.raises(MeshFileError, match="cannot tell the format"):
            file_type_of(tmp_path / name)


def test_image_sizes_are_read_from_their_headers():
    png = b"\x89PNG\r\n\x1a\n" + bytes(8) + struct.pack(">II", 640, 480)
    jpeg = b"\xff\xd8" + b"\xff\xc0" + struct.pack(">HBHH", 17, 8, 300, 200) + bytes(10)
    webp = b"RIFF" + bytes(4) + b"WEBPVP8X" + bytes(8) + (99).to_bytes(3, "little") * 2
    assert image_size(png) == (640, 480)
    assert image_size(jpeg) == (200, 300)
    assert image_size(webp) == (100, 100)
    assert image_size(b"GIF89a" + bytes(20)) is None
    assert mime_type("a.JPG") == "image/jpeg"
    assert mime_type("a.gif") is None
