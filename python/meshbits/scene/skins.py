"""Skinned meshes with integer positions: which meshes share a skin (they must share one
grid, since a skin's inverse bind matrices carry one dequantization), how far the skin's
joints stretch a length at the rest pose (the scale of a skinned mesh's error), and the
float32 rounding of inverse bind matrices with the dequantization folded in.

A skinned mesh ignores its node's transform: glTF 2.0 (3.7.3) poses a vertex ``v`` as
``sum_j w_j * world(joint_j) @ IBM_j @ v``. With positions stored as integer codes ``c``,
``v = origin + step * c = D @ c``, and ``IBM_j @ D`` stored in place of ``IBM_j`` poses
the codes exactly as the input posed ``v`` (as gltfpack's ``writeJointBindMatrices``
does), up to that product's rounding to float32, which :func:`ibm_rounding` bounds.
"""

from __future__ import annotations

import numpy as np

from ..formats.gltf.document import Document
from ..formats.gltf.skins import folded_matrices, inverse_bind_matrices

__all__ = [
    "FLOAT32_HALF_ULP",
    "code_reach",
    "ibm_rounding",
    "ibm_rounding_reserve",
    "mesh_skins",
    "node_worlds",
    "rest_joint_scale",
    "settle_skin_rounding",
]

#: Relative rounding of a float64 to float32 (half an ulp): ``|fl32(x) - x| <= this * |x|``.
FLOAT32_HALF_ULP = 2.0**-24


def mesh_skins(document: Document) -> dict[int, set[int | None]]:
    """``mesh -> the skins of the nodes that show it`` (None for a node without a skin)."""
    out: dict[int, set[int | None]] = {}
    for node in document.json.get("nodes", []):
        if node.get("mesh") is not None:
            out.setdefault(int(node["mesh"]), set()).add(node.get("skin"))
    return out


def node_worlds(document: Document) -> dict[int, np.ndarray]:
    """``node -> world matrix (4x4, float64)`` at the rest pose (the nodes' own
    transforms), for every node of every scene (or every root when there is no scene)."""
    nodes = document.json.get("nodes", [])
    roots = [n for scene in document.json.get("scenes", []) for n in scene.get("nodes", [])]
    if not roots:
        children = {c for node in nodes for c in node.get("children", [])}
        roots = [i for i in range(len(nodes)) if i not in children]
    out: dict[int, np.ndarray] = {}
    stack = [(r, np.eye(4), 0) for r in roots]
    while stack:
        index, parent, depth = stack.pop()
        if depth > len(nodes) or index in out:
            continue
        out[index] = parent @ document.node_matrix(index)
        stack.extend((c, out[index], depth + 1) for c in nodes[index].get("children", []))
    return out


def _joint_worlds(document: Document, skin: int, worlds: dict[int, np.ndarray]) -> np.ndarray:
    """The rest-pose world matrices of a skin's joints (identity for a joint in no
    scene)."""
    joints = document.json["skins"][skin].get("joints", [])
    return np.stack([worlds.get(j, np.eye(4)) for j in joints]).reshape(-1, 4, 4)


def rest_joint_scale(document: Document, skins: set[int], worlds: dict[int, np.ndarray]) -> float:
    """The largest singular value of ``world(joint) @ IBM`` (linear parts) over the joints
    of ``skins`` at the rest pose: a skinned vertex is a convex combination of these
    transforms of it, so a displacement ``d`` of it moves the posed vertex by at most this
    times ``|d|`` (1 for a skin bound where it rests)."""
    largest = 0.0
    for skin in skins:
        posed = _joint_worlds(document, skin, worlds) @ inverse_bind_matrices(document, skin)
        if len(posed):
            largest = max(
                largest, float(np.linalg.norm(posed[:, :3, :3], ord=2, axis=(1, 2)).max())
            )
    return largest


