"""Animations compressed by compress_scene, played back without meshbits.

Every output is read with tests/independent.py (pygltflib, the meshopt package's vertex
codec, this project's numpy decoders of the QUATERNION and EXPONENTIAL filters from the
EXT_meshopt_compression specification) and played by tests/independent_animation.py
(glTF's step, linear, slerp and cubic sampling): at every original key time and at seeded
random times between them, every node's world origin and every vertex of the input's
meshes (skinned by the input's skins, morphed by the animated weights) are placed with the
original and with the written animation, and must stay within the reported tolerance.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from independent import accessor, read_gltf
from independent_animation import channels, node_worlds, posed_vertices, scene_roots

from meshbits.errors import MeshbitsError
from meshbits.formats.gltf.document import Document
from meshbits.formats.gltf.write import glb_bytes, rebuild_document
from meshbits.scene import compress_scene
from meshbits.scene.animation import compress_animations

CORPUS = Path("/work/corpus")
#: Float64 rounding between meshbits's measure and this one (relative).
SLACK = 1e-9


def _check_times(doc: dict, blob: bytes, animation: int, seed: int, between: int) -> np.ndarray:
    """Every key time of an animation and ``between`` seeded random times per interval."""
    spec = doc["animations"][animation]
    keys = np.unique(
        np.concatenate(
            [read_times(doc, blob, s["input"]) for s in spec["samplers"]],
        )
    )
    rng = np.random.default_rng(seed)
    inner = keys[:-1, None] + np.diff(keys)[:, None] * rng.random((len(keys) - 1, between))
    return np.sort(np.concatenate([keys, inner.reshape(-1), [keys[0] - 1, keys[-1] + 1]]))


def read_times(doc: dict, blob: bytes, index: int) -> np.ndarray:
    return accessor(doc, blob, index).reshape(-1)


def largest_deviation(source: Path, written: Path, seed: int = 0, vertex_times: int = 40):
    """The largest distance any node origin, and any vertex of the input's meshes, moves
    from its original path with the written animations (world units), over every
    animation; and the number of animations compared."""
    doc, blob = read_gltf(source)
    out_doc, out_blob = read_gltf(written)
    assert len(out_doc.get("animations", [])) == len(doc.get("animations", []))
    largest = 0.0
    for a, spec in enumerate(doc.get("animations", [])):
        targets = [(c["target"]["node"], c["target"]["path"]) for c in spec["channels"]]
        out_targets = [
            (c["target"]["node"], c["target"]["path"]) for c in out_doc["animations"][a]["channels"]
        ]
        assert targets == out_targets
        at = _check_times(doc, blob, a, seed + a, 5)
        before = channels(doc, blob, a, at)
        after = channels(out_doc, out_blob, a, at)
        roots = scene_roots(doc)
        w0 = node_worlds(doc["nodes"], roots, before, len(at))
        w1 = node_worlds(doc["nodes"], roots, after, len(at))
        largest = max(
            largest, float(np.linalg.norm(w1[..., :3, 3] - w0[..., :3, 3], axis=-1).max())
        )
        picks = np.random.default_rng(seed).choice(
            len(at), min(vertex_times, len(at)), replace=False
        )
        for k in picks:
            v0 = posed_vertices(doc, blob, w0, before, k)
            v1 = posed_vertices(doc, blob, w1, after, k)
            if len(v0):
                largest = max(largest, float(np.linalg.norm(v1 - v0, axis=1).max()))
    return largest


ASSETS = {
    "RiggedSimple": 0.01,
    "CesiumMan": 0.005,
    "AnimatedMorphCube": 0.002,
    "Fox": 0.5,
}


@pytest.mark.parametrize("codec", ["meshopt", "draco"])
@pytest.mark.parametrize("name", sorted(ASSETS))
def test_corpus_animations_stay_within_tolerance(tmp_path, name, codec):
    """Real skinned, animated and morphed assets: within the tolerance, smaller, counted."""
    source = next((CORPUS / name).glob("*.glb"), None)
    if source is None:
        pytest.skip(f"{name} is not in the corpus")
    output = tmp_path / f"{name}.glb"
    result = compress_scene(source, error=ASSETS[name], codec=codec, output=output)
    report = result.animations
    assert report is not None and report.tolerance == ASSETS[name]
    assert report.compressed + sum(report.copied.values()) == report.samplers
    assert report.compressed == report.samplers, report.copied
    assert report.bytes_after < report.bytes_before
    assert report.largest_deviation <= report.tolerance
    measured = largest_deviation(source, output)
    assert measured <= report.tolerance * (1 + SLACK), (measured, report)
    used = json.loads(json.dumps(result.to_dict()))["animations"]
    assert used["tolerance"] == ASSETS[name] and used["bytes_after"] == report.bytes_after
    doc, _ = read_gltf(output)
    meshopt_views = [
        v for v in doc["bufferViews"] if "EXT_meshopt_compression" in (v.get("extensions") or {})
    ]
    if codec == "draco":
        assert not meshopt_views
        assert "EXT_meshopt_compression" not in doc.get("extensionsUsed", [])
    else:
        filters = {v["extensions"]["EXT_meshopt_compression"].get("filter") for v in meshopt_views}
        if name in ("CesiumMan", "Fox"):
            assert "QUATERNION" in filters


# --- synthetic documents ---------------------------------------------------------------------


def _document(tracks: list[tuple[int, str, str, np.ndarray, np.ndarray]]) -> Document:
    """A node 0 holding node 1, which shows a triangle of side 2 at (0, 1, 0); an
    animation of ``tracks`` ``(node, path, interpolation, times, values)``."""
    blob = bytearray()
    accessors, views = [], []

    def add(values: np.ndarray, kind: str) -> int:
        data = np.ascontiguousarray(values, dtype="<f4").tobytes()
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(data)})
        blob.extend(data)
        spec = {"bufferView": len(views) - 1, "componentType": 5126, "type": kind}
        spec["count"] = len(values)
        if kind == "SCALAR":
            spec["min"], spec["max"] = [float(values.min())], [float(values.max())]
        accessors.append(spec)
        return len(accessors) - 1

    triangle = np.array([[-1.0, 0, 0], [1, 0, 0], [0, 2, 0]])
    position = add(triangle, "VEC3")
    accessors[position]["min"] = triangle.min(axis=0).tolist()
    accessors[position]["max"] = triangle.max(axis=0).tolist()
    samplers, chans = [], []
    for node, path, interpolation, times, values in tracks:
        kind = {3: "VEC3", 4: "VEC4"}[values.shape[1]]
        samplers.append(
            {
                "input": add(times, "SCALAR"),
                "output": add(values, kind),
                "interpolation": interpolation,
            }
        )
        chans.append({"sampler": len(samplers) - 1, "target": {"node": node, "path": path}})
    doc = {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"children": [1]}, {"mesh": 0, "translation": [0, 1, 0]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": position}}]}],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": len(blob)}],
        "animations": [{"samplers": samplers, "channels": chans}],
    }
    return Document(doc, [bytes(blob)], None)


def _write(document: Document, tolerance: float, meshopt: bool, path: Path):
    encoded, report = compress_animations(document, tolerance, meshopt)
    out, data = rebuild_document(document, [], "meshopt" if meshopt else "draco", encoded)
    path.write_bytes(glb_bytes(out, data))
    source = path.with_name("source.glb")
    source.write_bytes(glb_bytes(document.json, document.buffers[0]))
    return source, report


def _random_tracks(seed: int, keys: int, interpolation: str) -> list:
    rng = np.random.default_rng(seed)
    times = np.cumsum(rng.uniform(0.01, 0.3, keys)).astype(np.float32).astype(np.float64)
    walk = np.cumsum(rng.normal(0, 0.3, (keys, 3)), axis=0)
    axis = rng.normal(size=3)
    angles = np.cumsum(rng.normal(0, 0.2, keys))
    rotation = np.hstack(
        [np.outer(np.sin(angles / 2), axis / np.linalg.norm(axis)), np.cos(angles / 2)[:, None]]
    )
    scale = 1 + 0.2 * np.sin(np.cumsum(rng.normal(0, 0.3, (keys, 3)), axis=0))
    return [
        (0, "rotation", interpolation, times, rotation),
        (1, "translation", interpolation, times, walk),
        (1, "scale", interpolation, times, scale),
    ]


@settings(max_examples=25, deadline=None, derandomize=True)
@given(
    seed=st.integers(0, 2**31),
    keys=st.integers(1, 60),
    interpolation=st.sampled_from(["LINEAR", "STEP"]),
    tolerance=st.floats(1e-3, 0.3),
    meshopt=st.booleans(),
)
def test_random_tracks_stay_within_tolerance(
    tmp_path_factory, seed, keys, interpolation, tolerance, meshopt
):
    """Random walks of a rotation, a translation and a scale on a two-node chain."""
    folder = tmp_path_factory.mktemp("random")
    document = _document(_random_tracks(seed, keys, interpolation))
    source, report = _write(document, tolerance, meshopt, folder / "out.glb")
    assert report.compressed == 3, report.copied
    assert report.keys_after <= report.keys_before
    measured = largest_deviation(source, folder / "out.glb", seed, vertex_times=200)
    assert measured <= tolerance * (1 + SLACK) + 1e-12, (measured, report)


@pytest.mark.parametrize(
    "damage",
    ["nan value", "times not increasing", "nan time"],
)
def test_bad_keys_are_copied_and_counted(tmp_path, damage):
    """An animation with bad keys is written as it was, and counted."""
    tracks = _random_tracks(3, 20, "LINEAR")
    node, path, interpolation, times, values = tracks[1]
    times, values = times.copy(), values.copy()
    if damage == "nan value":
        values[4, 1] = np.nan
    elif damage == "times not increasing":
        times[7] = times[6]
    else:
        times[2] = np.nan
    tracks[1] = (node, path, interpolation, times, values)
    document = _document(tracks)
    source, report = _write(document, 0.01, True, tmp_path / "out.glb")
    assert report.compressed == 0 and sum(report.copied.values()) == 3
    (reason,) = report.copied
    assert reason.startswith("bad keys") and "samplers[1]" in reason
    doc, blob = read_gltf(tmp_path / "out.glb")
    before, before_blob = read_gltf(source)

    for a, b in zip(
        doc["animations"][0]["samplers"], before["animations"][0]["samplers"], strict=True
    ):
        for key in ("input", "output"):
            np.testing.assert_array_equal(
                accessor(doc, blob, a[key]), accessor(before, before_blob, b[key])
            )


def test_cubic_spline_is_copied_and_counted(tmp_path):
    """A cubic spline sampler is kept as it is; the others still compressed and measured
    against it."""
    tracks = _random_tracks(5, 12, "LINEAR")
    node, path, _, times, values = tracks[1]
    cubic = np.repeat(values, 3, axis=0)
    cubic[0::3] = 0.0
    cubic[2::3] = 0.0
    tracks[1] = (node, path, "CUBICSPLINE", times, cubic)
    document = _document(tracks)
    source, report = _write(document, 0.01, True, tmp_path / "out.glb")
    assert report.compressed == 2 and report.copied == {"cubic spline (kept as it is)": 1}
    assert largest_deviation(source, tmp_path / "out.glb") <= 0.01 * (1 + SLACK)


def test_animation_tolerance_is_the_callers(tmp_path):
    """``animation_tolerance`` replaces the world error budget: 0 copies every sampler
    (counted), a bad one is refused in one line."""
    source = next((CORPUS / "RiggedSimple").glob("*.glb"), None)
    if source is None:
        pytest.skip("RiggedSimple is not in the corpus")
    result = compress_scene(source, error=0.01, animation_tolerance=0.0, output=tmp_path / "a.glb")
    assert result.animations.compressed == 0
    assert result.animations.copied == {"a tolerance of 0": result.animations.samplers}
    loose = compress_scene(source, error=0.01, animation_tolerance=0.05, output=tmp_path / "b.glb")
    assert loose.animations.tolerance == 0.05
    assert largest_deviation(source, tmp_path / "b.glb") <= 0.05 * (1 + SLACK)
    for bad in (-1.0, float("nan"), float("inf")):
        with pytest.raises(MeshbitsError, match="animation_tolerance"):
            compress_scene(source, error=0.01, animation_tolerance=bad)
