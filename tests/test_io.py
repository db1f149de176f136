"""meshbits.load_mesh on damaged files: it raises MeshFileError (or FileNotFoundError) with
a message that names the problem, emits no warning, and allocates nothing the size of a
header's claim. Each case was found by the fuzz campaign (benches/fuzz.py,
docs/reliability.md)."""

from __future__ import annotations

import gzip
import json
import struct
import subprocess
import sys
import time
import warnings
import zlib

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import meshbits
from meshbits.errors import MeshFileError
from meshbits.formats import sniff

VERTICES = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
FACES = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]


def ply(
    fmt: str = "ascii",
    *,
    vertex_count: int | None = None,
    face_count: int | None = None,
    faces: list[list[int]] = FACES,
    count_type: str = "uchar",
    comment: str = "meshbits test",
) -> bytes:
    """A tetrahedron as PLY; the counts in the header may lie."""
    header = (
        f"ply\nformat {fmt} 1.0\ncomment {comment}\n"
        f"element vertex {len(VERTICES) if vertex_count is None else vertex_count}\n"
        "property float x\nproperty float y\nproperty float z\n"
        f"element face {len(faces) if face_count is None else face_count}\n"
        f"property list {count_type} int vertex_indices\nend_header\n"
    ).encode()
    if fmt == "ascii":
        rows = [" ".join(map(str, v)) for v in VERTICES]
        rows += [" ".join(map(str, [len(f), *f])) for f in faces]
        return header + ("\n".join(rows) + "\n").encode()
    data = np.asarray(VERTICES, dtype="<f4").tobytes()
    counts = {"uchar": "<u1", "uint": "<u4"}[count_type]
    for face in faces:
        data += np.array([len(face)], dtype=counts).tobytes() + np.array(face, "<i4").tobytes()
    return header + data


def off(vertex_count: int = 4, face_count: int = 4) -> bytes:
    lines = ["OFF", f"{vertex_count} {face_count} 0"]
    lines += [" ".join(map(str, v)) for v in VERTICES]
    lines += [" ".join(map(str, [3, *f])) for f in FACES]
    return ("\n".join(lines) + "\n").encode()


