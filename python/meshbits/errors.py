"""The exceptions meshbits raises on input it refuses.

Every refusal of the caller's data or arguments (a NaN coordinate, an index out of range,
bits out of range, an unreadable file, a budget that is not a positive number) is a
:class:`MeshbitsError`, a ``ValueError``; ``TypeError`` means an argument of the wrong
type. Anything else escaping meshbits is a bug: the ``meshbits`` program reports it as an
internal error (exit code 3).

The native kernels raise one subclass per kind of refusal: :class:`ShapeError` (an array's
shape, dtype or layout), :class:`NonFiniteError` (a NaN or infinite coordinate),
:class:`IndexOutOfRangeError` (a face index), :class:`EmptyMeshError` (no vertices or no
faces), :class:`ParameterError` (a parameter out of range) and :class:`OutsideBoxError` (a
point outside a quantization box). :class:`UnreachableBudgetError` is a budget no output
can meet.
"""

from __future__ import annotations

from ._core import (
    EmptyMeshError,
    IndexOutOfRangeError,
    MeshbitsError,
    NonFiniteError,
    OutsideBoxError,
    ParameterError,
    ShapeError,
)

__all__ = [
    "EmptyMeshError",
    "IndexOutOfRangeError",
    "MeshFileError",
    "MeshbitsError",
    "NonFiniteError",
    "OutsideBoxError",
    "ParameterError",
    "ShapeError",
    "UnreachableBudgetError",
]


class MeshFileError(MeshbitsError):
    """A file that cannot be read as a triangle mesh: unparsable, truncated, or holding no
    usable triangles (NaN coordinates, indices out of range, no faces)."""


class UnreachableBudgetError(MeshbitsError):
    """A budget no output can meet, known before any is made: a size below the bytes an
    output keeps whatever its geometry (images, JSON). Nothing is written; the
    ``meshbits`` program exits 1 (a budget not met), not 2 (refused input)."""


def one_line(err: BaseException) -> str:
    """An exception's message on one line (its whitespace collapsed), or its class name."""
    return " ".join(str(err).split()) or type(err).__name__
