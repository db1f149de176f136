"""A budget: the one constraint a compression meets, checked once.

A budget is one of

- ``"error"``: the largest symmetric Hausdorff distance allowed between the input and its
  output, a length in the mesh's units; with ``relative`` a fraction of the grid size S
  (the largest side of the bounding box), resolved against S by :meth:`Budget.resolve`;
- ``"size"``: the file size allowed, in **bits** (``parse_size("20KB")`` is 160,000);
- ``"vertices"``: the vertex count V the output keeps.

:meth:`Budget.from_options` turns the keyword arguments of the entry points (``compress``,
``compress_scene``, ``batch``, ``meshbits plan`` and the command line) into one value,
refusing what is not exactly one positive finite budget in the words every entry point
shares.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from typing import Any

from .errors import MeshbitsError
from .units import parse_length, parse_size

__all__ = ["BUDGET_KINDS", "Budget"]

#: The kinds of budget, in the order the messages name them.
BUDGET_KINDS = ("size", "error", "vertices")

#: How the API takes each kind of budget, told when it is given something else.
_API_UNITS = {
    "size": "bits (8 * 20_000 for 20 kB; meshbits.parse_size('20KB') converts)",
    "error": "a length in the mesh's units (meshbits.parse_length('1mm') converts to meters)",
    "vertices": "a vertex count",
}


@dataclass(frozen=True)
class Budget:
    """One budget, checked: ``value`` is positive and finite.

    Attributes
    ----------
    kind : str
        ``"error"``, ``"size"`` or ``"vertices"``.
    value : float
        As given: a length (mesh units, or meters when typed with a unit), a fraction of
        S when ``relative``, bits for a size, a count for vertices.
    relative : bool
        ``value`` is a fraction of S (an error budget only; False for the other kinds).
    unit : str
        The unit of the resolved value: ``"bits"``, ``"vertices"``, or for an error the
        length unit of the file it applies to (``"mesh units"``, ``"m"`` for glTF).
    text : str
        The budget as the caller gave it, for messages and reports (``"--size 20KB"`` on
        the command line); :meth:`describe` when not given.
    """

    kind: str
    value: float
    relative: bool = False
    unit: str = "mesh units"
    text: str = ""

    @classmethod
    def from_options(
        cls,
        *,
        error: Any = None,
        size: Any = None,
        vertices: Any = None,
        relative: bool = False,
        kinds: tuple[str, ...] = BUDGET_KINDS,
        length_unit: str = "mesh units",
        text: str | None = None,
        parse_text: bool = False,
        refuse_stray_relative: bool = False,
    ) -> Budget:
        """The one budget among ``error``, ``size`` and ``vertices`` (the others None).

        Parameters
        ----------
        kinds
            The kinds this entry point takes, in the order its message names them.
        length_unit
            The length unit of the file an error budget applies to (``unit``).
        text
            The budget as the caller typed it; default :meth:`describe`.
        parse_text
            Also take text with a unit: an error like ``"5cm"`` (read by
            :func:`meshbits.parse_length`, in meters), a size like ``"100KB"``.
        refuse_stray_relative
            Refuse ``relative`` with a size budget (else it is ignored, as ``compress``
            always did).

        Raises
        ------
        MeshbitsError
            Not exactly one budget of ``kinds``; ``relative`` with a unit (or, with
            ``refuse_stray_relative``, without an error budget); a budget that is not a
            positive finite number.
        TypeError
            A budget that is not a real number (text without ``parse_text``).
        """
        options = {"size": size, "error": error, "vertices": vertices}
        given = [kind for kind in kinds if options[kind] is not None]
        if len(given) != 1:
            raise MeshbitsError(f"give exactly one of {', '.join(kinds)} (got {given or 'none'})")
        kind, raw = given[0], options[given[0]]
        if refuse_stray_relative and relative and kind != "error":
            raise MeshbitsError("relative applies to an error budget only")
        if parse_text and isinstance(raw, str):
            raw = _parsed(kind, raw, relative)
        value = _real(kind, raw)
        if not (math.isfinite(value) and value > 0):
            raise MeshbitsError(f"the {kind} budget must be a positive finite number, got {raw}")
        unit = {"size": "bits", "vertices": "vertices"}.get(kind, length_unit)
        budget = cls(kind, value, bool(relative) and kind == "error", unit)
        return budget.with_text(budget.describe() if text is None else text)

    def with_text(self, text: str) -> Budget:
        """This budget, reported as ``text``."""
        return Budget(self.kind, self.value, self.relative, self.unit, text)

    def resolve(self, grid_size: float) -> float:
        """The absolute budget: ``value * grid_size`` for a relative error budget (S, in
        the mesh's units), else ``value`` (mesh units, bits or vertices)."""
        return self.value * grid_size if self.relative else self.value

    def describe(self) -> str:
        """The budget in words: ``"0.01 x S"``, ``"0.002"`` (an error in the mesh's
        units), ``"20000 bytes"``, ``"500 vertices"``."""
        if self.kind == "error":
            return f"{self.value:g} x S" if self.relative else f"{self.value:g}"
        if self.kind == "size":
            return f"{self.value / 8:g} bytes"
        return f"{self.value:g} vertices"

    def options(self) -> dict[str, Any]:
        """The keyword arguments of ``compress`` and ``compress_scene`` that give it."""
        return {self.kind: self.value, "relative": self.relative}

    def to_dict(self) -> dict[str, Any]:
        """The keys a JSON report states it with: ``budget_text``, ``budget_unit``."""
        return {"budget_text": self.text, "budget_unit": self.unit}


def _parsed(kind: str, text: str, relative: bool) -> float:
    """A budget typed with its unit: a length (``"5cm"``) or a size (``"100KB"``)."""
    if kind == "error":
        if relative and text.strip()[-1:].isalpha():
            raise MeshbitsError(
                f"error {text!r} has a unit, and relative makes it a fraction of S: give a "
                "plain number with relative, or drop relative"
            )
        return parse_length(text)
    if kind == "size":
        return parse_size(text)
    return _real(kind, text)


def _real(kind: str, value: Any) -> float:
    """A budget given to the API as a float (an int beyond the float range is infinite,
    and refused by the range check).

    Raises
    ------
    TypeError
        If it is not a real number; text like ``"20KB"`` is told how the API takes it.
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(
            f"the {kind} budget must be a real number, got {value!r}: the API takes "
            f"{_API_UNITS[kind]}"
        )
    try:
        return float(value)
    except OverflowError:
        return math.inf
