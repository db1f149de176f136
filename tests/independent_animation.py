"""glTF animations played without meshbits: samplers read with :mod:`independent`'s
accessor reader (meshopt package for the vertex codec, this project's numpy decoders of the
specification for the QUATERNION and EXPONENTIAL filters), sampled as glTF 2.0's appendix
on interpolation defines (step, linear, spherical linear along the shorter arc, cubic
Hermite), the node tree composed in float64, and meshes posed (skins and morph weights).
"""

from __future__ import annotations

import numpy as np
from independent import accessor, decode_primitive, node_matrix


def sampler_keys(doc: dict, blob: bytes, sampler: dict, path: str) -> tuple[np.ndarray, np.ndarray]:
    """A sampler's key times and values (``(n, w)``; weights one column a target)."""
    times = accessor(doc, blob, sampler["input"]).reshape(-1).astype(np.float64)
    values = accessor(doc, blob, sampler["output"]).astype(np.float64)
    rows = len(times) * (3 if sampler.get("interpolation") == "CUBICSPLINE" else 1)
    if path == "weights":
        values = values.reshape(rows, -1)
    return times, values


def _slerp(a: np.ndarray, b: np.ndarray, t: np.ndarray) -> np.ndarray:
    dot = (a * b).sum(axis=1)
    b = np.where(dot[:, None] < 0, -b, b)
    dot = np.abs(dot).clip(max=1.0)
    angle = np.arccos(dot)
    with np.errstate(invalid="ignore", divide="ignore"):
        wa = np.sin((1 - t) * angle) / np.sin(angle)
        wb = np.sin(t * angle) / np.sin(angle)
    close = dot > 1 - 1e-9
    wa, wb = np.where(close, 1 - t, wa), np.where(close, t, wb)
    return a * wa[:, None] + b * wb[:, None]


def play(times: np.ndarray, values: np.ndarray, interpolation: str, path: str, at: np.ndarray):
    """A sampler's values at times ``at``."""
    cubic = interpolation == "CUBICSPLINE"
    points = values[1::3] if cubic else values
    if len(times) == 1:
        return np.repeat(points[:1], len(at), axis=0)
    i = np.clip(np.searchsorted(times, at, side="right") - 1, 0, len(times) - 2)
    if interpolation == "STEP":
        return points[np.where(at >= times[-1], len(times) - 1, i)]
    dt = times[i + 1] - times[i]
    t = np.clip((at - times[i]) / dt, 0.0, 1.0)
    if cubic:
        t2, t3 = t * t, t * t * t
        out = (
            (2 * t3 - 3 * t2 + 1)[:, None] * points[i]
            + ((t3 - 2 * t2 + t) * dt)[:, None] * values[3 * i + 2]
            + (-2 * t3 + 3 * t2)[:, None] * points[i + 1]
            + ((t3 - t2) * dt)[:, None] * values[3 * (i + 1)]
        )
        if path == "rotation":
            out = out / np.linalg.norm(out, axis=1, keepdims=True)
        return out
    if path == "rotation":
        return _slerp(points[i], points[i + 1], t)
    return points[i] * (1 - t)[:, None] + points[i + 1] * t[:, None]


def channels(doc: dict, blob: bytes, animation: int, at: np.ndarray) -> dict:
    """``(node, path) -> values at times at`` of an animation's channels."""
    spec = doc["animations"][animation]
    out = {}
    for channel in spec["channels"]:
        node, path = channel["target"]["node"], channel["target"]["path"]
        sampler = spec["samplers"][channel["sampler"]]
        times, values = sampler_keys(doc, blob, sampler, path)
        out[(node, path)] = play(times, values, sampler.get("interpolation", "LINEAR"), path, at)
    return out


def _trs(t: np.ndarray, q: np.ndarray, s: np.ndarray) -> np.ndarray:
    x, y, z, w = q.T
    m = np.zeros((len(t), 4, 4))
    m[:, 0, :3] = np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], 1)
    m[:, 1, :3] = np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], 1)
    m[:, 2, :3] = np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], 1)
    m[:, :3, :3] *= s[:, None, :]
    m[:, :3, 3] = t
    m[:, 3, 3] = 1
    return m


def node_worlds(nodes: list[dict], roots: list[int], tracks: dict, count: int) -> np.ndarray:
    """Every node's world matrix at ``count`` times: the rest ``nodes`` with ``tracks``
    (``(node, path) -> (count, w)``) applied."""
    worlds = np.zeros((count, len(nodes), 4, 4))
    stack = [(r, np.broadcast_to(np.eye(4), (count, 4, 4))) for r in roots]
    while stack:
        index, parent = stack.pop()
        node = nodes[index]
        if "matrix" in node:
            local = np.broadcast_to(node_matrix(node), (count, 4, 4))
        else:

            def part(path: str, rest: list[float], index: int = index) -> np.ndarray:
                if (index, path) in tracks:
                    return tracks[(index, path)]
                return np.broadcast_to(np.asarray(rest, dtype=np.float64), (count, len(rest)))

            local = _trs(
                part("translation", node.get("translation", [0, 0, 0])),
                part("rotation", node.get("rotation", [0, 0, 0, 1])),
                part("scale", node.get("scale", [1, 1, 1])),
            )
        worlds[:, index] = parent @ local
        stack += [(c, worlds[:, index]) for c in node.get("children", [])]
    return worlds


def posed_vertices(doc: dict, blob: bytes, worlds: np.ndarray, tracks: dict, k: int) -> np.ndarray:
    """Every vertex of ``doc`` at time ``k`` of ``worlds`` (``(count, nodes, 4, 4)``) and
    ``tracks``'s morph weights: skinned by its skin (the node's own transform ignored),
    else by its node's world matrix."""
    out = []
    for index, node in enumerate(doc["nodes"]):
        if "mesh" not in node or not worlds[k, index].any():
            continue
        mesh = doc["meshes"][node["mesh"]]
        weights = tracks.get((index, "weights"))
        weights = (
            list(weights[k]) if weights is not None else node.get("weights", mesh.get("weights"))
        )
        for prim in mesh["primitives"]:
            data = decode_primitive(doc, blob, prim)
            local = np.asarray(data["POSITION"], dtype=np.float64).copy()
            for w, target in zip(list(weights or ()), prim.get("targets") or [], strict=False):
                local += w * accessor(doc, blob, target["POSITION"]).astype(np.float64)
            if node.get("skin") is None:
                out.append(local @ worlds[k, index, :3, :3].T + worlds[k, index, :3, 3])
                continue
            skin = doc["skins"][node["skin"]]
            inverse = accessor(doc, blob, skin["inverseBindMatrices"]).reshape(-1, 4, 4)
            matrices = worlds[k, skin["joints"]] @ inverse.transpose(0, 2, 1)
            joints = np.asarray(data["JOINTS_0"], dtype=np.int64)
            weight = np.asarray(data["WEIGHTS_0"], dtype=np.float64)
            homogeneous = np.hstack([local, np.ones((len(local), 1))])
            posed = sum(
                weight[:, j, None] * np.einsum("nij,nj->ni", matrices[joints[:, j]], homogeneous)
                for j in range(joints.shape[1])
            )
            out.append(np.asarray(posed)[:, :3])
    return np.concatenate(out) if out else np.zeros((0, 3))


def scene_roots(doc: dict) -> list[int]:
    """The default scene's root nodes."""
    return list(doc["scenes"][doc.get("scene", 0)]["nodes"])
