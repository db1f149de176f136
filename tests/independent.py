"""Reading meshbits's outputs back and measuring them without meshbits.

Every written file is decoded with a reader that is not meshbits's own (DracoPy for
``.drc`` and ``KHR_draco_mesh_compression``, the meshopt package for
``EXT_meshopt_compression``, pygltflib for the glTF container, trimesh for PLY), and its
world positions composed in float64 from the stored values and the node transforms: the
convention of meshbits's certified bounds. The distance between two meshes is measured
with exact float64 point-to-triangle distances (Ericson's closest point, in numpy) on
seeded area samples, every vertex, and a second, denser round of samples on the triangles
nearest the largest distances found: a lower bound of the true Hausdorff distance, to
compare with a certified upper bound.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import DracoPy
import numpy as np
import pygltflib
import trimesh
from conftest import GLTF_DTYPES, GLTF_WIDTHS
from scipy.spatial import cKDTree

# --- glTF ---------------------------------------------------------------------------------


def decode_quaternion_filter(raw: bytes) -> bytes:
    """EXT_meshopt_compression's QUATERNION filter undone as its specification writes the
    decoder (Appendix B, float32 arithmetic): three components scaled by sqrt(2) over the
    K-bit 1.0 in the fourth short (its low two bits the index of the omitted largest
    component), the largest rebuilt as sqrt(1 - x^2 - y^2 - z^2), all stored as shorts."""
    data = np.frombuffer(raw, dtype="<i2").reshape(-1, 4)
    one = (data[:, 3] | 3).astype(np.float32)
    scale = np.float32(1.0) / np.sqrt(np.float32(2.0))
    xyz = data[:, :3].astype(np.float32) / one[:, None] * scale
    w = np.sqrt(np.maximum(np.float32(0.0), np.float32(1.0) - (xyz * xyz).sum(axis=1)))
    largest = (data[:, 3] & 3).astype(np.int64)
    out = np.zeros_like(data)
    rows = np.arange(len(data))
    for k in range(3):
        out[rows, (largest + k + 1) % 4] = np.round(xyz[:, k] * np.float32(32767.0))
    out[rows, largest] = np.round(w * np.float32(32767.0))
    return out.astype("<i2").tobytes()


def decode_exponential_filter(raw: bytes) -> bytes:
    """EXT_meshopt_compression's EXPONENTIAL filter undone as its specification writes the
    decoder: each little-endian int32 ``2^e * m``, ``e`` its top 8 bits and ``m`` its low
    24 bits, both signed."""
    words = np.frombuffer(raw, dtype="<i4").astype(np.int64)
    e = words >> 24
    m = ((words << 40) >> 40).astype(np.float64)
    return (np.ldexp(m, e)).astype("<f4").tobytes()


def _strided(raw: bytes, start: int, stride: int, dtype: type, width: int, count: int):
    """``count`` elements of ``width`` components from ``raw`` at ``start``, ``stride``
    bytes apart."""
    size = np.dtype(dtype).itemsize * width
    data = np.frombuffer(raw, dtype=np.uint8, count=stride * (count - 1) + size, offset=start)
    data = np.concatenate([data, np.zeros(stride * count - len(data), np.uint8)])
    return data.reshape(count, stride)[:, :size].copy().view(dtype).reshape(count, width)


def accessor(doc: dict, blob: bytes, index: int) -> np.ndarray:
    """An accessor's values: floats for float and normalized accessors, else integers.
    A meshopt bufferView is decoded by the meshopt package, its QUATERNION and EXPONENTIAL
    filters by this module's own decoders of the specification."""
    spec = doc["accessors"][index]
    dtype = GLTF_DTYPES[spec["componentType"]]
    width = GLTF_WIDTHS[spec["type"]]
    view = doc["bufferViews"][spec["bufferView"]]
    ext = (view.get("extensions") or {}).get("EXT_meshopt_compression")
    stride = view.get("byteStride") or np.dtype(dtype).itemsize * width
    if ext:
        import meshopt

        data = blob[ext["byteOffset"] : ext["byteOffset"] + ext["byteLength"]]
        if ext["mode"] in ("TRIANGLES", "INDICES"):
            indices = np.asarray(
                meshopt.decode_gltf_buffer(data, ext["count"], ext["byteStride"], ext["mode"])
            ).reshape(-1)
            first = spec.get("byteOffset", 0) // ext["byteStride"]
            return indices[first : first + spec["count"]].reshape(-1, 1)
        name = ext.get("filter", "NONE")
        own = {"QUATERNION": decode_quaternion_filter, "EXPONENTIAL": decode_exponential_filter}
        rows = np.asarray(
            meshopt.decode_gltf_buffer(
                data, ext["count"], ext["byteStride"], "ATTRIBUTES", "NONE" if name in own else name
            )
        )
        raw = own[name](rows.tobytes()) if name in own else rows.tobytes()
        values = _strided(raw, spec.get("byteOffset", 0), stride, dtype, width, spec["count"])
    else:
        start = view.get("byteOffset", 0) + spec.get("byteOffset", 0)
        values = _strided(blob, start, stride, dtype, width, spec["count"])
    if spec.get("normalized"):
        scale = {np.int8: 127, np.uint8: 255, np.int16: 32767, np.uint16: 65535}[dtype]
        return np.maximum(values / scale, -1.0)
    return values.astype(np.float64) if dtype == np.float32 else values


