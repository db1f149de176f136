"""What the public result dataclasses share: value equality over array fields, and a
JSON-ready ``to_dict``.

A dataclass's generated ``__eq__`` compares fields as tuples, which raises on numpy arrays
("the truth value of an array is ambiguous"); results that hold arrays derive from
:class:`ArrayResult` instead and are declared with ``eq=False``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from pathlib import PurePath
from typing import Any, ClassVar

import numpy as np

__all__ = ["SAMPLED_ONLY", "ArrayResult", "Progress", "ProgressCallback", "json_ready"]

#: Appended to the message of an error budget met without certification: a sampled
#: distance is a lower bound on the error, so the true error may still exceed the budget.
SAMPLED_ONLY = (
    " (not certified: by its sampled distance, a lower bound, so the true error may "
    "exceed the budget)"
)


def _equal(a: Any, b: Any) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        if not (isinstance(a, np.ndarray) and isinstance(b, np.ndarray)):
            return False
        if a.shape != b.shape:
            return False
        floating = a.dtype.kind in "fc" and b.dtype.kind in "fc"
        return bool(np.array_equal(a, b, equal_nan=floating))
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_equal(x, y) for x, y in zip(a, b, strict=True))
    return bool(a == b)


def json_ready(value: Any) -> Any:
    """``value`` with numpy arrays and scalars as Python lists and numbers, paths as
    strings, and every float that is not finite (NaN, an infinite radius) as None: strict
    JSON has no NaN or Infinity."""
    if isinstance(value, PurePath):
        return str(value)
    if isinstance(value, np.ndarray):
        if value.dtype.kind in "fc" and not np.isfinite(value).all():
            return np.where(np.isfinite(value), value, None).tolist()
        return value.tolist()
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, (list, tuple)):
        return [json_ready(v) for v in value]
    if isinstance(value, dict):
        return {str(k): json_ready(v) for k, v in value.items()}
    return value


class ArrayResult:
    """Mixin for frozen dataclasses (declared ``eq=False``) that hold numpy arrays.

    Two results are equal when they are of the same type and every field is equal, arrays
    compared by shape and values (NaN equal to NaN). Such results are not hashable.
    ``to_dict`` returns every field but the per-element arrays named in
    :attr:`_arrays`, which it adds as nested lists with ``arrays=True``.
    """

    #: Fields holding one row per point, vertex, face or edge: left out of ``to_dict``
    #: unless ``arrays=True``.
    _arrays: ClassVar[tuple[str, ...]] = ()

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return all(
            _equal(getattr(self, f.name), getattr(other, f.name))
            for f in dataclasses.fields(self)  # type: ignore[arg-type]
        )

    __hash__ = None  # type: ignore[assignment]

    def to_dict(self, *, arrays: bool = False) -> dict[str, Any]:
        """JSON-ready dict of the fields (with ``arrays=True``, also the per-element
        arrays, as nested lists)."""
        out = {}
        for f in dataclasses.fields(self):  # type: ignore[arg-type]
            value = getattr(self, f.name)
            if f.name in self._arrays and not arrays:
                continue
            if isinstance(value, ArrayResult):
                value = value.to_dict(arrays=arrays)
            out[f.name] = json_ready(value)
        return out


@dataclasses.dataclass(frozen=True)
class Progress:
    """One progress report of a long call (``hausdorff``, ``compress``,
    ``compress_scene``): every ``progress=`` callback receives these.

    Attributes
    ----------
    source : str
        The call that reports: ``"hausdorff"``, ``"compress"`` or ``"compress_scene"``.
    message : str
        One line for a person, numbers with their units; also ``str(event)``.
    detail : object or None
        The structured record when there is one: ``compress`` passes each pass's
        :class:`meshbits.Iteration`.
    """

    source: str
    message: str
    detail: Any = None

    def __str__(self) -> str:
        return self.message

    def to_dict(self) -> dict[str, Any]:
        detail = self.detail.to_dict() if hasattr(self.detail, "to_dict") else self.detail
        return json_ready({"source": self.source, "message": self.message, "detail": detail})


#: What ``progress=`` takes everywhere.
ProgressCallback = Callable[[Progress], None]