def stl_binary(count: int | None = None) -> bytes:
    triangles = np.asarray(VERTICES, dtype="<f4")[np.asarray(FACES)]
    records = np.zeros(len(FACES), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    records["v"] = triangles
    n = len(FACES) if count is None else count
    return b"\0" * 80 + struct.pack("<I", n) + records.tobytes()


def glb() -> bytes:
    import trimesh

    return trimesh.Trimesh(VERTICES, FACES, process=False).export(file_type="glb")


def refusal(tmp_path, name: str, data: bytes) -> str:
    path = tmp_path / name
    path.write_bytes(data)
    with pytest.raises(MeshFileError) as caught:
        meshbits.load_mesh(path)
    return str(caught.value)


def test_the_helpers_write_files_that_load(tmp_path):
    for name, data in [
        ("a.ply", ply()),
        ("b.ply", ply("binary_little_endian")),
        ("c.ply", ply("binary_little_endian", count_type="uint")),
        ("d.off", off()),
        ("e.stl", stl_binary()),
        ("f.glb", glb()),
        ("g.ply.gz", gzip.compress(ply())),
    ]:
        (tmp_path / name).write_bytes(data)
        assert meshbits.load_mesh(tmp_path / name)[1].shape == (4, 3), name


@pytest.mark.parametrize("fmt", ["ascii", "binary_little_endian"])
@pytest.mark.parametrize("count", [2**31, 10**12])
def test_a_small_ply_declaring_huge_counts_is_refused_at_once(tmp_path, fmt, count):
    """ASCII: a huge vertex count read as 'holds no triangles', a huge face count loaded
    the four faces; binary: 'PLY is unexpected length!'. Now the header is compared with
    the file's size before any parsing."""
    for counts in ({"vertex_count": count}, {"face_count": count}):
        start = time.perf_counter()
        message = refusal(tmp_path, "m.ply", ply(fmt, **counts))
        assert time.perf_counter() - start < 1.0
        assert "the PLY header declares" in message and f"{count:,}" in message, message


def test_an_ascii_ply_with_fewer_rows_than_declared_is_refused(tmp_path):
    """A face count of 2**31 over four faces used to load the four faces."""
    message = refusal(tmp_path, "m.ply", ply(face_count=2**31))
    assert "truncated" in message


def test_an_off_file_with_fewer_rows_than_declared_is_refused(tmp_path):
    """A face count of 10**12 over four faces used to load the four faces."""
    message = refusal(tmp_path, "m.off", off(face_count=10**12))
    assert "the OFF header declares 4 vertices and 1,000,000,000,000 faces" in message


def test_a_binary_stl_whose_count_disagrees_with_its_length_is_refused(tmp_path):
    """trimesh re-read it as ASCII and failed with "No module named 'charset_normalizer'"."""
    message = refusal(tmp_path, "m.stl", stl_binary(count=2**32 - 1))
    assert "the binary STL declares 4,294,967,295 triangles" in message


def test_a_text_file_named_stl_is_called_not_an_stl(tmp_path):
    """A README renamed .stl was "a binary STL declaring 1,797,286,003 triangles"."""
    text = "# A project\n\nSome prose about meshes, not an STL.\n" * 20
    message = refusal(tmp_path, "m.stl", text.encode())
    assert "not an STL file" in message and "text" in message


def test_glb_lengths_beyond_the_file_are_refused(tmp_path):
    """A header length of 2**32 - 1 loaded as if whole. A BIN chunk length of 2**32 - 1
    made trimesh ask for a 4 GiB read: a MemoryError under the campaign's 4 GiB
    address-space limit, 'chunk was not expected length!' without one."""
    data = bytearray(glb())
    data[8:12] = struct.pack("<I", 2**32 - 1)
    assert "the GLB header declares 4,294,967,295 bytes" in refusal(tmp_path, "a.glb", bytes(data))
    data = bytearray(glb())
    (json_length,) = struct.unpack_from("<I", data, 12)
    data[20 + json_length : 24 + json_length] = struct.pack("<I", 2**32 - 1)
    message = refusal(tmp_path, "b.glb", bytes(data))
    assert "GLB chunk 1 declares 4,294,967,295 bytes" in message


def test_a_binary_ply_list_longer_than_the_first_is_refused(tmp_path):
    """trimesh reads every list as long as the first one: a last face claiming 2**32 - 1
    corners was read as a triangle."""
    data = ply("binary_little_endian", count_type="uint")
    data = data[:-16] + struct.pack("<I", 2**32 - 1) + data[-12:]
    assert "face 3 has a list of 4294967295 items" in refusal(tmp_path, "m.ply", data)


def test_a_gzip_bomb_is_refused_before_it_inflates(tmp_path, monkeypatch):
    """A 1 MB .ply.gz of zeros inflating to 1 GiB peaked at 5.2 GB of memory."""
    monkeypatch.setattr(sniff, "GZIP_MIN_LIMIT", 1 << 20)
    compressor = zlib.compressobj(9, zlib.DEFLATED, 31)
    data = compressor.compress(ply("binary_little_endian"))
    data += compressor.compress(bytes(8 << 20)) + compressor.flush()
    assert len(data) < 20_000
    assert "it inflates to more than 1,048,576 bytes" in refusal(tmp_path, "m.ply.gz", data)


def test_loading_a_damaged_file_emits_no_warning(tmp_path):
    """A NaN in an ASCII face list made trimesh warn 'invalid value encountered in cast'."""
    data = ply().replace(b"3 1 2 3\n", b"3 1 nan 3\n")
    path = tmp_path / "m.ply"
    path.write_bytes(data)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with pytest.raises(MeshFileError):
            meshbits.load_mesh(path)
    assert not caught, [str(w.message) for w in caught]


def test_a_missing_texture_prints_nothing_on_stderr(tmp_path):
    """trimesh logged 'unable to load image!' with a traceback, which Python printed on
    stderr for want of a logging handler."""
    path = tmp_path / "m.ply"
    path.write_bytes(ply(comment="TextureFile missing.png"))
    done = subprocess.run(
        [sys.executable, "-m", "meshbits.cli", "k", str(path), "--json"],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0 and done.stderr == ""
    assert json.loads(done.stdout)["faces"] == 4


@pytest.mark.parametrize(
    ("name", "data", "expected"),
    [
        # Each used to end in the parser's own words, quoted after it in a comment.
        ("a.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 41\n", "beyond the 3 items the file defines"),
        # index 40 is out of bounds for axis 0 with size 3
        ("b.ply", ply().replace(b"meshbits test", b"\xff\xfe"), "a byte that is not text"),
        # 'utf-8' codec can't decode byte 0xff in position 8: invalid start byte
        ("c.ply", ply().replace(b"property float y", b"property foo y"), "unknown type 'foo'"),
        # 'foo'
        ("d.ply", ply().replace(b"property float y", b"property float q"), "no property 'y'"),
        # 'y'
        (
            "e.off",
            off().replace(b"0.0 1.0 0.0\n", b"0.0 x 0.0\n"),
            "'x' where a number was expected",
        ),
        # could not convert string to float: 'x'
        ("f.off", off().replace(b"4 4 0", b"4 4.5 0"), "the OFF face count is '4.5'"),
        # invalid literal for int() with base 10: '4.5'
        ("g.ply", ply().replace(b"element face 4", b"element face 0x4"), "not a whole number"),
        # invalid literal for int() with base 10: '0x4'
        ("h.glb", glb()[:100], "truncated"),
        # Unterminated string starting at: line 1 column 74 (char 73)
        ("i.txt", ply(), "does not read TXT files"),
        # file_type 'txt' not supported
        ("j", ply(), "cannot tell the format"),
        # file_type 'j' not supported
    ],
)
def test_damaged_files_get_messages_that_name_the_problem(tmp_path, name, data, expected):
    message = refusal(tmp_path, name, data)
    assert expected in message, message
    assert "\n" not in message


def test_a_draco_file_reads_back_as_draco_decodes_it(tmp_path):
    """``meshbits hausdorff mesh.ply out.drc`` said trimesh does not read DRC files: the
    library could not check its own output. A .drc is now decoded with DracoPy (its points
    and faces as DracoPy gives them), plain or gzipped; a damaged one is refused."""
    import DracoPy

    from meshbits.codecs import encode_draco

    spot = meshbits.load_mesh(meshbits.example_mesh_path())
    data = encode_draco(spot, 11).data
    path = tmp_path / "spot.drc"
    path.write_bytes(data)
    decoded = DracoPy.decode(data)
    for source in (path, tmp_path / "spot.drc.gz"):
        if source.suffix == ".gz":
            source.write_bytes(gzip.compress(data))
        vertices, faces = meshbits.load_mesh(source)
        assert np.array_equal(vertices, np.asarray(decoded.points, dtype=np.float64))
        assert np.array_equal(faces, np.asarray(decoded.faces, dtype=np.int64))
    damaged = tmp_path / "damaged.drc"
    damaged.write_bytes(data[: len(data) // 3])
    with pytest.raises(MeshFileError, match=r"damaged\.drc"):
        meshbits.load_mesh(damaged)


def _rich_gltf() -> dict:
    """A valid glTF document that uses every kind of reference the specification has: a
    node tree with a mesh, skin and camera; a primitive with normals, UVs, indices, a
    material and a morph target; textures with samplers and an embedded image; a sparse
    accessor; an animation. The buffer is a data URI."""
    import base64
    import io as _io

    from PIL import Image

    png = _io.BytesIO()
    Image.new("RGB", (2, 2), (200, 30, 30)).save(png, format="PNG")
    parts = [
        np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], "<f4").tobytes(),  # positions
        np.array([[0, 0, 1]] * 3, "<f4").tobytes(),  # normals
        np.array([[0, 0], [1, 0], [0, 1]], "<f4").tobytes(),  # uvs
        np.array([0, 1, 2, 0], "<u2").tobytes(),  # indices (padded)
        np.eye(4, dtype="<f4").tobytes(),  # inverse bind matrix
        np.array([0.0, 1.0], "<f4").tobytes(),  # animation times
        np.array([[0, 0, 0], [0, 0, 1]], "<f4").tobytes(),  # animation translations
        np.array([1], "<u2").tobytes() + b"\0\0",  # sparse indices (padded)
        np.array([[0, 0, 0.5]], "<f4").tobytes(),  # sparse values
        png.getvalue(),
    ]
    views, offset = [], 0
    for part in parts:
        views.append({"buffer": 0, "byteOffset": offset, "byteLength": len(part)})
        offset += len(part) + (-len(part) % 4)
    data = b"".join(p + b"\0" * (-len(p) % 4) for p in parts)
    views[3]["byteLength"] = 6
    views[7]["byteLength"] = 2
    vec3 = {"componentType": 5126, "type": "VEC3"}
    return {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0, 2]}],
        "nodes": [
            {"children": [1], "skin": 0, "camera": 0, "rotation": [0, 0, 0, 1], "scale": [1, 1, 1]},
            {"mesh": 0, "translation": [1, 0, 0]},
            {"matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]},
        ],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 1.0, "znear": 0.1}}],
        "meshes": [
            {
                "primitives": [
                    {
                        "attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2},
                        "indices": 3,
                        "material": 0,
                        "targets": [{"POSITION": 7}],
                    }
                ]
            }
        ],
        "accessors": [
            {**vec3, "bufferView": 0, "count": 3, "min": [0, 0, 0], "max": [1, 1, 0]},
            {**vec3, "bufferView": 1, "count": 3},
            {"componentType": 5126, "type": "VEC2", "bufferView": 2, "count": 3},
            {"componentType": 5123, "type": "SCALAR", "bufferView": 3, "count": 3},
            {"componentType": 5126, "type": "MAT4", "bufferView": 4, "count": 1},
            {"componentType": 5126, "type": "SCALAR", "bufferView": 5, "count": 2},
            {**vec3, "bufferView": 6, "count": 2},
            {
                **vec3,
                "count": 3,
                "sparse": {
                    "count": 1,
                    "indices": {"bufferView": 7, "componentType": 5123},
                    "values": {"bufferView": 8},
                },
            },
        ],
        "bufferViews": views,
        "buffers": [
            {
                "byteLength": len(data),
                "uri": "data:application/octet-stream;base64," + base64.b64encode(data).decode(),
            }
        ],
        "materials": [
            {
                "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}},
                "normalTexture": {"index": 0},
            }
        ],
        "textures": [{"source": 0, "sampler": 0}],
        "samplers": [{}],
        "images": [{"bufferView": 9, "mimeType": "image/png"}],
        "skins": [{"joints": [1], "inverseBindMatrices": 4, "skeleton": 0}],
        "animations": [
            {
                "samplers": [{"input": 5, "output": 6}],
                "channels": [{"sampler": 0, "target": {"node": 1, "path": "translation"}}],
            }
        ],
    }