def decode_primitive(doc: dict, blob: bytes, prim: dict) -> dict[str, np.ndarray]:
    """A primitive's attributes and ``indices`` (triangles), decoded with DracoPy or the
    meshopt package."""
    draco = (prim.get("extensions") or {}).get("KHR_draco_mesh_compression")
    if draco:
        view = doc["bufferViews"][draco["bufferView"]]
        mesh = DracoPy.decode(
            blob[view.get("byteOffset", 0) : view.get("byteOffset", 0) + view["byteLength"]]
        )
        by_id = {a["unique_id"]: np.asarray(a["data"]) for a in mesh.attributes}
        out = {name: by_id[i] for name, i in draco["attributes"].items()}
        for name, values in list(out.items()):
            spec = doc["accessors"][prim["attributes"][name]]
            assert spec["count"] == len(values)
            if spec.get("normalized"):
                out[name] = values / 255.0
        out["indices"] = np.asarray(mesh.faces).reshape(-1, 3)
        return out
    out = {name: accessor(doc, blob, i) for name, i in prim["attributes"].items()}
    shape = (-1, 3) if prim.get("mode", 4) == 4 else (-1,)
    if prim.get("indices") is not None:
        out["indices"] = accessor(doc, blob, prim["indices"]).reshape(shape)
    else:
        out["indices"] = np.arange(len(out["POSITION"])).reshape(shape)
    return out


