"""The glTF 2.0 specification as meshbits reads it: component and accessor types,
primitive modes, the extensions read, and the conversions the specification defines
(normalized integers, strips and fans, a node's TRS transform).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ...errors import MeshFileError

__all__ = [
    "ANIMATION_PATHS",
    "ATTRIBUTE_TYPES",
    "COLLECTIONS",
    "COMPONENT_DTYPES",
    "COMPONENT_TYPES",
    "DRACO",
    "GEOMETRY_NEUTRAL_PREFIXES",
    "GLB_MAGIC",
    "MESHOPT_EXTENSIONS",
    "MESHOPT_LIMIT",
    "READ_EXTENSIONS",
    "TRIANGLES",
    "TRIANGLE_FAN",
    "TRIANGLE_STRIP",
    "TYPE_WIDTHS",
    "WIDTH_TYPES",
    "from_normalized",
    "triangles",
    "trs_matrix",
    "unread_required_extensions",
]

#: numpy dtype of each glTF component type.
COMPONENT_DTYPES = {
    5120: np.dtype(np.int8),
    5121: np.dtype(np.uint8),
    5122: np.dtype(np.int16),
    5123: np.dtype(np.uint16),
    5125: np.dtype(np.uint32),
    5126: np.dtype(np.float32),
}
COMPONENT_TYPES = {dtype: code for code, dtype in COMPONENT_DTYPES.items()}

#: Components of each accessor type.
TYPE_WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
WIDTH_TYPES = {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4"}

#: Primitive modes (glTF 2.0 `mesh.primitive.mode`).
TRIANGLES, TRIANGLE_STRIP, TRIANGLE_FAN = 4, 5, 6

GLB_MAGIC = b"glTF"

#: The bufferView compressions the reader decodes (meshoptimizer's codecs).
MESHOPT_EXTENSIONS = ("EXT_meshopt_compression", "KHR_meshopt_compression")

#: The primitive compression the reader decodes (with DracoPy).
DRACO = "KHR_draco_mesh_compression"

#: Extensions that change how geometry is stored, which the reader decodes, and one that
#: the scene writer carries over as it is (``EXT_mesh_gpu_instancing``).
READ_EXTENSIONS = frozenset(
    {DRACO, "KHR_mesh_quantization", "EXT_mesh_gpu_instancing"} | set(MESHOPT_EXTENSIONS)
)

#: Families of extensions that leave the geometry as glTF stores it (materials, textures,
#: images, lights, metadata): a reader of meshes may skip them, required or not.
GEOMETRY_NEUTRAL_PREFIXES = (
    "KHR_materials_",
    "KHR_texture_",
    "EXT_texture_",
    "MSFT_texture_",
    "KHR_lights_",
    "EXT_lights_",
    "KHR_xmp",
    "KHR_animation_pointer",
    "KHR_node_visibility",
)

#: Largest ``count`` or ``byteStride`` of a meshopt bufferView the reader takes.
MESHOPT_LIMIT = 1 << 62

#: Top-level glTF collections (arrays of objects) that other objects refer to by index.
COLLECTIONS = (
    "accessors",
    "animations",
    "bufferViews",
    "buffers",
    "cameras",
    "images",
    "materials",
    "meshes",
    "nodes",
    "samplers",
    "scenes",
    "skins",
    "textures",
)

#: Accessor types each standard attribute allows (glTF 2.0 Sec. 3.7.2.1).
ATTRIBUTE_TYPES = {
    "POSITION": ("VEC3",),
    "NORMAL": ("VEC3",),
    "TANGENT": ("VEC4",),
    "TEXCOORD": ("VEC2",),
    "COLOR": ("VEC3", "VEC4"),
    "JOINTS": ("VEC4",),
    "WEIGHTS": ("VEC4",),
}

#: Animation channel paths (glTF 2.0, and KHR_animation_pointer's ``pointer``).
ANIMATION_PATHS = ("translation", "rotation", "scale", "weights", "pointer")


def unread_required_extensions(document: Any) -> list[str]:
    """The extensions a document requires (``extensionsRequired``) that change how its
    geometry is stored and that meshbits does not decode: a reader must refuse it."""
    required = document.get("extensionsRequired") if isinstance(document, dict) else None
    if not isinstance(required, list):
        return []
    names = [str(name) for name in required]
    return [
        name
        for name in names
        if name not in READ_EXTENSIONS and not name.startswith(GEOMETRY_NEUTRAL_PREFIXES)
    ]


def from_normalized(values: np.ndarray) -> np.ndarray:
    """Normalized integers as the glTF spec maps them to floats."""
    kind = values.dtype
    if kind == np.uint8:
        return values / 255.0
    if kind == np.uint16:
        return values / 65535.0
    if kind == np.int8:
        return np.maximum(values / 127.0, -1.0)
    if kind == np.int16:
        return np.maximum(values / 32767.0, -1.0)
    return values.astype(np.float64)


def trs_matrix(translation: Any, rotation: Any, scale: Any) -> np.ndarray:
    """``T * R * S`` (4x4) from a translation, a unit quaternion ``(x, y, z, w)`` and a
    scale, as glTF composes a node's."""
    x, y, z, w = (float(c) for c in rotation)
    r = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
    out = np.eye(4)
    out[:3, :3] = r * np.asarray(scale, dtype=np.float64)
    out[:3, 3] = np.asarray(translation, dtype=np.float64)
    return out


def triangles(indices: np.ndarray, mode: int) -> np.ndarray:
    """A triangle list, strip or fan's indices as triangles, ``(m, 3)``."""
    if mode == TRIANGLES:
        if len(indices) % 3:
            raise MeshFileError(f"a triangle list has {len(indices)} indices, not a multiple of 3")
        return indices.reshape(-1, 3)
    if len(indices) < 3:
        return np.zeros((0, 3), dtype=np.int64)
    if mode == TRIANGLE_STRIP:
        i = np.arange(len(indices) - 2)
        tri = np.stack([indices[i], indices[i + 1], indices[i + 2]], axis=1)
        odd = i % 2 == 1
        tri[odd] = tri[odd][:, [1, 0, 2]]
        return tri
    i = np.arange(1, len(indices) - 1)
    return np.stack([np.full(len(i), indices[0]), indices[i], indices[i + 1]], axis=1)
