"""Every certified bound holds of the written file, on every output path, far from the
origin and at any scale.

The input is a float64 PLY of the bunny (948 faces) moved by a rigid transform with an
offset of up to 1e7 on any axis and scaled by 1e-9 to 1e9; it is compressed to each
output (``.drc``, ``.ply``, ``.glb`` with Draco and with meshopt, ``.gltf``) at an error or
a size budget. The written file is read back without meshbits (tests/independent.py:
DracoPy, pygltflib, the meshopt package, node transforms composed in float64) and its
distance to the float64 input measured with exact float64 distances: that lower bound
must never exceed the certified upper bound, and no case may take a minute. The larger
run of the same matrix is ``benches/certificates.py`` (docs/reliability.md).
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from independent import hausdorff_lower, read_output

import meshbits
from meshbits.scene import compress_scene

DATA = Path(__file__).parent / "data"

#: Output paths: (suffix, codec).
OUTPUTS = [
    (".drc", None),
    (".ply", None),
    (".glb", "draco"),
    (".glb", "meshopt"),
    (".gltf", "draco"),
    (".gltf", "meshopt"),
    (".obj", None),
    (".off", None),
]

#: The longest a case may take (seconds).
CASE_SECONDS = 60.0


def write_ply64(path: Path, vertices: np.ndarray, faces: np.ndarray) -> Path:
    """A binary PLY of float64 coordinates (what trimesh's export would round to float32)."""
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {len(vertices)}\n"
        "property double x\nproperty double y\nproperty double z\n"
        f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    records = np.zeros(len(faces), dtype=[("n", "u1"), ("v", "<i4", (3,))])
    records["n"] = 3
    records["v"] = faces
    path.write_bytes(
        header.encode() + np.asarray(vertices, dtype="<f8").tobytes() + records.tobytes()
    )
    return path


def rotation(angles: tuple[float, float, float]) -> np.ndarray:
    a, b, c = angles
    rx = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    ry = np.array([[math.cos(b), 0, math.sin(b)], [0, 1, 0], [-math.sin(b), 0, math.cos(b)]])
    rz = np.array([[math.cos(c), -math.sin(c), 0], [math.sin(c), math.cos(c), 0], [0, 0, 1]])
    return rz @ ry @ rx


def run_case(
    folder: Path,
    vertices: np.ndarray,
    faces: np.ndarray,
    output: tuple[str, str | None],
    error: float | None,
    size_bytes: int | None,
) -> dict:
    """Compress the float64 mesh to one output with the public API, as the CLI does, and
    measure the written file independently. Returns what was claimed and measured."""
    source = write_ply64(folder / "input.ply", vertices, faces)
    suffix, codec = output
    target = folder / f"output{suffix}"
    size = None if size_bytes is None else 8 * size_bytes
    start = time.perf_counter()
    try:
        if suffix in (".obj", ".off"):
            # The CLI's path: float64 text, compressed about a centre, sized as Draco.
            result = meshbits.compress_in_frame(
                meshbits.load_mesh(source), error=error, size=size, relative=error is not None
            )
            meshbits.save_mesh(target, result.vertices, result.faces)
            bound = result.error_upper
        elif codec is None:
            result = meshbits.compress(
                meshbits.load_mesh(source),
                error=error,
                size=size,
                relative=error is not None,
                format="draco" if suffix == ".drc" else "ply",
            )
            result.write(target)
            bound = result.error_upper
        else:
            scene = compress_scene(
                source,
                error=error,
                size=size,
                relative=error is not None,
                codec=codec,
                output=target,
            )
            result = scene
            bound = scene.world_error_upper
    except meshbits.MeshbitsError as err:
        return {"refused": str(err), "seconds": time.perf_counter() - start}
    seconds = time.perf_counter() - start
    decoded = read_output(target)
    true = hausdorff_lower((vertices, faces), decoded, samples=8000)
    if suffix in (".glb", ".gltf"):
        # A reader that keeps node transforms in float32 (cgltf, gltfpack, most engines)
        # must find the same file: meshbits writes no translation float32 would round by
        # more than a position near the origin.
        rounded = read_output(target, float32_transforms=True)
        true = max(true, hausdorff_lower((vertices, faces), rounded, samples=8000))
    return {
        "bound": bound,
        "true": true,
        "seconds": seconds,
        "met": result.met,
        "bytes": result.size_bytes,
    }


@pytest.fixture(scope="module")
def bunny() -> tuple[np.ndarray, np.ndarray]:
    vertices, faces = meshbits.load_mesh(DATA / "bunny_res4.ply")
    return vertices - vertices.mean(axis=0), faces


@settings(
    max_examples=24,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(
    output=st.sampled_from(OUTPUTS),
    offset_exponent=st.floats(-2, 7),
    axis=st.sampled_from([(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 1), (0.42, 5.4, 0)]),
    scale_exponent=st.floats(-9, 9),
    angles=st.tuples(*[st.floats(0, 2 * math.pi)] * 3),
    budget=st.one_of(
        st.floats(1e-3, 5e-2).map(lambda e: ("error", e)),
        st.integers(2_000, 12_000).map(lambda b: ("size", b)),
    ),
)
def test_the_certified_bound_holds_of_the_written_file(
    tmp_path, bunny, output, offset_exponent, axis, scale_exponent, angles, budget
):
    vertices, faces = bunny
    scale = 10.0**scale_exponent
    offset = 10.0**offset_exponent * np.asarray(axis, dtype=float)
    size = scale * float(np.ptp(vertices, axis=0).max())
    # Beyond this the float64 input itself cannot hold the mesh's shape (its coordinates
    # are spaced more than 1e-5 of its size apart): there is nothing to certify.
    assume(np.abs(offset).max() * 2.0**-52 < 1e-5 * size)
    moved = vertices @ rotation(angles).T * scale + offset
    kind, value = budget
    case = run_case(
        tmp_path,
        moved,
        faces,
        output,
        error=value if kind == "error" else None,
        size_bytes=value if kind == "size" else None,
    )
    assert case["seconds"] < CASE_SECONDS
    if "refused" in case:
        # Only a format of float32 positions too coarse there for the mesh may refuse.
        assert output[1] is None and "float32" in case["refused"], case
    elif case["bound"] is not None:
        assert case["true"] <= case["bound"], case


@pytest.mark.parametrize("output", OUTPUTS[2:6], ids=lambda o: f"{o[0]}-{o[1]}")
def test_far_from_the_origin_costs_what_it_costs_at_the_origin(tmp_path, bunny, output):
    """A georeferenced offset (UTM-like) to a glTF output: met, certified, and within 1%
    of the bytes at the origin, or at most the JSON of a parent node carrying the centre
    more (Draco's 2 kB file: 28 bytes, 1.3%; written 420000.0 and -0.0, it took 40). The
    centre is a parent of its own where folding it into the mesh's node would write a
    translation float32 rounds (meshopt's grid origin added to it: 5400000.0329 read as
    5400000.0 by gltfpack, 0.03 off)."""
    vertices, faces = bunny
    sizes = []
    for offset in ([0.0, 0.0, 0.0], [4.2e5, 5.4e6, 0.0]):
        folder = tmp_path / str(len(sizes))
        folder.mkdir()
        case = run_case(folder, vertices + offset, faces, output, error=0.01, size_bytes=None)
        assert case["met"] and case["true"] <= case["bound"]
        sizes.append(case["bytes"])
    translation = len('{"translation":[42e4,54e5,0],"children":[1]},')
    padding = 3 if output[0] == ".glb" else 0
    assert sizes[1] <= max(1.01 * sizes[0], sizes[0] + translation + padding), sizes


@pytest.mark.parametrize("offset", [[1e6, 1e6, 1e6], [4.2e5, 5.4e6, 0.0]], ids=["1e6", "utm"])
def test_the_full_bunny_far_from_the_origin_is_within_one_percent_of_its_bytes(tmp_path, offset):
    """Issue 31's case: the Stanford bunny (35,947 vertices, float64 PLY) at 0.01 of its
    size, .glb and .gltf with both codecs, within 1% of the bytes at the origin. The
    centre's translation is the only difference, written shortest (``[1e6,1e6,1e6]``,
    ``[42e4,54e5,0]``: 28 bytes, 0.9% of Draco's 3.1 kB; written ``1000000`` it was 40,
    1.3%)."""
    vertices, faces = meshbits.load_mesh(DATA / "bunny.ply")
    vertices = vertices - (vertices.min(axis=0) + vertices.max(axis=0)) / 2
    for suffix, codec in [(".glb", "draco"), (".glb", "meshopt"), (".gltf", "draco")]:
        sizes = []
        for shift in ([0.0, 0.0, 0.0], offset):
            folder = tmp_path / f"{codec}{suffix}{len(sizes)}"
            folder.mkdir()
            source = write_ply64(folder / "in.ply", vertices + shift, faces)
            result = compress_scene(
                source, error=0.01, relative=True, codec=codec, output=folder / f"out{suffix}"
            )
            assert result.met, result.message
            sizes.append(sum(f.stat().st_size for f in folder.glob("out*")))
        assert sizes[1] <= 1.01 * sizes[0], (suffix, codec, sizes)


@pytest.mark.parametrize("output", [(".drc", None), (".glb", "draco")], ids=["drc", "glb"])
def test_a_mesh_a_millionth_of_a_unit_keeps_its_shape(tmp_path, output):
    """The bunny scaled by 1e-6 (side 1.5e-7) ran past 300 s: Draco decoded every vertex to
    one point at that range and the measurement visited every triangle per sample; Spot
    scaled by 1e-7 at 5 kB was "met" while collapsed."""
    vertices, faces = meshbits.load_mesh(meshbits.example_mesh_path())
    case = run_case(tmp_path, vertices * 1e-7, faces, output, error=None, size_bytes=5_000)
    assert case["met"] and case["seconds"] < CASE_SECONDS
    assert case["true"] <= case["bound"] < 0.05 * 1e-7 * np.ptp(vertices, axis=0).max()
    decoded, _ = read_output(tmp_path / f"output{output[0]}")
    assert np.ptp(decoded, axis=0).max() > 0.9 * 1e-7 * np.ptp(vertices, axis=0).max()


def test_an_output_that_lost_the_geometry_says_so():
    square = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=float)
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    collapsed = np.zeros_like(square)
    area, extent = meshbits.mesh.kept_shape((square, faces), (collapsed, faces))
    assert (area, extent) == (0.0, 0.0)
    assert "the geometry is lost" in meshbits.mesh.lost_geometry_note(area, extent)
    assert (
        meshbits.mesh.lost_geometry_note(
            *meshbits.mesh.kept_shape((square, faces), (square, faces))
        )
        == ""
    )
    result = meshbits.compress(meshbits.load_mesh(meshbits.example_mesh_path()), size=8 * 400)
    assert 0.5 < result.kept_area < 2 and 0.9 < result.kept_extent < 1.1
    assert "lost" not in result.message


@pytest.mark.parametrize("suffix", [".obj", ".off", ".stl"])
def test_text_and_stl_outputs_hold_the_decoded_positions_exactly(tmp_path, bunny, suffix):
    """An OBJ kept 8 decimals (trimesh's default): a mesh 1e-7 in size lost its shape."""
    vertices, faces = bunny
    for scale, offset in ((1e-7, 0.0), (1.0, 3e5)):
        result = meshbits.compress((vertices * scale + offset, faces), error=0.01, relative=True)
        path = meshbits.save_mesh(tmp_path / f"out{suffix}", result.vertices, result.faces)
        written, _ = read_output(path)
        # Every written position is a decoded one, exactly (an STL's corners come back
        # once per face).
        assert set(map(tuple, written)) == set(map(tuple, result.vertices))


@pytest.mark.parametrize("suffix", [".obj", ".off"])
def test_text_outputs_far_from_the_origin_meet_the_budget(tmp_path, bunny, suffix, capsys):
    """OBJ and OFF hold float64 text, but were written from Draco's float32 decoding of
    the mesh where it lies: at (4.2e5, 5.4e6, 0) the bunny came out "unmet" at B = 1,
    V = 4. They are compressed about a centre now and moved back in float64."""
    import json

    from meshbits.cli import main

    vertices, faces = bunny
    moved = vertices + np.array([4.2e5, 5.4e6, 0.0])
    source = write_ply64(tmp_path / "far.ply", moved, faces)
    target = tmp_path / f"far{suffix}"
    code = main(
        [
            "compress",
            str(source),
            "--error",
            "0.01",
            "--relative",
            "-o",
            str(target),
            "--json",
            "--quiet",
        ]
    )
    report = json.loads(capsys.readouterr().out)
    assert code == 0 and report["met"], report["message"]
    assert report["bits"] >= 6 and report["vertices"] > 100 and any(report["frame"])
    decoded = read_output(target)
    assert np.abs(decoded[0]).max() > 5e6
    true = hausdorff_lower((moved, faces), decoded, samples=8000)
    assert true <= report["error_upper"] <= 0.01 * np.ptp(vertices, axis=0).max()


@pytest.mark.parametrize("error", [1e-4, 3e-5])
def test_a_budget_filled_to_the_last_digit_survives_the_move_back(error):
    """The bunny at (4.2e5, 5.4e6, 0) to .obj at an absolute budget: the search certified
    within about 1e-10 of it, and the move back from the centre (up to 8.1e-10 there)
    took the bound past it: unmet, in a message that also said "met the error budget".
    The move's rounding is now set aside before the search."""
    vertices, faces = meshbits.load_mesh(DATA / "bunny.ply")
    moved = vertices.astype(np.float64) + np.array([4.2e5, 5.4e6, 0.0])
    result = meshbits.compress_in_frame((moved, faces), error=error)
    assert result.met and result.budget == error, result.message
    assert result.error_upper <= error and "did not meet" not in result.message
    assert f"budget of {error:.6g} (mesh units)" in result.message
    true = hausdorff_lower((moved, faces), (result.vertices, result.faces), samples=8000)
    assert true <= result.error_upper


def test_a_size_budget_met_by_float32_that_holds_no_likeness_says_so():
    """The bunny at (4.2e5, 5.4e6, 0) scaled by 1e-6 (1.6e-7 in size at 5.4) to .ply at
    30 kB was "met" silently as 4 vertices 60% of its size away: float32 is spaced 4.8e-7
    there, three times the mesh. (bunny_res4 there is refused: no face keeps any area.)"""
    vertices, faces = meshbits.load_mesh(DATA / "bunny.ply")
    tiny = (vertices.astype(np.float64) + np.array([4.2e5, 5.4e6, 0.0])) * 1e-6
    result = meshbits.compress((tiny, faces), size=8 * 30_000, format="ply")
    assert "holds no likeness of the mesh" in result.message, result.message
    near = meshbits.compress((tiny - tiny.mean(axis=0), faces), size=8 * 30_000, format="ply")
    assert "likeness" not in near.message


def test_a_result_in_a_frame_is_not_written_as_a_drc(tmp_path, bunny):
    vertices, faces = bunny
    result = meshbits.compress_in_frame((vertices + 1e6, faces), error=0.01, relative=True)
    assert result.frame.any() and np.abs(result.vertices).min() > 9e5
    with pytest.raises(meshbits.MeshbitsError, match="centre"):
        result.write(tmp_path / "x.drc")


def test_info_names_a_float64_input_float64(tmp_path, bunny, capsys):
    """``meshbits info`` called a float64 PLY's positions float32 (the accessor of the
    glTF it is read as), though meshbits measures against the float64 values."""
    from meshbits.cli import main

    vertices, faces = bunny
    source = write_ply64(tmp_path / "double.ply", vertices + 0.1, faces)
    assert main(["info", str(source)]) == 0
    assert "POSITION (VEC3 float64)" in capsys.readouterr().out
    assert main(["info", str(DATA / "bunny_res4.ply")]) == 0
    assert "POSITION (VEC3 float32)" in capsys.readouterr().out
