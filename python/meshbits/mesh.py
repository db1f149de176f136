"""Normalise anything mesh-like to the arrays the native kernels take.

The kernels want ``vertices`` as C-ordered float64 ``(n, 3)`` and ``faces`` as C-ordered
uint32 ``(m, 3)``. Every public function goes through :func:`as_mesh` or
:func:`as_points`, so bad input is refused once, here, with a message that names the
argument, what was expected and what arrived.
"""

from __future__ import annotations

from typing import Any, Protocol, TypeAlias

import numpy as np
import numpy.typing as npt

from . import _core
from .errors import MeshbitsError

__all__ = [
    "MAX_BOX_OVERLAP",
    "MeshLike",
    "as_mesh",
    "as_points",
    "box_overlap",
    "check_overlap",
    "compact",
    "referenced",
    "refuse_overlap",
    "weld",
]


class VerticesAndFaces(Protocol):
    """A ``trimesh.Trimesh``, or any object with ``vertices (n, 3)`` and ``faces (m, 3)``."""

    @property
    def vertices(self) -> npt.ArrayLike: ...

    @property
    def faces(self) -> npt.ArrayLike: ...


class VerticesAndTriangles(Protocol):
    """An Open3D ``TriangleMesh`` (``vertices`` and ``triangles``, as Open3D vectors)."""

    @property
    def vertices(self) -> Any: ...

    @property
    def triangles(self) -> Any: ...


#: What every function that takes a mesh accepts: a ``trimesh.Trimesh`` (or any object
#: with ``vertices`` and ``faces``), an Open3D ``TriangleMesh`` (legacy or
#: ``open3d.t.geometry``), or a ``(vertices, faces)`` pair of arrays.
MeshLike: TypeAlias = (
    VerticesAndFaces | VerticesAndTriangles | tuple[npt.ArrayLike, npt.ArrayLike] | Any
)


def as_points(
    points: Any, name: str = "points", *, allow_empty: bool = False, check_finite: bool = True
) -> np.ndarray:
    """Return ``points`` as a C-ordered float64 ``(n, 3)`` array of finite values.

    ``check_finite=False`` skips the NaN/infinity check, for kernels that refuse
    non-finite coordinates themselves; on such a refusal the caller can run the check
    to name the row.

    Raises
    ------
    TypeError
        If the dtype is not a real number type.
    ValueError
        If the shape is not ``(n, 3)``, a value is NaN or infinite, or the array is empty
        and ``allow_empty`` is false.
    """
    array = _asarray(points, name, "(n, 3) coordinates")
    if array.dtype == object or not (
        np.issubdtype(array.dtype, np.floating) or np.issubdtype(array.dtype, np.integer)
    ):
        raise TypeError(f"{name} must hold real numbers, got dtype {array.dtype}")
    if array.ndim != 2 or array.shape[1] != 3:
        raise MeshbitsError(f"{name} must have shape (n, 3), got {array.shape}")
    if len(array) == 0 and not allow_empty:
        raise MeshbitsError(f"{name} is empty: expected at least one point")
    out = np.ascontiguousarray(array, dtype=np.float64)
    # Fast path: the per-row reduction below costs ~15x more.
    if not check_finite or np.isfinite(out).all():
        return out
    finite = np.isfinite(out).all(axis=1)
    if not finite.all():
        bad = int(np.flatnonzero(~finite)[0])
        count = int((~finite).sum())
        rows = "1 row has" if count == 1 else f"{count} rows have"
        raise MeshbitsError(
            f"{name}[{bad}] = {out[bad].tolist()} is not finite "
            f"({rows} NaN or infinite coordinates)"
        )
    return out


def _asarray(value: Any, name: str, what: str) -> np.ndarray:
    """``np.asarray(value)``; a ragged sequence (rows of different lengths) is refused
    naming the argument, not with numpy's ``ValueError``."""
    try:
        return np.asarray(value)
    except ValueError as err:
        raise MeshbitsError(
            f"{name} must be {what}, got a {type(value).__name__} whose rows have different "
            f"lengths ({err})"
        ) from None


def _as_faces(faces: Any, vertex_count: int, keep_int64: bool = False) -> np.ndarray:
    array = _asarray(faces, "faces", "(m, 3) vertex indices")
    if array.dtype == bool or not np.issubdtype(array.dtype, np.integer):
        if array.size == 0 and array.ndim == 2:
            array = array.astype(np.int64)
        else:
            raise TypeError(f"faces must hold integer vertex indices, got dtype {array.dtype}")
    if array.ndim != 2 or array.shape[1] != 3:
        raise MeshbitsError(f"faces must have shape (m, 3) (triangles), got {array.shape}")
    if len(array) == 0:
        raise MeshbitsError("mesh is empty: faces has no rows")
    if array.dtype == np.int64 and array.flags.c_contiguous:
        if keep_int64:
            return array
        converted = _core.faces_as_u32(array, vertex_count)
        if converted is not None:
            return converted
    low, high = int(array.min()), int(array.max())
    if low < 0:
        row = int(np.flatnonzero((array < 0).any(axis=1))[0])
        raise MeshbitsError(f"faces[{row}] = {array[row].tolist()} has a negative vertex index")
    if high >= vertex_count:
        row = int(np.flatnonzero((array >= vertex_count).any(axis=1))[0])
        raise MeshbitsError(
            f"faces[{row}] = {array[row].tolist()} refers to a vertex out of range "
            f"(there are {vertex_count} vertices)"
        )
    if vertex_count > np.iinfo(np.uint32).max:
        raise MeshbitsError(f"{vertex_count} vertices exceed the supported maximum of 2**32 - 1")
    return np.ascontiguousarray(array, dtype=np.uint32)


