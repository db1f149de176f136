"""The Rust readers (meshbits.formats.native, rust/io/): PLY, STL and OBJ read into
float64 vertices and uint32 faces, checked against trimesh's reading of the same files
(written by trimesh, or by hand with numpy from known arrays), and damaged files never
getting past them (left to the general path, which refuses them as before)."""

from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import meshbits
from meshbits import _core
from meshbits.cli import main
from meshbits.errors import MeshFileError
from meshbits.formats import read_mesh

DATA = Path(__file__).parent / "data"
SETTINGS = settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)


def trimesh_arrays(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """trimesh's reading of a file, scenes concatenated, as load_mesh did before."""
    loaded = trimesh.load(path, process=False)
    if isinstance(loaded, trimesh.Scene):
        loaded = trimesh.util.concatenate(list(loaded.dump()))
    return np.asarray(loaded.vertices, dtype=np.float64), np.asarray(loaded.faces, np.int64)


def corners(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """The triangles as corner positions, each as its smallest rotation (same
    orientation), rows sorted: equal for the same triangles in any order and any
    vertex numbering or fan start."""
    tri = vertices[np.asarray(faces, dtype=np.int64)]
    keys = [tuple(map(tuple, t)) for t in tri]
    rotated = []
    for t in keys:
        rotated.append(min(t[k:] + t[:k] for k in range(3)))
    return np.array(sorted(rotated)).reshape(-1, 9)


def fan(polygons: list[list[int]]) -> np.ndarray:
    return np.array([[p[0], p[k], p[k + 1]] for p in polygons for k in range(1, len(p) - 1)])


@pytest.mark.parametrize("name", sorted(p.stem for p in DATA.glob("*.ply")))
def test_the_test_meshes_read_as_trimesh_reads_them(name):
    path = DATA / f"{name}.ply"
    read = read_mesh(path)
    assert read.reader == "meshbits"
    assert read.vertices.dtype == np.float64 and read.faces.dtype == np.uint32
    vertices, faces = trimesh_arrays(path)
    assert np.array_equal(read.vertices, vertices)
    assert np.array_equal(read.faces, faces)
    assert read.polygons == 0


def random_meshes(least_vertices: int, most_vertices: int, most_corners: int, most_faces: int):
    """(vertices, faces) of float32-exact coordinates and faces of 3 to ``most_corners``
    distinct corners."""
    return st.integers(least_vertices, most_vertices).flatmap(
        lambda n: st.tuples(
            st.lists(
                st.tuples(*[st.floats(-1e3, 1e3, allow_nan=False, width=32)] * 3),
                min_size=n,
                max_size=n,
            ),
            st.lists(
                st.lists(st.integers(0, n - 1), min_size=3, max_size=most_corners, unique=True),
                min_size=1,
                max_size=most_faces,
            ),
        )
    )


meshes = random_meshes(4, 40, most_corners=3, most_faces=60)


@SETTINGS
@given(mesh=meshes, kind=st.sampled_from(["ply", "ply-ascii", "stl", "stl-ascii", "obj"]))
def test_files_trimesh_writes_read_as_trimesh_reads_them(tmp_path, mesh, kind):
    vertices = np.asarray(mesh[0], dtype=np.float64)
    faces = np.asarray(mesh[1], dtype=np.int64)
    exported = trimesh.Trimesh(vertices, faces, process=False)
    suffix = kind.split("-")[0]
    path = tmp_path / f"m.{suffix}"
    data = exported.export(file_type=suffix, encoding="ascii") if kind == "ply-ascii" else None
    if kind == "stl-ascii":
        data = trimesh.exchange.stl.export_stl_ascii(exported)
    if data is None:
        data = exported.export(file_type=suffix)
    path.write_bytes(data.encode() if isinstance(data, str) else data)
    read = read_mesh(path)
    assert read.reader == "meshbits", kind
    want_v, want_f = trimesh_arrays(path)
    if suffix == "obj":  # trimesh re-indexes an OBJ's vertices: compare the triangles
        assert len(read.faces) == len(want_f)
        assert np.array_equal(corners(read.vertices, read.faces), corners(want_v, want_f))
    else:
        assert np.array_equal(read.vertices, want_v), kind
        assert np.array_equal(read.faces, want_f), kind


def binary_ply(
    vertices: np.ndarray,
    polygons: list[list[int]],
    *,
    order: str,
    coordinate: str,
    count: str,
    index: str,
    extra_first: bool,
) -> bytes:
    """A binary PLY written with numpy from known arrays: an extra vertex property (before
    or after x, y, z, in another order), an extra face property, any list types."""
    types = {
        "float": "f4",
        "double": "f8",
        "uchar": "u1",
        "ushort": "u2",
        "int": "i4",
        "uint": "u4",
    }
    e = {"binary_little_endian": "<", "binary_big_endian": ">"}[order]
    props = ["z", "x", "y"]
    fields = [(p, e + types[coordinate]) for p in props]
    fields.insert(0 if extra_first else 3, ("quality", e + "f4"))
    rows = np.zeros(len(vertices), dtype=fields)
    for k, axis in enumerate("xyz"):
        rows[axis] = vertices[:, k]
    rows["quality"] = 0.5
    head = [f"ply\nformat {order} 1.0\nelement vertex {len(vertices)}"]
    head += [
        f"property {'float' if name == 'quality' else coordinate} {name}" for name, _ in fields
    ]
    head += [f"element face {len(polygons)}", "property uchar flags"]
    head += [f"property list {count} {index} vertex_indices", "end_header\n"]
    body = bytearray(rows.tobytes())
    for polygon in polygons:
        body += b"\x07" + np.array([len(polygon)], e + types[count]).tobytes()
        body += np.array(polygon, e + types[index]).tobytes()
    return "\n".join(head).encode() + bytes(body)


polygon_meshes = random_meshes(5, 30, most_corners=6, most_faces=40)


@SETTINGS
@given(
    mesh=polygon_meshes,
    order=st.sampled_from(["binary_little_endian", "binary_big_endian"]),
    coordinate=st.sampled_from(["float", "double"]),
    count=st.sampled_from(["uchar", "ushort", "int", "uint"]),
    index=st.sampled_from(["int", "uint"]),
    extra_first=st.booleans(),
)
def test_binary_ply_layouts_read_to_the_arrays_written(
    tmp_path, mesh, order, coordinate, count, index, extra_first
):
    """Any property order, float or double, any list types, either byte order, extra
    properties, polygons of mixed sizes: the arrays written, polygons fanned and counted."""
    vertices = np.asarray(mesh[0], dtype=np.float64)
    polygons = mesh[1]
    path = tmp_path / "m.ply"
    layout = dict(order=order, coordinate=coordinate, count=count, index=index)
    path.write_bytes(binary_ply(vertices, polygons, extra_first=extra_first, **layout))
    read = read_mesh(path)
    assert read.reader == "meshbits"
    assert np.array_equal(read.vertices, vertices)
    assert np.array_equal(read.faces, fan(polygons))
    assert read.polygons == sum(len(p) > 3 for p in polygons)
    assert read.polygon_triangles == sum(len(p) - 2 for p in polygons if len(p) > 3)
    if len({len(p) for p in polygons}) == 1:  # trimesh reads one polygon size only
        assert np.array_equal(corners(read.vertices, read.faces), corners(*trimesh_arrays(path)))


@SETTINGS
@given(
    mesh=polygon_meshes,
    relative=st.booleans(),
    form=st.sampled_from(["{}", "{}/1", "{}//1", "{}/1/1"]),
)
def test_obj_polygons_corner_forms_and_negative_indices(tmp_path, mesh, relative, form):
    """``f a``, ``a/b``, ``a//c``, ``a/b/c``, negative indices; polygons fanned, counted,
    and the triangles trimesh reads."""
    vertices = np.asarray(mesh[0], dtype=np.float64)
    polygons = mesh[1]
    n = len(vertices)
    lines = ["# test", "o thing"] + [f"v {x!r} {y!r} {z!r}" for x, y, z in vertices.tolist()]
    lines += ["vt 0 0", "vn 0 0 1", "l 1 2"]
    for p in polygons:
        refs = [str(i - n if relative else i + 1) for i in p]
        lines.append("f " + " ".join(form.format(r) for r in refs))
    path = tmp_path / "m.obj"
    path.write_text("\n".join(lines) + "\n")
    read = read_mesh(path)
    assert read.reader == "meshbits"
    assert np.array_equal(read.vertices, vertices)
    assert np.array_equal(read.faces, fan(polygons))
    assert read.polygons == sum(len(p) > 3 for p in polygons)
    assert read.skipped_elements == 1
    assert np.array_equal(corners(read.vertices, read.faces), corners(*trimesh_arrays(path)))


@SETTINGS
@given(mesh=polygon_meshes)
def test_ascii_ply_polygons_read_as_trimesh_reads_them(tmp_path, mesh):
    vertices = np.asarray(mesh[0], dtype=np.float32).astype(np.float64)
    polygons = mesh[1]
    head = (
        f"ply\nformat ascii 1.0\nelement vertex {len(vertices)}\nproperty float x\n"
        f"property float y\nproperty float z\nelement face {len(polygons)}\n"
        "property list uchar int vertex_indices\nend_header\n"
    )
    rows = [" ".join(repr(float(c)) for c in v) for v in vertices]
    rows += [" ".join(map(str, [len(p), *p])) for p in polygons]
    path = tmp_path / "m.ply"
    path.write_text(head + "\n".join(rows) + "\n")
    read = read_mesh(path)
    assert read.reader == "meshbits"
    assert np.array_equal(read.vertices, vertices)
    assert np.array_equal(read.faces, fan(polygons))
    assert np.array_equal(corners(read.vertices, read.faces), corners(*trimesh_arrays(path)))


def sources(tmp_path: Path) -> dict[str, bytes]:
    ball = trimesh.creation.icosphere(subdivisions=2)
    quad = binary_ply(
        np.asarray(ball.vertices),
        [[*f, f[0]][:3] + ([int(f[2])] if k % 2 else []) for k, f in enumerate(ball.faces)],
        order="binary_big_endian",
        coordinate="double",
        count="ushort",
        index="uint",
        extra_first=True,
    )
    return {
        ".ply": (DATA / "suzanne.ply").read_bytes(),
        "-quad.ply": quad,
        "-ascii.ply": ball.export(file_type="ply", encoding="ascii"),
        ".stl": ball.export(file_type="stl"),
        "-ascii.stl": trimesh.exchange.stl.export_stl_ascii(ball).encode(),
        ".obj": ball.export(file_type="obj").encode(),
    }


@SETTINGS
@given(data=st.data())
def test_damaged_files_never_get_past_the_readers(tmp_path, data):
    """Bytes flipped, truncated or inserted: the Rust reader returns arrays it checked
    (indices in range, finite coordinates) or leaves the file to the general path; no
    panic, no other exception."""
    all_sources = sources(tmp_path)
    name = data.draw(st.sampled_from(sorted(all_sources)))
    damaged = bytearray(all_sources[name])
    edit = data.draw(st.sampled_from(["flip", "truncate", "insert"]))
    at = data.draw(st.integers(0, len(damaged) - 1))
    if edit == "flip":
        for k in range(data.draw(st.integers(1, 8))):
            damaged[(at + 97 * k) % len(damaged)] = data.draw(st.integers(0, 255))
    elif edit == "truncate":
        del damaged[at:]
    else:
        damaged[at:at] = data.draw(st.binary(min_size=1, max_size=8))
    path = tmp_path / f"d{name}"
    path.write_bytes(bytes(damaged))
    outcome = _core.read_mesh(str(path), path.suffix.lstrip("."))
    if isinstance(outcome, str):
        return
    vertices, faces, counts = outcome
    assert vertices.dtype == np.float64 and faces.dtype == np.uint32
    assert np.isfinite(vertices).all() and len(faces) > 0
    assert int(faces.max()) < len(vertices)
    assert set(counts) == {"polygons", "polygon_triangles", "skipped_elements"}


def test_a_mixed_polygon_binary_ply_is_read_and_counted(tmp_path, capsys):
    """A binary PLY of triangles and quads was refused ('mixes polygon sizes'): it is now
    read, the quads fanned and counted in meshbits k."""
    polygons = [[0, 1, 2], [0, 2, 3, 4], [1, 2, 4]]
    vertices = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 1.0]])
    path = tmp_path / "m.ply"
    path.write_bytes(
        binary_ply(
            vertices,
            polygons,
            order="binary_little_endian",
            coordinate="float",
            count="uchar",
            index="int",
            extra_first=False,
        )
    )
    faces = meshbits.load_mesh(path)[1]
    assert faces.dtype == np.uint32 and np.array_equal(faces, fan(polygons))
    assert main(["k", str(path), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["reader"] == "meshbits" and report["polygons"] == 1
    assert report["polygon_triangles"] == 2 and report["faces"] == 4


def test_nan_and_out_of_range_files_are_refused_as_before(tmp_path):
    """Left to the general path, which names the row."""
    header = (
        b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n"
        b"property float y\nproperty float z\nelement face 1\n"
        b"property list uchar int vertex_indices\nend_header\n"
    )
    good = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], "<f4")
    nan = good.copy()
    nan[1, 2] = np.nan
    for vertices, face, expected in [
        (nan, [0, 1, 2], "not finite"),
        (good, [0, 1, 7], "out of range"),
    ]:
        path = tmp_path / "m.ply"
        path.write_bytes(header + vertices.tobytes() + b"\x03" + struct.pack("<3i", *face))
        with pytest.raises(MeshFileError, match=expected) as caught:
            meshbits.load_mesh(path)
        assert str(path) in str(caught.value)


def test_stl_is_read_as_a_soup_that_k_welds(tmp_path):
    ball = trimesh.creation.icosphere(subdivisions=2)
    path = tmp_path / "b.stl"
    ball.export(path)
    read = read_mesh(path)
    assert read.reader == "meshbits" and len(read.vertices) == 3 * len(ball.faces)
    k = meshbits.shape_complexity(read.vertices, read.faces)
    assert k.merged_vertices == len(read.vertices) - len(ball.vertices)
    rounded = np.asarray(ball.vertices, dtype=np.float32).astype(np.float64)  # STL's float32
    assert k.k == pytest.approx(meshbits.shape_complexity(rounded, ball.faces).k, rel=1e-12)
