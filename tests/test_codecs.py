"""meshbits.codecs: the real encoders (Draco for meshes and primitives, quantized PLY and
GLB), fixed-width sizes, the size-model fit; and simplification's level choice."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from independent import hausdorff_lower

import meshbits
from meshbits.codecs import encode, encode_draco, encode_quantized_ply, fit_size_model
from meshbits.codecs.attributes import AttributeBits
from meshbits.codecs.draco import encode_draco_primitive
from meshbits.simplify import closest_level

DATA = Path(__file__).parent / "data"


@settings(max_examples=50, deadline=None)
@given(
    st.floats(1 / 3, 1.0),
    st.floats(0.0, 8.0),
    st.floats(0.0, 0.02),
    st.integers(0, 2**32 - 1),
)
def test_fit_recovers_known_alpha_and_t(alpha, t, noise, seed):
    rng = np.random.default_rng(seed)
    bits = rng.integers(4, 17, size=40).astype(float)
    vertices = rng.integers(100, 100_000, size=40).astype(float)
    sizes = (3 * alpha * bits + t) * vertices * (1 + rng.normal(scale=noise, size=40))
    fit = fit_size_model(bits, vertices, sizes)
    exact = noise == 0.0
    assert fit.alpha == pytest.approx(
        alpha, rel=1e-9 if exact else 0.1, abs=1e-9 if exact else 0.05
    )
    assert fit.connectivity_bits == pytest.approx(t, abs=1e-7 if exact else 1.0)
    assert fit.relative_rms <= 1e-9 if exact else fit.relative_rms < 0.1


def test_fit_refuses_a_single_bit_depth():
    with pytest.raises(ValueError, match="two or more bit depths"):
        fit_size_model([8, 8], [100, 200], [3000, 6000])


def test_draco_uses_the_paper_grid(bunny):
    vertices, faces = bunny
    bits = 10
    encoded = encode_draco((vertices, faces), bits)
    used = np.unique(faces)
    lo = vertices[used].min(axis=0)
    step = (vertices[used].max(axis=0) - lo).max() / (2**bits - 1)
    codes = (encoded.vertices - lo) / step
    # Decoded positions sit on the grid; Draco stores origin and range as float32, which
    # shifts them by a few thousandths of a step.
    assert np.abs(codes - np.rint(codes)).max() < 1e-2
    assert len(encoded.faces) == len(faces)
    assert len(encoded.vertices) == len(used)  # Draco drops unreferenced vertices
    assert encoded.size_bits == 8 * len(encoded.data)


def test_draco_size_grows_with_bits(bunny):
    sizes = [encode_draco(bunny, bits).size_bytes for bits in (6, 10, 14)]
    assert sizes[0] < sizes[1] < sizes[2]


def test_quantized_ply_round_trips_through_trimesh(tmp_path, bunny):
    encoded = encode_quantized_ply(bunny, 8)
    path = encoded.write(tmp_path / "q.ply")
    loaded = trimesh.load(path, process=False)
    np.testing.assert_array_equal(np.asarray(loaded.faces), encoded.faces)
    np.testing.assert_allclose(np.asarray(loaded.vertices), encoded.vertices, rtol=0, atol=0)
    assert len(np.unique(encoded.vertices[:, 0])) <= 2**8


@pytest.mark.parametrize("bits", [0, 31, 8.5])
def test_bad_bits(bunny, bits):
    with pytest.raises(ValueError, match="bits must be an integer"):
        encode_draco(bunny, bits)


def test_closest_level_on_a_log_scale():
    levels = [trimesh.creation.icosphere(subdivisions=s) for s in range(1, 5)]  # 42..2562 vertices
    assert closest_level(levels, 40) == 0
    assert closest_level(levels, 600) == 2  # 642 vertices
    assert closest_level(levels, 10**6) == 3
    with pytest.raises(ValueError, match="lods is empty"):
        closest_level([], 100)


@pytest.mark.parametrize("bits", [1, 6, 8, 9, 12, 16])
def test_quantized_glb_decodes_in_trimesh_to_the_grid(bits):
    import io

    from meshbits import quantize
    from meshbits.codecs import encode_quantized_glb

    mesh = trimesh.load(meshbits.example_mesh_path(), process=False)
    vertices, faces = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    encoded = encode_quantized_glb((vertices, faces), bits)
    # An independent reader: trimesh applies the node's translation and scale.
    loaded = trimesh.load(io.BytesIO(encoded.data), file_type="glb", force="mesh", process=False)
    np.testing.assert_array_equal(np.asarray(loaded.faces), encoded.faces)
    np.testing.assert_allclose(np.asarray(loaded.vertices), encoded.vertices, rtol=0, atol=1e-6)
    # Every vertex is referenced in spot, so the order is the input's: positions are the
    # grid positions of meshbits.quantize, up to float32.
    grid = quantize(vertices, bits).positions
    np.testing.assert_allclose(encoded.vertices, grid, rtol=0, atol=1e-6)
    stride = 4 if bits <= 8 else 8
    index_bytes = 2 if len(vertices) < 65536 else 4
    payload = len(vertices) * stride + faces.size * index_bytes
    assert payload < encoded.size_bytes < payload + 2048


def test_quantized_glb_refuses_more_than_16_bits():
    from meshbits.codecs import encode_quantized_glb

    with pytest.raises(ValueError, match="1 to 16"):
        encode_quantized_glb(trimesh.creation.icosphere(1), 17)


# --- found by the fuzz campaign (benches/fuzz.py) ------------------------------------------


def test_calibrate_on_coordinates_beyond_float32_is_refused_not_crashed(tmp_path):
    """DracoPy crashed the process (SIGSEGV) encoding a vertex at 3.5e38: `meshbits
    calibrate` on this 80-byte file died with exit code -11."""
    path = tmp_path / "far.off"
    path.write_text(
        "OFF\n4 4 0\n0 0 0\n3.5e38 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n"
    )
    done = subprocess.run(
        [sys.executable, "-m", "meshbits.cli", "calibrate", str(path)],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 2, done.stderr
    assert "beyond float32's range" in done.stderr and done.stderr.count("\n") == 1


@pytest.mark.parametrize("fmt", ["glb", "ply"])
def test_quantized_formats_refuse_coordinates_beyond_float32(fmt):
    """Positions at 1e39 became infinite float32 values, with a RuntimeWarning."""
    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]) * 1e36 + 1e39
    f = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    with pytest.raises(meshbits.MeshbitsError, match="beyond float32's range"):
        encode((v, f), 8, format=fmt)


def test_draco_on_a_mesh_of_degenerate_faces_is_refused_in_words(tmp_path):
    """DracoPy raised its EncodingFailedException ('Invalid mesh', exit 3 from `meshbits
    calibrate`) after printing 'Draco encoding error: All triangles are degenerate.' on
    the process's stderr."""
    with pytest.raises(meshbits.MeshbitsError, match="its only face is degenerate"):
        encode_draco((np.zeros((3, 3)), np.array([[0, 1, 2]])), 8)
    path = tmp_path / "zero.stl"  # a binary STL of one triangle with every corner at 0
    path.write_bytes(b"x" * 80 + (1).to_bytes(4, "little") + bytes(50))
    done = subprocess.run(
        [sys.executable, "-m", "meshbits.cli", "calibrate", str(path)],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert "degenerate" in done.stderr or "every face repeats a vertex" in done.stderr


@settings(max_examples=20, deadline=None)
@given(
    fmt=st.sampled_from(["glb", "ply"]),
    bits=st.integers(1, 16),
    subdivisions=st.integers(0, 4),
)
def test_fixed_width_size_is_the_encoded_size(fmt, bits, subdivisions):
    """glb and ply sizes from the vertex and face counts alone, against the encoder."""
    from meshbits.codecs import fixed_width_size_bits

    sphere = trimesh.creation.icosphere(subdivisions)
    encoded = encode((sphere.vertices * 3.7 + 1.0, sphere.faces), bits, format=fmt)
    predicted = fixed_width_size_bits(fmt, bits, len(sphere.vertices), len(sphere.faces))
    assert abs(predicted - encoded.size_bits) <= 8 * 160  # the JSON header's numbers


@pytest.mark.parametrize("fmt", ["glb", "ply"])
def test_codes_are_the_quantizers_far_from_the_origin(fmt):
    """CompressResult.codes were rint((decoded - origin) / step) from float32 positions:
    1e4 away from the origin with S = 1, float32 positions are 1e-3 apart, many steps. A
    quantized GLB's positions are its codes through its node's float64 transform, which
    give the codes back; a PLY's are float32."""
    sphere = trimesh.creation.icosphere(3)
    vertices = sphere.vertices * 0.5 + [3000.0, -7000.0, 12000.0]
    bits, origin, size = 16, None, 1.0
    origin = vertices.min(axis=0)
    encoded = encode((vertices, sphere.faces), bits, format=fmt, origin=origin, grid_size=size)
    expected = meshbits.quantize(vertices, bits, box=(origin, origin + size)).codes
    np.testing.assert_array_equal(encoded.codes, expected)
    naive = np.rint((encoded.vertices - origin) / (size / (2**bits - 1)))
    if fmt == "glb":
        np.testing.assert_array_equal(naive, expected)
    else:
        assert np.abs(naive - expected).max() > 1


@pytest.mark.parametrize("bits", [8, 12, 16])
def test_draco_codes_are_draco_grid_codes(bits):
    """Draco decodes a few 1e-6 S off the nominal grid: the nearest codes stay Draco's
    up to 16 bits, within a fraction of a step of each decoded position."""
    sphere = trimesh.creation.icosphere(3)
    vertices = sphere.vertices * 0.5 + 3.0
    origin, size = vertices.min(axis=0), 1.0
    encoded = encode_draco((vertices, sphere.faces), bits, origin=origin, grid_size=size)
    step = size / (2**bits - 1)
    off = np.abs(encoded.vertices - (origin + encoded.codes * step)) / step
    assert off.max() < 0.25
    expected = meshbits.quantize(vertices, bits, box=(origin, origin + size)).codes
    same = {tuple(c) for c in encoded.codes.astype(int)} & {tuple(c) for c in expected.astype(int)}
    assert len(same) >= 0.95 * len(expected)


def test_draco_refusing_a_candidate_does_not_end_the_search():
    """Draco 1.5.7 refuses the bunny at 3,851 faces with UVs at 18 to 21 bits ("Failed to
    encode point attributes") at compression level 7: SheenCloth at a tight budget exited
    3. The encoder falls back to a level that takes it."""
    vertices, faces = meshbits.load_mesh(DATA / "bunny_res3.ply")
    lo, side = vertices.min(axis=0), float(np.ptp(vertices, axis=0).max())
    uv = (vertices[:, :2] - lo[:2]) / side
    for bits in range(17, 23):
        encoding = encode_draco_primitive(
            vertices,
            faces,
            {"TEXCOORD_0": uv},
            bits,
            lo,
            side,
            AttributeBits(8, {"TEXCOORD_0": 12}),
        )
        step = side / (2**bits - 1)
        assert len(encoding.faces) == len(faces)
        assert hausdorff_lower((vertices, faces), (encoding.vertices, encoding.faces)) <= step