def read_gltf(path: Path) -> tuple[dict, bytes]:
    """The document and its (first) buffer, read by pygltflib (whose dataclass decoding
    warns about optional fields left out, as glTF allows)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        gltf = pygltflib.GLTF2().load(str(path))
        doc = json.loads(gltf.to_json())
        if Path(path).suffix.lower() == ".glb":
            return doc, gltf.binary_blob() or b""
        uri = doc["buffers"][0].get("uri")
        return doc, (Path(path).parent / uri).read_bytes() if uri else b""


read_glb = read_gltf


def node_matrix(node: dict, float32: bool = False) -> np.ndarray:
    """A node's local transform (float64), from its matrix or its TRS; with ``float32``,
    each of its numbers first rounded to float32 (as cgltf, gltfpack and most engines
    read them)."""
    if float32:
        node = {
            key: np.asarray(node[key], dtype=np.float32).astype(np.float64).tolist()
            for key in ("matrix", "rotation", "scale", "translation")
            if key in node
        }
    if "matrix" in node:
        return np.asarray(node["matrix"], dtype=np.float64).reshape(4, 4).T
    x, y, z, w = node.get("rotation", [0, 0, 0, 1])
    r = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
    m = np.eye(4)
    m[:3, :3] = r * np.asarray(node.get("scale", [1, 1, 1]), dtype=np.float64)
    m[:3, 3] = np.asarray(node.get("translation", [0, 0, 0]), dtype=np.float64)
    return m


def world_matrices(doc: dict) -> dict[int, list[np.ndarray]]:
    """mesh -> world matrices of the nodes of the default scene that show it."""
    out: dict[int, list[np.ndarray]] = {}
    stack = [(n, np.eye(4)) for n in doc["scenes"][doc.get("scene", 0)]["nodes"]]
    while stack:
        index, parent = stack.pop()
        node = doc["nodes"][index]
        world = parent @ node_matrix(node)
        if "mesh" in node:
            out.setdefault(node["mesh"], []).append(world)
        stack += [(c, world) for c in node.get("children", [])]
    return out


def _triangles(indices: np.ndarray, mode: int) -> np.ndarray:
    """The triangles of a list (4), strip (5) or fan (6) of vertex indices, as the glTF
    specification (3.7.2.1) defines them."""
    if mode == 4:
        return indices.reshape(-1, 3)
    i = np.arange(len(indices) - 2)
    if mode == 5:
        odd = i % 2 == 1
        a, b = np.where(odd, i + 1, i), np.where(odd, i, i + 1)
        return np.stack([indices[a], indices[b], indices[i + 2]], axis=1)
    return np.stack([np.full(len(i), indices[0]), indices[i + 1], indices[i + 2]], axis=1)


def node_world_matrices(doc: dict, float32: bool = False) -> dict[int, np.ndarray]:
    """node -> its world matrix (composed in float64), for every node of the default
    scene; with ``float32``, of nodes whose numbers are read as float32."""
    out: dict[int, np.ndarray] = {}
    stack = [(n, np.eye(4)) for n in doc["scenes"][doc.get("scene", 0)]["nodes"]]
    while stack:
        index, parent = stack.pop()
        out[index] = parent @ node_matrix(doc["nodes"][index], float32)
        stack += [(c, out[index]) for c in doc["nodes"][index].get("children", [])]
    return out


def _skinned(
    doc: dict, blob: bytes, skin: dict, data: dict, worlds: dict[int, np.ndarray]
) -> np.ndarray:
    """Positions posed by a skin at the scene's default (rest) transforms, glTF 2.0
    Sec. 3.7.3: ``sum_k w_k * world(joint_k) @ inverseBind(joint_k) @ v``, in float64."""
    joints = skin["joints"]
    if skin.get("inverseBindMatrices") is not None:
        inverse = accessor(doc, blob, skin["inverseBindMatrices"]).astype(np.float64)
        inverse = inverse.reshape(-1, 4, 4).transpose(0, 2, 1)
    else:
        inverse = np.broadcast_to(np.eye(4), (len(joints), 4, 4))
    matrices = np.stack([worlds[j] @ inverse[i] for i, j in enumerate(joints)])
    local = np.asarray(data["POSITION"], dtype=np.float64)
    homogeneous = np.hstack([local, np.ones((len(local), 1))])
    posed = np.zeros((len(local), 4))
    sets = 0
    while f"JOINTS_{sets}" in data:
        index = np.asarray(data[f"JOINTS_{sets}"], dtype=np.int64)
        weight = np.asarray(data[f"WEIGHTS_{sets}"], dtype=np.float64)
        for k in range(index.shape[1]):
            posed += weight[:, k, None] * np.einsum(
                "nij,nj->ni", matrices[index[:, k]], homogeneous
            )
        sets += 1
    return posed[:, :3]


def _morphed(doc: dict, blob: bytes, mesh: dict, node: dict, prim: dict, local: np.ndarray):
    """Positions with the default morph weights applied (the node's, else the mesh's)."""
    weights = node.get("weights", mesh.get("weights"))
    if not weights or not any(weights):
        return local
    out = local.copy()
    for weight, target in zip(weights, prim.get("targets") or [], strict=False):
        if weight and "POSITION" in target:
            out += weight * accessor(doc, blob, target["POSITION"]).astype(np.float64)
    return out


def gltf_world_mesh(
    path: Path, skinned: bool = False, float32_transforms: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """Every triangle primitive of a .glb/.gltf at each node showing it, in world
    coordinates composed in float64: one mesh. With ``skinned``, a skinned node's
    primitives are posed by its skin at the rest transforms (the node's own transform is
    then ignored, as glTF says) and the default morph weights are applied: what a viewer
    shows before any animation plays. With ``float32_transforms``, every node's numbers
    are read as float32 first (the composition stays float64)."""
    doc, blob = read_gltf(path)
    worlds = node_world_matrices(doc, float32_transforms)
    vertices, faces, offset = [], [], 0
    for index, world in worlds.items():
        node = doc["nodes"][index]
        if "mesh" not in node:
            continue
        mesh = doc["meshes"][node["mesh"]]
        for prim in mesh["primitives"]:
            mode = prim.get("mode", 4)
            if mode not in (4, 5, 6):
                continue
            used = [prim["attributes"]["POSITION"], prim.get("indices")]
            if any(i is not None and "sparse" in doc["accessors"][i] for i in used):
                raise NotImplementedError("sparse accessors are not read here")
            data = decode_primitive(doc, blob, prim)
            triangles = _triangles(np.asarray(data["indices"], dtype=np.int64).reshape(-1), mode)
            local = np.asarray(data["POSITION"], dtype=np.float64)
            if skinned:
                local = _morphed(doc, blob, mesh, node, prim, local)
            if skinned and node.get("skin") is not None:
                data = dict(data, POSITION=local)
                vertices.append(_skinned(doc, blob, doc["skins"][node["skin"]], data, worlds))
            else:
                vertices.append(local @ world[:3, :3].T + world[:3, 3])
            faces.append(triangles + offset)
            offset += len(local)
    return np.concatenate(vertices), np.concatenate(faces)


def read_output(path: Path, float32_transforms: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """A written file as ``(vertices float64, faces int64)``, by a reader that is not
    meshbits's: DracoPy, pygltflib with DracoPy / meshopt, or trimesh
    (``float32_transforms``: :func:`gltf_world_mesh`'s)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".drc":
        mesh = DracoPy.decode(path.read_bytes())
        return (
            np.asarray(mesh.points, dtype=np.float64).reshape(-1, 3),
            np.asarray(mesh.faces, dtype=np.int64).reshape(-1, 3),
        )
    if suffix in (".glb", ".gltf"):
        return gltf_world_mesh(path, float32_transforms=float32_transforms)
    loaded = trimesh.load(path, process=False, force="mesh")
    return np.asarray(loaded.vertices, dtype=np.float64), np.asarray(loaded.faces, np.int64)


# --- float64 distances ----------------------------------------------------------------------


def point_triangle_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray):
    """Exact distances (float64) from points ``p`` to triangles ``(a, b, c)``, row by row
    (Ericson, Real-Time Collision Detection, 5.1.5); a degenerate triangle's distance is
    its nearest edge's."""
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = np.einsum("ij,ij->i", ab, ap), np.einsum("ij,ij->i", ac, ap)
    bp = p - b
    d3, d4 = np.einsum("ij,ij->i", ab, bp), np.einsum("ij,ij->i", ac, bp)
    cp = p - c
    d5, d6 = np.einsum("ij,ij->i", ab, cp), np.einsum("ij,ij->i", ac, cp)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = va + vb + vc
        inside = (va >= 0) & (vb >= 0) & (vc >= 0) & (denom > 0)
        # Projecting inside the triangle, the distance is the plane's: |ap . n| / |n|.
        # (Through the closest point a + v ab + w ac it carries the rounding of v and w,
        # which a long thin triangle amplifies: 1.7e-13 for a point on a 4 x 0.1 triangle
        # of MorphStressTest, whose plane distance is 0.)
        normal = np.cross(ab, ac)
        length = np.linalg.norm(normal, axis=1)
        inside &= length > 0
        plane = np.abs(np.einsum("ij,ij->i", ap, normal)) / np.where(length > 0, length, 1.0)
        best = np.where(inside, plane, np.inf)
    for s, e in ((a, b), (b, c), (c, a)):
        se = e - s
        length2 = np.einsum("ij,ij->i", se, se)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.clip(np.einsum("ij,ij->i", p - s, se) / length2, 0.0, 1.0)
        t = np.where(length2 > 0, t, 0.0)
        best = np.minimum(best, np.linalg.norm(p - (s + se * t[:, None]), axis=1))
    return best