def _reference_paths(value, path=()):
    """Every place in a document that holds an index (an int under a key that names one),
    as a tuple of keys."""
    names = {
        "scene", "nodes", "children", "mesh", "skin", "camera", "indices", "material",
        "bufferView", "buffer", "source", "sampler", "index", "joints", "skeleton",
        "inverseBindMatrices", "input", "output", "node", "POSITION", "NORMAL", "TEXCOORD_0",
    }  # fmt: skip
    if isinstance(value, dict):
        for key, inner in value.items():
            if key in names and isinstance(inner, int) and not isinstance(inner, bool):
                yield (*path, key)
            yield from _reference_paths(inner, (*path, key))
    elif isinstance(value, list):
        for k, inner in enumerate(value):
            if isinstance(inner, int) and path and path[-1] in names:
                yield (*path, k)
            yield from _reference_paths(inner, (*path, k))


RICH_GLTF_PATHS = sorted(_reference_paths(_rich_gltf()), key=str)


def _value_paths(value, path=()):
    """Every place that holds a count, offset, length, stride, type, mode, transform or
    animation path: what a reader sizes or shapes its arrays by."""
    names = {
        "count", "byteOffset", "byteLength", "byteStride", "componentType", "type", "mode",
        "matrix", "translation", "rotation", "scale", "path", "primitives", "normalized",
    }  # fmt: skip
    if isinstance(value, dict):
        for key, inner in value.items():
            if key in names:
                yield (*path, key)
            yield from _value_paths(inner, (*path, key))
    elif isinstance(value, list):
        for k, inner in enumerate(value):
            yield from _value_paths(inner, (*path, k))


