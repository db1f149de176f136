"""How far an animation's nodes, and what they carry, move from their original paths when
its tracks change: the measure of animation error (world units; see docs/scenes.md).

At a time ``t`` a node ``n`` has the world transform ``G_n(t) = G_parent(t) L_n(t)``, its
local ``L_n = T R S`` from the animated or rest translation, rotation and scale (a node
given by a ``matrix`` is never animated). With the original tracks ``G``, with the written
ones ``G'``. A point ``p`` of the node's own frame within its **influence radius**
``R_n`` of the origin moves by

    |G'_n(t) p - G_n(t) p| <= |dT_n(t)| + sigma(dM_n(t)) R_n =: dev_n(t)

(``dT`` the difference of the world translations, ``sigma(dM)`` the spectral norm of the
difference of the world linear parts). ``R_n`` is: for a joint of a skin, the largest
``|IBM_j v|`` over the skin's vertices ``v`` it weighs (bind pose, raised by the morph
targets' largest displacements), so a skinned vertex ``sum_j w_j G_j IBM_j v`` moves by at
most the largest ``dev_j`` of its joints; for a node showing a mesh without a skin, the
largest ``|v|`` of its mesh (with instancing, of every instance); else 0 (the node's
origin: its path itself). A node whose morph weights change adds
``sigma(M'(t)) sum_k |dw_k(t)| D_k`` (``D_k`` target ``k``'s largest displacement,
``M'`` its world linear part, or for a skinned mesh the largest of its joints'
``G'_j IBM_j``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..formats.gltf.document import Document

__all__ = ["Skeleton", "node_deviations", "read_skeleton", "world_matrices"]


@dataclass
class Skeleton:
    """A document's node tree for animation: ``parents`` (-1 for a root), ``order``
    (every node after its parent), the rest ``translation``, ``rotation`` and ``scale``,
    ``fixed`` local matrices (nodes given by a ``matrix``), each node's influence
    ``radius`` (its own units), ``morph_reach`` (node -> ``D_k`` of its mesh's targets) and
    ``skin_joints`` (node -> ``(joint nodes, inverse bind matrices)`` of its skin)."""

    parents: np.ndarray
    order: list[int]
    translation: np.ndarray
    rotation: np.ndarray
    scale: np.ndarray
    fixed: dict[int, np.ndarray]
    radius: np.ndarray
    morph_reach: dict[int, np.ndarray] = field(default_factory=dict)
    skin_joints: dict[int, tuple[list[int], np.ndarray]] = field(default_factory=dict)

    def subtree(self, node: int) -> list[int]:
        """``node`` and every node below it."""
        children: dict[int, list[int]] = {}
        for child, parent in enumerate(self.parents):
            children.setdefault(int(parent), []).append(child)
        out, stack = [], [node]
        while stack:
            n = stack.pop()
            out.append(n)
            stack.extend(children.get(n, []))
        return out


def _tree(nodes: list[dict]) -> tuple[np.ndarray, list[int]]:
    parents = np.full(len(nodes), -1, dtype=np.int64)
    for i, node in enumerate(nodes):
        for child in node.get("children", []):
            parents[child] = i
    order: list[int] = []
    depth = np.zeros(len(nodes), dtype=np.int64)
    for i in range(len(nodes)):
        n, d = i, 0
        while parents[n] >= 0 and d <= len(nodes):
            n, d = int(parents[n]), d + 1
        depth[i] = d
    order = [int(i) for i in np.argsort(depth, kind="stable")]
    return parents, order


def _mesh_vertices(document: Document, mesh: int) -> list[tuple[np.ndarray, dict, np.ndarray]]:
    """Per primitive of a mesh: positions, attributes (joints and weights) and the largest
    displacement of each morph target (zeros without targets)."""
    out = []
    for p, prim in enumerate(document.json["meshes"][mesh].get("primitives", [])):
        data = document.primitive(mesh, p)
        if data is not None:
            positions, attributes = data.positions, data.attributes
        else:
            attributes = {
                name: document.accessor(acc, normalize=not name.startswith("JOINTS_"))
                for name, acc in prim.get("attributes", {}).items()
            }
            positions = np.asarray(attributes.pop("POSITION", np.zeros((0, 3))), np.float64)
        reach = np.array(
            [
                float(np.linalg.norm(document.accessor(t["POSITION"]), axis=1).max(initial=0.0))
                if t.get("POSITION") is not None
                else 0.0
                for t in prim.get("targets", [])
            ]
        )
        out.append((positions, attributes, reach))
    return out


def _skin_radii(
    document: Document, skin: dict, parts: list[tuple[np.ndarray, dict, np.ndarray]]
) -> tuple[list[int], np.ndarray, dict[int, float]]:
    """A skin's joints, inverse bind matrices and each joint's influence radius over the
    vertices it weighs in ``parts``."""
    joints = [int(j) for j in skin.get("joints", [])]
    if skin.get("inverseBindMatrices") is not None:
        ibm = document.accessor(skin["inverseBindMatrices"]).reshape(-1, 4, 4).transpose(0, 2, 1)
    else:
        ibm = np.repeat(np.eye(4)[None], len(joints), axis=0)
    radii: dict[int, float] = {}
    for positions, attributes, reach in parts:
        extra = float(reach.sum())
        for name in attributes:
            if not name.startswith("JOINTS_"):
                continue
            slots = np.asarray(attributes[name], dtype=np.int64)
            weights = attributes.get("WEIGHTS_" + name[7:])
            used = slots if weights is None else np.where(np.asarray(weights) > 0, slots, -1)
            for slot in np.unique(used[used >= 0]):
                if slot >= len(joints):
                    continue
                rows = (used == slot).any(axis=1)
                bind = positions[rows] @ ibm[slot, :3, :3].T + ibm[slot, :3, 3]
                r = float(np.linalg.norm(bind, axis=1).max(initial=0.0)) + extra
                radii[joints[slot]] = max(radii.get(joints[slot], 0.0), r)
    return joints, ibm, radii


def read_skeleton(document: Document) -> Skeleton:
    """The document's node tree, rest transforms and influence radii (module docstring)."""
    nodes = document.json.get("nodes", [])
    parents, order = _tree(nodes)
    n = len(nodes)
    skeleton = Skeleton(
        parents=parents,
        order=order,
        translation=np.zeros((n, 3)),
        rotation=np.tile([0.0, 0.0, 0.0, 1.0], (n, 1)),
        scale=np.ones((n, 3)),
        fixed={},
        radius=np.zeros(n),
    )
    for i, node in enumerate(nodes):
        if "matrix" in node:
            skeleton.fixed[i] = document.node_matrix(i)
        skeleton.translation[i] = node.get("translation", [0, 0, 0])
        skeleton.rotation[i] = node.get("rotation", [0, 0, 0, 1])
        skeleton.scale[i] = node.get("scale", [1, 1, 1])
    for i, node in enumerate(nodes):
        if node.get("mesh") is None:
            continue
        parts = _mesh_vertices(document, int(node["mesh"]))
        reach = np.zeros(max((len(r) for _, _, r in parts), default=0))
        for _, _, r in parts:
            reach[: len(r)] = np.maximum(reach[: len(r)], r)
        skeleton.morph_reach[i] = reach
        if node.get("skin") is not None:
            skin = document.json["skins"][int(node["skin"])]
            joints, ibm, radii = _skin_radii(document, skin, parts)
            skeleton.skin_joints[i] = (joints, ibm)
            for joint, joint_radius in radii.items():
                skeleton.radius[joint] = max(float(skeleton.radius[joint]), joint_radius)
            continue
        instances = document.instance_matrices(i) or [np.eye(4)]
        for positions, _, r in parts:
            for m in instances:
                moved = positions @ m[:3, :3].T + m[:3, 3]
                far = float(np.linalg.norm(moved, axis=1).max(initial=0.0))
                skeleton.radius[i] = max(skeleton.radius[i], far + float(r.sum()))
    return skeleton


def _rotation_matrices(q: np.ndarray) -> np.ndarray:
    """Rotation matrices ``(..., 3, 3)`` of quaternions ``(..., 4)`` (x, y, z, w) by
    glTF's formula, the quaternions taken as they are (not normalized)."""
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )


def world_matrices(
    skeleton: Skeleton, tracks: dict[tuple[int, str], np.ndarray], count: int
) -> np.ndarray:
    """Every node's world matrix at ``count`` times, ``(count, nodes, 4, 4)``:
    ``tracks`` maps ``(node, path)`` to its sampled values ``(count, w)`` (paths
    translation, rotation, scale; the rest pose elsewhere)."""
    n = len(skeleton.parents)
    world = np.zeros((count, n, 4, 4))
    for i in skeleton.order:
        if i in skeleton.fixed:
            local = np.broadcast_to(skeleton.fixed[i], (count, 4, 4))
        else:
            t = tracks.get((i, "translation"), skeleton.translation[i][None])
            r = tracks.get((i, "rotation"), skeleton.rotation[i][None])
            s = tracks.get((i, "scale"), skeleton.scale[i][None])
            local = np.zeros((count, 4, 4))
            local[:, :3, :3] = (
                _rotation_matrices(np.broadcast_to(r, (count, 4)))
                * np.broadcast_to(s, (count, 3))[:, None, :]
            )
            local[:, :3, 3] = t
            local[:, 3, 3] = 1.0
        parent = int(skeleton.parents[i])
        world[:, i] = local if parent < 0 else world[:, parent] @ local
    return world


def node_deviations(
    skeleton: Skeleton,
    original: np.ndarray,
    written: np.ndarray,
    weight_change: dict[int, np.ndarray],
) -> np.ndarray:
    """``dev_n(t)`` (module docstring), ``(count, nodes)`` world units, from the original
    and written world matrices and, per node whose weights change, ``sum_k |dw_k| D_k``
    at each time (mesh units)."""
    difference = written - original
    translation = np.linalg.norm(difference[..., :3, 3], axis=-1)
    linear = np.linalg.norm(difference[..., :3, :3], ord=2, axis=(-2, -1))
    deviation = translation + linear * skeleton.radius[None, :]
    for node, change in weight_change.items():
        if node in skeleton.skin_joints:
            joints, ibm = skeleton.skin_joints[node]
            bound = written[:, joints] @ ibm[None, : len(joints)]
            scale = np.linalg.norm(bound[..., :3, :3], ord=2, axis=(-2, -1)).max(axis=1)
        else:
            scale = np.linalg.norm(written[:, node, :3, :3], ord=2, axis=(-2, -1))
        deviation[:, node] += scale * change
    return deviation
