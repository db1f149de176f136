"""Grid quantization to B bits per coordinate and vertex clustering.

King & Rossignac 1999, Sec. 1.1 and 3.3 (the grid and its error bound ``(sqrt(3)/2) * S /
(2^B - 1)``), Sec. 8 (the centred code convention), and Rossignac & Borrel's vertex
clustering (the paper's reference [20]). The kernels are in ``rust/quantize/``.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from . import _core
from .constants import CONVENTIONS, DUPLICATES, GRIDS, MAX_BITS, MIN_BITS
from .errors import MeshbitsError
from .mesh import MeshLike, as_mesh, as_points
from .results import ArrayResult

__all__ = [
    "Clustered",
    "Quantized",
    "cluster",
    "cube_grid",
    "dequantize",
    "precision_bits",
    "quantize",
]

_GRID_DOC = """grid
        ``"cube"`` (default): one step ``S / (2^B - 1)`` on every axis, ``S`` the largest
        side of the box (the paper, Draco, gltfpack). ``"axes"``: a step
        ``(max_a - min_a) / (2^B - 1)`` per axis.
    box
        ``(min, max)``, two 3-vectors (length): quantize on this box instead of the
        bounding box of the vertices, so that several meshes share one grid. A vertex
        outside the closed box raises :class:`meshbits.MeshbitsError`.
    convention
        ``"corner"`` (default): codes in ``[0, 2^B - 1]``, code 0 at ``box min``
        (Sec. 1.1). ``"centered"``: the same grid with codes shifted by
        ``2^(B-1) - 1`` into ``[-2^(B-1) + 1, 2^(B-1)]`` (Sec. 8); positions and errors
        do not change."""


def _check_bits(bits: Any) -> int:
    if isinstance(bits, bool) or not isinstance(bits, numbers.Integral):
        raise TypeError(f"bits must be an integer, got {bits!r}")
    if not MIN_BITS <= int(bits) <= MAX_BITS:
        raise MeshbitsError(f"bits must be from {MIN_BITS} to {MAX_BITS}, got {int(bits)}")
    return int(bits)


def _check_choice(name: str, value: Any, choices: tuple[str, ...]) -> str:
    if value not in choices:
        raise MeshbitsError(f"{name} must be one of {choices}, got {value!r}")
    return str(value)


def _as_box(box: Any) -> tuple[tuple[float, ...], tuple[float, ...]] | tuple[None, None]:
    if box is None:
        return None, None
    try:
        corners = np.asarray(box, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise TypeError(f"box must be (min, max), two 3-vectors of numbers: {err}") from err
    if corners.shape != (2, 3):
        raise MeshbitsError(f"box must be (min, max), two 3-vectors, got shape {corners.shape}")
    return tuple(corners[0].tolist()), tuple(corners[1].tolist())


def _corner(value: Any, name: str) -> np.ndarray:
    """A box corner as a float64 3-vector; anything else refused naming ``name``."""
    try:
        corner = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise TypeError(f"{name} must be a 3-vector of numbers, got {value!r} ({err})") from None
    if corner.size != 3:
        raise MeshbitsError(f"{name} must be a 3-vector, got shape {corner.shape}")
    return corner.reshape(3)


def cube_grid(lo: Any, hi: Any) -> tuple[np.ndarray, float]:
    """Origin and side ``S`` of the cube grid over the box ``[lo, hi]`` (length).

    ``S`` is the largest side ``max(hi - lo)``, raised by the fewest float64 ulps for which
    the grid's far corner ``lo + S``, computed in float64 as the quantizer computes it,
    reaches ``hi`` on every axis: ``lo + (hi - lo)`` can round an ulp below ``hi``, which
    would leave a point on the box's far face outside the grid. Pass
    ``box=(origin, origin + S)`` to :func:`quantize` or :func:`cluster`.
    """
    low, high = _corner(lo, "lo"), _corner(hi, "hi")
    if not (np.isfinite(low).all() and np.isfinite(high).all() and (low <= high).all()):
        raise MeshbitsError(f"box must have finite corners with min <= max, got {low}, {high}")
    with np.errstate(over="ignore"):
        side = float((high - low).max())
    if not math.isfinite(side):
        raise MeshbitsError(f"box side overflows float64: from {low} to {high}")
    while (low + side < high).any():
        side = float(np.nextafter(side, np.inf))
    return low, side


def precision_bits(vertices: Any, grid_size: float | None = None) -> int:
    """Bits per coordinate beyond which a cube grid of side ``S`` cannot add accuracy to
    ``vertices``: the smallest ``B`` whose step ``S / (2^B - 1)`` is at most the spacing of
    their floating-point numbers at their largest magnitude.

    Coordinates that float32 holds exactly (every PLY, STL and glTF file of float32
    positions, even when read as float64) are spaced ``2^-23`` of that magnitude apart, so
    a mesh whose box touches its largest coordinate carries about 24 bits: more bits cost
    bytes and encoder memory (Draco allocates ``2^B``-sized tables) and move no vertex
    closer to where the file put it. float64 coordinates carry about 53.

    Parameters
    ----------
    vertices : (n, 3) float
        The coordinates (length).
    grid_size : float, optional
        ``S`` (length); default: the largest side of the vertices' bounding box.
    """
    array = as_points(vertices, "vertices")
    if grid_size is None:
        with np.errstate(over="ignore"):
            grid_size = float((array.max(axis=0) - array.min(axis=0)).max())
    elif isinstance(grid_size, bool) or not isinstance(grid_size, numbers.Real):
        raise TypeError(f"grid_size must be a real number, got {grid_size!r}")
    grid_size = float(grid_size)
    if not math.isfinite(grid_size):
        raise MeshbitsError(
            f"grid_size must be finite, got {grid_size} (a box side beyond the float64 range?)"
        )
    largest = float(np.abs(array).max())
    if not grid_size > 0 or largest == 0:
        return MIN_BITS
    with np.errstate(over="ignore"):  # beyond float32's range: not exact, rightly
        exact32 = np.array_equal(array.astype(np.float32).astype(np.float64), array)
    # The spacing of floats at the largest coordinate, from its exponent (np.spacing
    # overflows at the top of the range): 2^(e - 23) in float32, 2^(e - 52) in float64.
    exponent = math.frexp(largest)[1] - 1
    spacing = math.ldexp(1.0, max(exponent - (23 if exact32 else 52), -1074))
    ratio = grid_size / spacing
    if not math.isfinite(ratio):  # S / spacing beyond float64: in logarithms
        return math.ceil(math.log2(grid_size) - math.log2(spacing))
    return max(MIN_BITS, math.ceil(math.log2(ratio + 1.0)))


def _is_table(value: Any) -> bool:
    """Whether ``value`` reads as a 2-D array (the faces of a pair, not a point)."""
    try:
        return np.ndim(value) == 2
    except ValueError:  # ragged
        return False


def _grid_fields(raw: dict[str, Any]) -> dict[str, Any]:
    return {
        "origin": np.asarray(raw.pop("origin")),
        "step": np.asarray(raw.pop("step")),
        "box_min": np.asarray(raw.pop("box_min")),
        "box_max": np.asarray(raw.pop("box_max")),
    }


@dataclass(frozen=True, eq=False)
class Quantized(ArrayResult):
    """Points quantized on a grid (paper Sec. 1.1).

    Attributes
    ----------
    codes : ndarray, shape (n, 3)
        Integer codes. ``"corner"``: ``uint16`` for ``bits <= 16``, else ``uint32``, in
        ``[0, 2^B - 1]``. ``"centered"``: ``int16`` for ``bits <= 15``, ``int32`` for
        ``bits <= 31``, ``int64`` for 32, in ``[-2^(B-1) + 1, 2^(B-1)]``.
    positions : ndarray, shape (n, 3), float64
        Dequantised positions ``origin + codes * step`` (length).
    origin : ndarray, shape (3,), float64
        Position of code ``(0, 0, 0)`` (length): ``box_min`` for ``"corner"``,
        ``box_min + (2^(B-1) - 1) * step`` for ``"centered"``.
    step : ndarray, shape (3,), float64
        Length of one code unit per axis (length); 0 on an axis of zero extent.
    box_min, box_max : ndarray, shape (3,), float64
        The box the grid was laid on (length).
    grid_size : float
        ``S``, the largest side of the box (length).
    bits : int
        Bits per coordinate ``B``.
    max_displacement : float
        Measured ``max |positions - points|`` (Euclidean, length).
    bound : float
        Guaranteed ``0.5 * |step|`` (length): ``(sqrt(3)/2) * S / (2^B - 1)`` on the cube
        grid. ``max_displacement <= bound`` up to the float64 rounding of the positions
        (a few ulp of the largest coordinate).
    grid, convention : str
        The options used.
    """

    codes: np.ndarray = field(repr=False)
    positions: np.ndarray = field(repr=False)
    origin: np.ndarray
    step: np.ndarray
    box_min: np.ndarray
    box_max: np.ndarray
    grid_size: float
    bits: int
    max_displacement: float
    bound: float
    grid: str
    convention: str

    _arrays = ("codes", "positions")


@dataclass(frozen=True, eq=False)
class Clustered(ArrayResult):
    """A mesh after vertex clustering on a grid (Rossignac-Borrel).

    Attributes
    ----------
    vertices : ndarray, shape (k, 3), float64
        One vertex per kept cluster, at the dequantised position of its code (length), so
        ``vertices == origin + codes * step`` exactly. Ordered by the smallest input index
        in each cluster.
    faces : ndarray, shape (f, 3), uint32
        Kept faces, in input order, with their input winding, indexing ``vertices``
        (uint32 like the face arrays the kernels take; ``trimesh.Trimesh`` accepts it).
    codes : ndarray, shape (k, 3)
        Codes of ``vertices``, dtype as in :class:`Quantized`.
    vertex_map : ndarray, shape (n,), int64
        Output vertex of each input vertex, ``-1`` when its cluster was dropped.
    face_index : ndarray, shape (f,), uint32
        Input face of each output face (ascending).
    input_vertices, input_faces, output_vertices, output_faces : int
        Sizes before and after. ``input_vertices = output_vertices + merged_vertices +
        unreferenced_vertices`` and ``input_faces = output_faces + degenerate_faces +
        duplicate_faces``.
    merged_vertices : int
        Input vertices that share another input vertex's code (``n`` minus the number
        of distinct codes).
    unreferenced_vertices : int
        Clusters that no kept face uses (unreferenced input vertices, and vertices whose
        faces all collapsed); they are dropped.
    degenerate_faces : int
        Faces with two equal corners after merging (also faces that repeated a vertex
        index in the input).
    duplicate_faces : int
        Faces dropped as repeats of an earlier kept face (see ``duplicates``).
    max_displacement : float
        Measured largest distance from a kept input vertex to its output vertex (length).
    origin, step, box_min, box_max, grid_size, bits, bound, grid, convention
        The grid, as in :class:`Quantized`.
    duplicates : str
        The duplicate rule used.
    """

    vertices: np.ndarray = field(repr=False)
    faces: np.ndarray = field(repr=False)
    codes: np.ndarray = field(repr=False)
    vertex_map: np.ndarray = field(repr=False)
    face_index: np.ndarray = field(repr=False)
    input_vertices: int
    input_faces: int
    output_vertices: int
    output_faces: int
    merged_vertices: int
    unreferenced_vertices: int
    degenerate_faces: int
    duplicate_faces: int
    max_displacement: float
    origin: np.ndarray
    step: np.ndarray
    box_min: np.ndarray
    box_max: np.ndarray
    grid_size: float
    bits: int
    bound: float
    grid: str
    convention: str
    duplicates: str

    _arrays = ("vertices", "faces", "codes", "vertex_map", "face_index")


def quantize(
    points: Any,
    bits: int,
    *,
    grid: str = "cube",
    box: Any = None,
    convention: str = "corner",
) -> Quantized:
    """Quantize points to ``bits`` bits per coordinate on a grid (paper Sec. 1.1, 3.3).

    Per axis, ``q = round((x - box_min) / step)`` with ``step = S / (2^B - 1)``, halves
    rounded up, computed in float64 relative to ``box_min`` (so coordinates far from the
    origin keep their precision); dequantised ``x' = box_min + q * step``.

    Parameters
    ----------
    points
        ``(n, 3)`` real coordinates (length), or a mesh (its ``vertices`` are used, all of
        them). Empty only together with ``box``.
    bits
        ``B``, an integer from 1 to 32.
    {grid_doc}

    Returns
    -------
    Quantized

    Notes
    -----
    Zero extent: an axis with step 0 (a flat axis under ``"axes"``, or every axis when
    all points coincide) gets code 0 there and keeps its coordinate exactly; ``bound``
    is then 0 on that axis. ``positions`` are float64: when ``step`` falls below the
    spacing of float64 numbers near the coordinates (32 bits on a box far from the
    origin), the codes stay exact but the positions cannot hold the grid.

    Raises
    ------
    ValueError
        Bad shape, NaN or infinite coordinates, ``bits`` outside 1..32, an unknown option,
        a bad box, or a point outside ``box`` (:class:`meshbits.MeshbitsError`).
    TypeError
        Non-numeric points or box, non-integer ``bits``.
    """
    bits = _check_bits(bits)
    grid = _check_choice("grid", grid, GRIDS)
    convention = _check_choice("convention", convention, CONVENTIONS)
    box_min, box_max = _as_box(box)
    if hasattr(points, "vertices"):
        points = points.vertices
    elif isinstance(points, tuple) and len(points) == 2 and _is_table(points[1]):
        points = points[0]  # a (vertices, faces) pair: every vertex, as for a mesh
    array = as_points(points, "points", allow_empty=box_min is not None)
    raw: dict[str, Any] = dict(
        _core.quantize(array, bits, grid, box_min, box_max, convention == "centered")
    )
    return Quantized(
        codes=raw.pop("codes"),
        positions=raw.pop("positions"),
        **_grid_fields(raw),
        grid=grid,
        convention=convention,
        **raw,
    )


def dequantize(codes: Any, origin: Any, step: Any) -> np.ndarray:
    """Positions ``origin + codes * step`` of integer codes (float64, length).

    Parameters
    ----------
    codes
        ``(n, 3)`` integers of any integer dtype, e.g. :attr:`Quantized.codes`.
    origin
        ``(3,)`` position of code ``(0, 0, 0)`` (length), e.g. :attr:`Quantized.origin`.
    step
        ``(3,)`` or a scalar: length of one code unit per axis.

    Returns
    -------
    ndarray, shape (n, 3), float64

    Raises
    ------
    TypeError
        Non-integer codes.
    ValueError
        Bad shapes, non-finite ``origin`` or ``step``, or a result beyond the float64
        range.
    """
    array = np.asarray(codes)
    if array.dtype == bool or not np.issubdtype(array.dtype, np.integer):
        raise TypeError(f"codes must be integers, got dtype {array.dtype}")
    if array.ndim != 2 or array.shape[1] != 3:
        raise MeshbitsError(f"codes must have shape (n, 3), got {array.shape}")
    if array.dtype == np.uint64 and array.size and int(array.max()) > np.iinfo(np.int64).max:
        raise MeshbitsError("codes above 2**63 - 1 are not supported")
    vectors = []
    for name, value in (("origin", origin), ("step", step)):
        try:
            vector = np.broadcast_to(np.asarray(value, dtype=np.float64), (3,))
        except (TypeError, ValueError) as err:
            raise MeshbitsError(f"{name} must be a 3-vector of numbers: {err}") from err
        vectors.append(tuple(vector.tolist()))
    return _core.dequantize(np.ascontiguousarray(array, dtype=np.int64), vectors[0], vectors[1])


def cluster(
    mesh_or_vertices: MeshLike,
    faces: Any = None,
    *,
    bits: int,
    grid: str = "cube",
    box: Any = None,
    convention: str = "corner",
    duplicates: str = "keep",
) -> Clustered:
    """Rossignac-Borrel vertex clustering: merge vertices that share a grid code.

    The vertices are quantized as by :func:`quantize` (on the bounding box of *all*
    vertices unless ``box`` is given); vertices with equal codes become one vertex at
    the dequantised position of the code. Faces with two equal corners after merging
    are dropped as degenerate, then optionally repeated faces, then vertices that no
    kept face uses.

    Parameters
    ----------
    mesh_or_vertices
        A ``trimesh.Trimesh``, a ``(vertices, faces)`` pair, or ``(n, 3)`` float vertices.
    faces
        ``(m, 3)`` integer vertex indices when ``mesh_or_vertices`` is an array.
    bits
        ``B``, an integer from 1 to 32, keyword-only: ``cluster(mesh, bits=8)``,
        ``cluster(vertices, faces, bits=8)``.
    {grid_doc}
    duplicates
        ``"keep"`` (default): keep repeated faces. ``"oriented"``: drop a face whose
        corners are those of an earlier kept face in the same cyclic order (same
        triangle, same winding; the opposite winding is kept, so a collapsed two-sided
        sheet keeps both sides). ``"any"``: drop a face whose corner set equals an
        earlier kept face's, whatever the order or winding. The earliest face is kept.

    Returns
    -------
    Clustered

    Notes
    -----
    The output order does not depend on the thread count: vertices in order of the
    smallest input index of their cluster (if nothing merges and every vertex is used,
    the vertex order is unchanged), faces in input order.

    Raises
    ------
    ValueError
        Bad shapes, NaN or infinite coordinates, out-of-range indices, an empty mesh,
        ``bits`` outside 1..32, an unknown option, a bad box, or a vertex outside
        ``box`` (:class:`meshbits.MeshbitsError`).
    TypeError
        Non-numeric vertices, non-integer faces or ``bits``, ``bits`` missing.
    """
    if faces is not None and isinstance(faces, (numbers.Number, np.generic)):
        raise TypeError(
            f"cluster() got {faces!r} for faces; bits is keyword-only: cluster(mesh, bits=8)"
        )
    bits = _check_bits(bits)
    grid = _check_choice("grid", grid, GRIDS)
    convention = _check_choice("convention", convention, CONVENTIONS)
    duplicates = _check_choice("duplicates", duplicates, DUPLICATES)
    box_min, box_max = _as_box(box)
    # The kernel checks the indices and refuses NaN/infinite coordinates in its own
    # passes; a refused mesh is checked again here for a message naming the row.
    vertices, triangles = as_mesh(mesh_or_vertices, faces, keep_int64=True, check_finite=False)
    try:
        raw: dict[str, Any] = dict(
            _core.cluster(
                vertices,
                triangles,
                bits,
                grid,
                box_min,
                box_max,
                convention == "centered",
                duplicates,
            )
        )
    except _core.MeshbitsError:
        as_points(vertices, "vertices")
        raise
    out_vertices, out_faces = raw.pop("vertices"), raw.pop("faces")
    return Clustered(
        vertices=out_vertices,
        faces=out_faces,
        codes=raw.pop("codes"),
        vertex_map=raw.pop("vertex_map"),
        face_index=raw.pop("face_index"),
        input_vertices=len(vertices),
        input_faces=len(triangles),
        output_vertices=len(out_vertices),
        output_faces=len(out_faces),
        **_grid_fields(raw),
        grid=grid,
        convention=convention,
        duplicates=duplicates,
        **raw,
    )


quantize.__doc__ = (quantize.__doc__ or "").replace("{grid_doc}", _GRID_DOC)
cluster.__doc__ = (cluster.__doc__ or "").replace("{grid_doc}", _GRID_DOC)