def as_mesh(
    mesh: MeshLike, faces: Any = None, *, keep_int64: bool = False, check_finite: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """Return ``(vertices, faces)`` as C-ordered ``float64 (n, 3)`` and ``uint32 (m, 3)``.

    Parameters
    ----------
    mesh
        A ``trimesh.Trimesh`` (or any object with ``vertices`` and ``faces``), an Open3D
        ``TriangleMesh`` (legacy or tensor), a ``(vertices, faces)`` pair, or a vertex
        array when ``faces`` is given.
    faces
        ``(m, 3)`` integer vertex indices of any integer dtype, C or Fortran order.
    keep_int64
        Return C-ordered int64 faces (numpy's default integer, trimesh's) as they are,
        indices unchecked, for kernels that read int64 and check the indices themselves:
        this skips a conversion pass over the faces.
    check_finite
        ``False`` leaves NaN and infinite coordinates to the kernel (see
        :func:`as_points`).

    Raises
    ------
    TypeError
        Wrong dtypes, or something that is not a mesh.
    ValueError
        Wrong shapes, no vertices or faces, NaN or infinite coordinates, negative or
        out-of-range indices.
    """
    if faces is None:
        if hasattr(mesh, "vertices") and hasattr(mesh, "faces"):
            vertices, faces = mesh.vertices, mesh.faces
        elif hasattr(mesh, "vertices") and hasattr(mesh, "triangles"):  # Open3D
            vertices, faces = np.asarray(mesh.vertices), np.asarray(mesh.triangles)
        elif hasattr(mesh, "vertex") and hasattr(mesh, "triangle"):  # open3d.t.geometry
            vertices = mesh.vertex["positions"].numpy()
            faces = mesh.triangle["indices"].numpy()
        elif isinstance(mesh, (tuple, list)) and len(mesh) == 2:
            vertices, faces = mesh
        else:
            raise TypeError(
                "expected a trimesh.Trimesh, an Open3D TriangleMesh, a (vertices, faces) pair, "
                f"or vertices and faces, got {type(mesh).__name__}"
            )
    else:
        vertices = mesh
    vertices = as_points(vertices, "vertices", check_finite=check_finite)
    return vertices, _as_faces(faces, len(vertices), keep_int64)


#: Most triangle bounding boxes a point of the mesh's box may lie in, on average, before
#: closest-point queries are refused (see :func:`box_overlap`). Surfaces score 0.03 to
#: 0.4 (bunny 0.036, dragon 0.039, Suzanne 0.37); fan-triangulated polygons of vertices
#: from all over a mesh scored 319 (5,688 faces: compress took 62 s) and 18,100 (240k
#: faces: 10,000 queries took 140 s).
MAX_BOX_OVERLAP = 64.0


def referenced(faces: np.ndarray, n_vertices: int | None = None) -> np.ndarray:
    """The indices of the vertices some face uses, increasing (``np.unique(faces)``
    by a flag per vertex: linear, not a sort). ``faces`` must be valid indices."""
    flat = np.asarray(faces).ravel()
    if n_vertices is None:
        n_vertices = int(flat.max()) + 1 if flat.size else 0
    used = np.zeros(n_vertices, dtype=bool)
    used[flat] = True
    return np.flatnonzero(used)


def weld(mesh: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Point every face at the first of the vertices with its coordinates (STL files are
    triangle soups: without this no edge is shared); duplicates become unreferenced (the
    vertices are kept as they are, the same array when nothing merges)."""
    vertices, faces = mesh
    welded, merged = _core.weld(vertices, faces)
    return (vertices, welded) if merged else mesh


def all_faces_degenerate(vertices: np.ndarray, faces: np.ndarray) -> bool:
    """True when every face has two corners at one position: nothing with area is left
    (Draco encodes none of it)."""
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    return bool(((a == b).all(axis=1) | (b == c).all(axis=1) | (a == c).all(axis=1)).all())


def distinct_positions(vertices: np.ndarray) -> int:
    """How many distinct positions the vertices take: a mesh's vertex count as the paper's
    V counts it, whatever copies an encoder split them into (Draco splits the vertices of
    non-manifold edges and boundaries: the bunny at 453 vertices decodes to 651)."""
    vertices = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    if len(vertices) == 0:
        return 0
    return len(np.unique(np.where(vertices == 0.0, 0.0, vertices), axis=0))


#: An output keeping less than this fraction of its input's surface area, or less than
#: :data:`LOST_EXTENT` of its bounding box's largest side, is said to have lost the
#: geometry, whatever budget it meets.
LOST_AREA = 0.1
LOST_EXTENT = 0.5


def zero_area_faces(vertices: np.ndarray, faces: np.ndarray) -> int:
    """Faces whose corners span no area (a segment or a point), counted."""
    corners = np.asarray(vertices, dtype=np.float64)[np.asarray(faces).reshape(-1, 3)]
    cross = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    return int((~np.any(cross != 0, axis=1)).sum())


def draco_drops_note(vertices: np.ndarray, faces: np.ndarray, where: str = "the mesh") -> str:
    """Why Draco may miss an error budget that the model expects it to meet: it drops
    zero-area faces, whose edges are part of the surface measured (a segment is no less a
    part of it than a sliver); an empty string when there are none."""
    count = zero_area_faces(vertices, faces)
    if not count:
        return ""
    return (
        f"; {where} has {count:,} zero-area face{'s' if count > 1 else ''}, which Draco "
        "drops: their edges count as surface in the measured error (meshopt keeps them)"
    )


def surface_area(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Total area of the triangles (length squared)."""
    corners = np.asarray(vertices, dtype=np.float64)[np.asarray(faces).reshape(-1, 3)]
    cross = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    return float(0.5 * np.linalg.norm(cross, axis=1).sum())


def _extent(vertices: np.ndarray, faces: np.ndarray) -> float:
    used = np.asarray(vertices, dtype=np.float64)[np.unique(np.asarray(faces).reshape(-1))]
    return float(np.ptp(used, axis=0).max()) if len(used) else 0.0


def kept_shape(
    original: tuple[np.ndarray, np.ndarray], output: tuple[np.ndarray, np.ndarray]
) -> tuple[float, float]:
    """How much of the original's surface area and of its largest box side (over its
    referenced vertices) the output keeps, as fractions (1 for an original with none)."""
    area, extent = surface_area(*original), _extent(*original)
    kept_area = surface_area(*output) / area if area > 0 else 1.0
    kept_extent = _extent(*output) / extent if extent > 0 else 1.0
    return kept_area, kept_extent


def lost_geometry_note(kept_area: float, kept_extent: float) -> str:
    """A warning when an output keeps almost none of its input's area or extent
    (:data:`LOST_AREA`, :data:`LOST_EXTENT`); else an empty string."""
    if kept_area >= LOST_AREA and kept_extent >= LOST_EXTENT:
        return ""
    return (
        f"; warning: the output keeps {100 * kept_area:.3g}% of the input's surface area "
        f"and {100 * kept_extent:.3g}% of its extent: the geometry is lost"
    )


def compact(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The mesh without its unreferenced vertices: ``vertices[used]`` and the faces
    renumbered over them (int64), as ``np.unique(faces, return_inverse=True)`` gives."""
    faces = np.asarray(faces)
    used = referenced(faces, len(vertices))
    renumber = np.empty(len(vertices), dtype=np.int64)
    renumber[used] = np.arange(len(used), dtype=np.int64)
    return vertices[used], renumber[faces.reshape(-1, 3)]


def box_overlap(vertices: np.ndarray, faces: np.ndarray) -> float:
    """How many triangle bounding boxes a point of the mesh's bounding box lies in, on
    average: the sum of the triangles' box volumes over the mesh's box volume, every box
    widened on each axis by 1e-3 of the mesh's side on that axis (at least 1e-8 of its
    largest side) so flat boxes count; stretching an axis does not change it, and parts
    far apart add no overlap through the empty space between them. A BVH query visits
    about this many triangles beyond the few near it (dimensionless). One parallel pass
    in the Rust core; ``faces`` must index ``vertices``."""
    vertices = np.ascontiguousarray(vertices, dtype=np.float64)
    faces = np.ascontiguousarray(faces).reshape(-1, 3)
    if faces.dtype != np.uint32:
        converted = _core.faces_as_u32(faces.astype(np.int64, copy=False), len(vertices))
        if converted is None:
            raise MeshbitsError("faces index vertices out of range")
        faces = converted
    return float(_core.box_overlap(vertices, faces))


def check_overlap(vertices: np.ndarray, faces: np.ndarray, name: str = "the mesh") -> None:
    """Refuse a mesh whose triangles overlap beyond :data:`MAX_BOX_OVERLAP`: measuring
    distances to it would take minutes to hours, not seconds."""
    refuse_overlap(box_overlap(vertices, faces), len(faces), name)


def refuse_overlap(overlap: float, n_faces: int, name: str = "the mesh") -> None:
    """:func:`check_overlap` of a mesh whose :func:`box_overlap` is known (a BVH measures
    it while it is built: ``tree.box_overlap``)."""
    if overlap > MAX_BOX_OVERLAP:
        raise MeshbitsError(
            f"{name}'s {n_faces:,} triangles overlap: a point of its bounding box lies in "
            f"{overlap:,.0f} triangles' boxes on average (a surface: below 1; at most "
            f"{MAX_BOX_OVERLAP:g} are measured), so each distance query would visit "
            "thousands of triangles. Remove the overlapping faces first (polygons of many "
            "corners fan-triangulated?)"
        )