RICH_GLTF_VALUE_PATHS = sorted(_value_paths(_rich_gltf()), key=str)


@settings(
    max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    edits=st.lists(
        st.tuples(
            st.sampled_from(RICH_GLTF_PATHS + RICH_GLTF_VALUE_PATHS),
            st.one_of(
                st.integers(-2, 12),
                st.sampled_from([2, 3, 16, 5126, 5123, 2**31, 10**12, -(2**31), "VEC3", "MAT4"]),
                st.lists(st.floats(-2, 2), min_size=2, max_size=5),
                st.none(),
                st.booleans(),
                st.floats(allow_nan=True),
                st.text(max_size=2),
                st.lists(st.integers(0, 3), max_size=2),
                st.dictionaries(st.text(max_size=1), st.integers(0, 2), max_size=1),
            ),
        ),
        min_size=1,
        max_size=3,
    )
)
def test_a_gltf_with_any_broken_reference_is_refused_in_words(tmp_path, edits):
    """Whatever index of a valid document is replaced (out of range, negative, another
    type), reading it (and compressing it as a scene) gives a result or a MeshbitsError:
    never a KeyError, IndexError, TypeError or a reader's internal error (what a new
    user's hand-made files got)."""
    from meshbits.formats import load_document
    from meshbits.scene import scene_info

    document = _rich_gltf()
    for path, value in edits:
        parent = document
        try:
            for key in path[:-1]:
                parent = parent[key]
            parent[path[-1]]  # an earlier edit may have replaced the container
        except (KeyError, IndexError, TypeError):
            continue
        parent[path[-1]] = value
    file = tmp_path / "broken.gltf"
    file.write_text(json.dumps(document))

    def compress(path):
        return meshbits.compress_scene(path, error=0.01, output=tmp_path / "out.glb")

    for read in (meshbits.load_mesh, load_document, scene_info, compress):
        try:
            read(file)
        except meshbits.MeshbitsError:
            pass