def ibm_rounding(
    document: Document,
    skins: set[int],
    worlds: dict[int, np.ndarray],
    origin: np.ndarray,
    step: float,
    reach: float,
) -> float:
    """A bound (world units, at the rest pose) on how far storing ``IBM_j @ D`` in float32
    moves a posed vertex whose code vector has length at most ``reach``:
    ``max_j sigma(world(joint_j)) * (||E_j||_2 * reach + |e_j|)``, with ``E_j`` and
    ``e_j`` the rounding of the product's linear part and translation (exact, from the
    float32 values written)."""
    largest = 0.0
    for skin in skins:
        folded = folded_matrices(inverse_bind_matrices(document, skin), origin, step)
        rounding = folded.astype(np.float32).astype(np.float64) - folded
        linear = np.linalg.norm(rounding[:, :3, :3], ord=2, axis=(1, 2))
        shift = np.linalg.norm(rounding[:, :3, 3], axis=1)
        joints = _joint_worlds(document, skin, worlds)
        stretch = np.linalg.norm(joints[:, :3, :3], ord=2, axis=(1, 2))
        largest = max(largest, float((stretch * (linear * reach + shift)).max()))
    return largest


def ibm_rounding_reserve(
    document: Document,
    skins: set[int],
    worlds: dict[int, np.ndarray],
    positions: np.ndarray,
    spread: float,
) -> float:
    """What :func:`ibm_rounding` can be at most for positions in the box of ``positions``
    (mesh units, on any grid over it) whose morph displacements add up to ``spread``:
    float32 rounds each entry of ``IBM_j @ D`` by at most ``2^-24`` of it, so the posed
    vertex moves by at most ``2^-24 * sigma(world) * (||IBM||_F * (|origin| + reach) +
    |t|)``; doubled. Set aside from a skinned job's budget before its search."""
    if not skins or len(positions) == 0:
        return 0.0
    lo, hi = positions.min(axis=0), positions.max(axis=0)
    corner = float(np.linalg.norm(np.maximum(np.abs(lo), np.abs(hi))))
    reach = float(np.linalg.norm(hi - lo)) * 2 + spread
    largest = 0.0
    for skin in skins:
        ibm = inverse_bind_matrices(document, skin)
        linear = np.linalg.norm(ibm[:, :3, :3], axis=(1, 2))
        shift = np.linalg.norm(ibm[:, :3, 3], axis=1)
        joints = _joint_worlds(document, skin, worlds)
        stretch = np.linalg.norm(joints[:, :3, :3], ord=2, axis=(1, 2))
        largest = max(largest, float((stretch * (linear * (corner + reach) + shift)).max()))
    return 2 * FLOAT32_HALF_ULP * largest


def code_reach(
    vertices: np.ndarray, deltas: list[np.ndarray], origin: np.ndarray, step: float
) -> float:
    """The longest code vector a reader poses (code units): a vertex's code
    ``(v - origin) / step`` plus every target's displacement at weight 1."""
    if len(vertices) == 0 or step <= 0:
        return 0.0
    codes = float(np.linalg.norm((vertices - origin) / step, axis=1).max())
    return codes + sum(float(np.linalg.norm(d, axis=1).max(initial=0.0)) / step for d in deltas)


def settle_skin_rounding(document: Document, jobs: list, encodings: list) -> None:
    """Each skin-framed job's ``skin_rounding``, once the output is written:
    :func:`ibm_rounding` of the frame it is written with (integer codes, or positions
    moved to their centre), 0 when its skins keep their matrices (float32 positions, or
    the job kept as it was)."""
    worlds: dict[int, np.ndarray] | None = None
    for job, encoding in zip(jobs, encodings, strict=True):
        if encoding is not None and encoding.dequantize is not None:
            origin, step = encoding.dequantize
        else:
            origin, step = np.zeros(3), 1.0
        if (
            not job.skins
            or job.kept is not None
            or encoding is None
            or (encoding.dequantize is None and not job.offset.any())
        ):
            job.skin_rounding = 0.0
            continue
        worlds = node_worlds(document) if worlds is None else worlds
        reach = code_reach(encoding.vertices, encoding.target_deltas, origin, step)
        job.skin_rounding = ibm_rounding(
            document, job.skins, worlds, job.offset + origin, step, reach
        )
