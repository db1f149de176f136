"""Plans for fixed-width outputs: ``B`` and ``V`` when positions cost the same at every ``B``.

glb positions without a codec and PLY store each coordinate in a fixed-width field (see
:func:`meshbits.codecs.fixed_width_size_bits`): up to the format's most bits
(:data:`meshbits.constants.FORMAT_MAX_BITS`) every ``B`` takes the same bytes, so the best
plan stores that most and spends the budget on the vertex count ``V``. The error of a plan
is the paper's ``E = E_Q(B) + E_T(V)`` (Eq. 2 and 10, :mod:`meshbits.model`); its size is
``header + V * vertex_bytes + F * face_bytes``, with ``F = V * faces_per_vertex`` (the
input's faces per welded vertex).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

from . import model
from .budget import Budget
from .codecs import fixed_width_size_bits
from .constants import FORMAT_MAX_BITS, MODEL_MIN_VERTICES
from .errors import MeshbitsError

__all__ = ["FIXED_WIDTH_FORMATS", "FixedWidthPlan", "FixedWidthSizes", "plan_fixed_width"]

#: The outputs whose positions are stored in fixed-width fields.
FIXED_WIDTH_FORMATS = ("glb", "ply")
#: Halvings of the bracket of ``V`` when solving for a size: from [4, budget bits] far
#: below one vertex's width.
_BISECTION_STEPS = 200


@dataclass(frozen=True)
class FixedWidthSizes:
    """The size model of a fixed-width ``format`` at its most bits, for a mesh with
    ``faces_per_vertex`` triangles per vertex."""

    format: str
    faces_per_vertex: float

    @property
    def bits(self) -> int:
        """Bits per coordinate: the format's most (any fewer cost the same)."""
        return FORMAT_MAX_BITS[self.format]

    def size_bits(self, vertices: float) -> float:
        """The file size (bits) at ``vertices`` vertices; increasing in ``vertices``."""
        return fixed_width_size_bits(
            self.format, self.bits, vertices, vertices * self.faces_per_vertex
        )

    def vertices_for_size(self, size_bits: float) -> float:
        """The most vertices whose file fits in ``size_bits`` (bisection: ``size_bits``
        must hold a tetrahedron, :data:`MODEL_MIN_VERTICES` vertices)."""
        if size_bits < self.size_bits(MODEL_MIN_VERTICES):
            raise MeshbitsError(
                f"a size of {size_bits / 8:,.0f} bytes cannot hold a tetrahedron in "
                f"{self.format}: the smallest is {self.size_bits(MODEL_MIN_VERTICES) / 8:,.0f} "
                "bytes"
            )
        # int 4 while no middle fits: reported as the old solver did
        low: float = MODEL_MIN_VERTICES
        high = size_bits
        for _ in range(_BISECTION_STEPS):
            middle = 0.5 * (low + high)
            low, high = (middle, high) if self.size_bits(middle) <= size_bits else (low, middle)
        return low


@dataclass(frozen=True)
class FixedWidthPlan:
    """The plan of a fixed-width output for one budget.

    Attributes
    ----------
    format : str
        ``"glb"`` or ``"ply"``.
    constraint : str
        The budget's kind: ``"size"``, ``"error"`` or ``"vertices"``.
    budget : float
        The budget resolved: bits, a length (mesh units) or a vertex count.
    bits : int
        ``B``, the format's most.
    vertices : float
        ``V`` (continuous).
    file_size : float
        The size at ``V`` (bits).
    quantization_error, tessellation_error, error : float
        ``E_Q(B)``, ``E_T(V)`` and their sum (mesh units).
    k, grid_size : float
        The mesh's shape complexity K and grid size S.
    """

    format: str
    constraint: str
    budget: float
    bits: int
    vertices: float
    file_size: float
    quantization_error: float
    tessellation_error: float
    error: float
    k: float
    grid_size: float

    def to_dict(self) -> dict[str, Any]:
        """The fields as a dict."""
        return asdict(self)


def plan_fixed_width(
    budget: Budget, k: float, grid_size: float, format: str, faces_per_vertex: float
) -> FixedWidthPlan:
    """The plan of a fixed-width ``format`` (``"glb"`` or ``"ply"``) for ``budget``: ``B``
    is the format's most, and ``V`` the most vertices within a size, the fewest within an
    error (``E_T(V) = budget - E_Q(B)``), or the count given.

    Raises
    ------
    MeshbitsError
        A size that cannot hold a tetrahedron; an error not above the format's
        quantization error or not below the grid size S.
    """
    if format not in FIXED_WIDTH_FORMATS:
        raise MeshbitsError(f"format must be one of {FIXED_WIDTH_FORMATS}, got {format!r}")
    sizes = FixedWidthSizes(format, faces_per_vertex)
    quantization = float(model.quantization_error(sizes.bits, grid_size))
    value = budget.resolve(grid_size)
    if budget.kind == "size":
        vertices = sizes.vertices_for_size(value)
    elif budget.kind == "error":
        if value <= quantization:
            raise MeshbitsError(
                f"an error of {value:g} is not above {format}'s quantization error at "
                f"{sizes.bits} bits, {quantization:.4g} (mesh units)"
            )
        if value >= grid_size:
            raise MeshbitsError(f"an error of {value:g} is not below the grid size S")
        vertices = float(model.vertices_for_error(value - quantization, k, grid_size))
    else:
        vertices = float(value)
    tessellation = float(model.tessellation_error(vertices, k, grid_size))
    return FixedWidthPlan(
        format=format,
        constraint=budget.kind,
        budget=float(value),
        bits=sizes.bits,
        vertices=vertices,
        file_size=sizes.size_bits(vertices),
        quantization_error=quantization,
        tessellation_error=tessellation,
        error=quantization + tessellation,
        k=k,
        grid_size=grid_size,
    )