def surface_samples(
    vertices: np.ndarray, faces: np.ndarray, count: int, seed: int
) -> tuple[np.ndarray, np.ndarray]:
    """``count`` area-weighted random points on the surface, and their faces."""
    corners = vertices[faces]
    area = 0.5 * np.linalg.norm(
        np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1
    )
    rng = np.random.default_rng(seed)
    weights = area / area.sum() if area.sum() > 0 else None
    chosen = rng.choice(len(faces), size=count, p=weights)
    r1, r2 = rng.random(count), rng.random(count)
    s = np.sqrt(r1)
    u, v, w = 1 - s, s * (1 - r2), s * r2
    c = corners[chosen]
    return c[:, 0] * u[:, None] + c[:, 1] * v[:, None] + c[:, 2] * w[:, None], chosen


def distances_to_mesh(
    points: np.ndarray, vertices: np.ndarray, faces: np.ndarray, pairs: int = 1 << 21
) -> np.ndarray:
    """Exact float64 distance from every point to the mesh. Each point's distance to its
    nearest vertex bounds it; the triangles whose centre lies within that bound plus
    their reach (found with a k-d tree over the triangles of the smallest 98% of reaches)
    are measured exactly, and those of the largest 2% whose box lies within the bound, in
    blocks of at most ``pairs`` point-triangle pairs."""
    corners = vertices[faces]
    centres = corners.mean(axis=1)
    reach = np.linalg.norm(corners - centres[:, None, :], axis=2).max(axis=1)
    cut = float(np.quantile(reach, 0.98)) if len(reach) else 0.0
    small = np.flatnonzero(reach <= cut)
    large = np.flatnonzero(reach > cut)
    upper, _ = cKDTree(vertices[np.unique(faces)]).query(points)
    out = np.full(len(points), np.inf)
    tree = cKDTree(centres[small]) if len(small) else None
    start = 0
    while start < len(points):
        block = slice(start, min(len(points), start + 64))
        if tree is not None:
            radii = upper[block] * (1 + 1e-12) + cut + 1e-300
            found = tree.query_ball_point(points[block], radii)
            rows = np.repeat(np.arange(block.start, block.stop), [len(c) for c in found])
            cols = small[np.concatenate([np.asarray(c, dtype=np.int64) for c in found])]
            for first in range(0, len(rows), pairs):
                r, c = rows[first : first + pairs], cols[first : first + pairs]
                d = point_triangle_distance(points[r], corners[c, 0], corners[c, 1], corners[c, 2])
                np.minimum.at(out, r, d)
        start = block.stop
    # The large triangles: those whose box lies within a point's bound, exactly.
    lo, hi = corners[large].min(axis=1), corners[large].max(axis=1)
    step = max(1, pairs // max(len(large), 1))
    for first in range(0, len(points) if len(large) else 0, step):
        block = points[first : first + step]
        gap = np.maximum(np.maximum(lo[None] - block[:, None], block[:, None] - hi[None]), 0.0)
        bound = upper[first : first + step] * (1 + 1e-12) + 1e-300
        near = np.nonzero((gap * gap).sum(axis=2) <= (bound * bound)[:, None])
        r, c = near[0] + first, large[near[1]]
        d = point_triangle_distance(points[r], corners[c, 0], corners[c, 1], corners[c, 2])
        np.minimum.at(out, r, d)
    return out


#: Above this many triangles, distances are ranked with Open3D (float32, when it is
#: installed) and only the farthest points are measured exactly, against every triangle.
RANKED_ABOVE = 20_000

#: Points measured exactly after ranking.
RANKED_TOP = 256


def _near_exact(
    points: np.ndarray, guesses: np.ndarray, vertices: np.ndarray, faces: np.ndarray
) -> np.ndarray:
    """Exact float64 distances from a few points to the mesh, given a float32 guess of each
    (Open3D's): only the triangles whose box lies within the guess plus a slack far beyond
    float32's error (1e-4 of the coordinates' and the guess's magnitude) can be nearest."""
    corners = vertices[faces]
    lo, hi = corners.min(axis=1), corners.max(axis=1)
    magnitude = float(np.abs(vertices).max())
    out = np.empty(len(points))
    for i, (point, guess) in enumerate(zip(points, guesses, strict=True)):
        reach = guess + 1e-4 * (magnitude + guess) + 1e-300
        gap = np.maximum(np.maximum(lo - point, point - hi), 0.0)
        near = np.flatnonzero((gap * gap).sum(axis=1) <= reach * reach)
        repeated = np.broadcast_to(point, (len(near), 3))
        c = corners[near]
        out[i] = point_triangle_distance(repeated, c[:, 0], c[:, 1], c[:, 2]).min()
    return out


def _farthest_exact(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Exact distances of the points that may be the farthest: all of them on a small
    mesh; on a large one, the :data:`RANKED_TOP` farthest by Open3D's float32 distance
    (every point exactly without Open3D). Returns ``(indices, distances)`` pairs as two
    arrays."""
    try:
        import open3d as o3d
    except ImportError:
        o3d = None
    if o3d is None or len(faces) <= RANKED_ABOVE:
        return np.arange(len(points)), distances_to_mesh(points, vertices, faces)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(
        o3d.core.Tensor(vertices.astype(np.float32)), o3d.core.Tensor(faces.astype(np.uint32))
    )
    ranked = scene.compute_distance(o3d.core.Tensor(points.astype(np.float32))).numpy()
    top = np.argsort(ranked)[-RANKED_TOP:]
    return top, _near_exact(points[top], ranked[top].astype(np.float64), vertices, faces)


def directed_lower(
    a: tuple[np.ndarray, np.ndarray],
    b: tuple[np.ndarray, np.ndarray],
    samples: int,
    seed: int,
) -> float:
    """A lower bound of the directed distance from ``a``'s surface to ``b``'s: the largest
    exact distance of ``a``'s referenced vertices and ``samples`` area samples, then of as
    many again on the faces of the 32 farthest samples."""
    (va, fa), (vb, fb) = a, b
    points, chosen = surface_samples(va, fa, samples, seed)
    used = va[np.unique(fa)]
    index, d = _farthest_exact(np.concatenate([points, used]), vb, fb)
    on_samples = index < len(points)
    far = index[on_samples][np.argsort(d[on_samples])[-32:]]
    if len(far) == 0:
        return float(d.max())
    faces = fa[chosen[far]]
    rng = np.random.default_rng(seed + 1)
    picks = rng.integers(0, len(faces), samples)
    r1, r2 = rng.random(samples), rng.random(samples)
    s = np.sqrt(r1)
    c = va[faces[picks]]
    dense = (
        c[:, 0] * (1 - s)[:, None] + c[:, 1] * (s * (1 - r2))[:, None] + c[:, 2] * (s * r2)[:, None]
    )
    return float(max(d.max(), _farthest_exact(dense, vb, fb)[1].max()))


def hausdorff_lower(
    a: tuple[np.ndarray, np.ndarray],
    b: tuple[np.ndarray, np.ndarray],
    samples: int = 20_000,
    seed: int = 7,
) -> float:
    """A lower bound of the symmetric Hausdorff distance (float64, exact distances)."""
    return max(directed_lower(a, b, samples, seed), directed_lower(b, a, samples, seed + 2))
