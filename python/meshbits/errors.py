"""The exceptions meshbits raises on input it refuses.

Every refusal of the caller's data or arguments (a NaN coordinate, an index out of range,
bits out of range, an unreadable file, a budget that is not a positive number) is a
:class:`MeshbitsError`, a ``ValueError``; ``TypeError`` means an argument of the wrong
type. Anything else escaping meshbits is a bug: the ``meshbits`` program reports it as an
internal error (exit code 3).
"""

from __future__ import annotations

from ._core import MeshbitsError

__all__ = ["MeshFileError", "MeshbitsError"]


class MeshFileError(MeshbitsError):
    """A file that cannot be read as a triangle mesh: unparsable, truncated, or holding no
    usable triangles (NaN coordinates, indices out of range, no faces)."""