def test_attributes_of_different_counts_are_refused_in_words(tmp_path):
    """Found by the property test above: a NORMAL accessor of 0 rows beside 3 positions
    went through the reader and reached the meshopt encoder as an IndexError."""
    from meshbits.formats import load_document

    document = _rich_gltf()
    document["accessors"][1]["count"] = 0
    file = tmp_path / "counts.gltf"
    file.write_text(json.dumps(document))
    for read in (load_document, meshbits.load_mesh):
        with pytest.raises(meshbits.MeshbitsError, match=r"NORMAL has 0 rows.*POSITION 3"):
            read(file)
    with pytest.raises(meshbits.MeshbitsError, match="one row per vertex"):
        meshbits.compress_scene(file, error=0.01, codec="meshopt", output=tmp_path / "o.glb")


def test_the_rich_gltf_document_reads_whole(tmp_path):
    """The property test above starts from a valid document: every reader takes it."""
    from meshbits.formats import load_document
    from meshbits.scene import scene_info

    file = tmp_path / "rich.gltf"
    file.write_text(json.dumps(_rich_gltf()))
    vertices, faces = meshbits.load_mesh(file)
    assert len(faces) == 1 and vertices[:, 0].max() == pytest.approx(2.0)  # node translation
    document = load_document(file)
    assert len(document.json["meshes"]) == 1
    info = scene_info(file)
    assert info["meshes"][0]["primitives"][0]["faces"] == 1
    assert len(RICH_GLTF_PATHS) >= 25
