"""Sizes and lengths as people type them: ``"100KB"``, ``"2MiB"``, ``"1mm"``.

A size always carries its unit, spelled so bits and bytes cannot be confused; a length is
a plain number in the mesh's own units or carries a metric or imperial unit, converted to
meters (glTF's unit).
"""

from __future__ import annotations

import math
import os
import re
from pathlib import Path

from .errors import MeshbitsError

__all__ = ["LENGTH_UNITS", "length_unit_of", "parse_length", "parse_size"]

#: Length units, in meters (glTF's unit).
LENGTH_UNITS = {"mm": 1e-3, "cm": 1e-2, "dm": 0.1, "m": 1.0, "km": 1e3, "in": 0.0254, "ft": 0.3048}


def length_unit_of(path: str | os.PathLike[str]) -> str:
    """The unit of lengths read from ``path``: ``"m"`` for glTF (``.glb``/``.gltf``,
    whose unit is the meter), else ``"mesh units"`` (the file's own coordinates, which
    name no unit)."""
    return "m" if Path(path).suffix.lower() in (".glb", ".gltf") else "mesh units"


def in_unit(text: str, unit: str) -> str:
    """A message of the library, whose lengths are in "(mesh units)", in ``unit``: the
    unit a file's JSON report names (``length_unit_of``; meters for a glTF input)."""
    return text if unit == "mesh units" else text.replace("(mesh units)", f"({unit})")


def parse_length(text: str) -> float:
    """Parse a positive length: ``"0.002"`` (the mesh's own units) or ``"1mm"``,
    ``"0.5 cm"``, ``"2in"`` (converted to meters, glTF's unit: ``"1mm"`` = 0.001).

    Raises
    ------
    MeshbitsError
        If it is not a positive finite number with an optional known unit.
    """
    if not isinstance(text, str):
        raise TypeError(f"length must be a string such as '1mm', got {text!r}")
    stripped = text.strip()
    scale = 1.0
    for unit in sorted(LENGTH_UNITS, key=len, reverse=True):
        if stripped.lower().endswith(unit) and stripped[: -len(unit)].strip():
            stripped, scale = stripped[: -len(unit)].strip(), LENGTH_UNITS[unit]
            break
    try:
        value = float(stripped) * scale
    except ValueError:
        raise MeshbitsError(
            f"cannot read length {text!r}: expected a number, optionally with a unit "
            f"({', '.join(LENGTH_UNITS)})"
        ) from None
    if not (math.isfinite(value) and value > 0):
        raise MeshbitsError(f"length {text!r} must be positive and finite")
    return value


_SIZE = re.compile(r"^\s*(\d+(?:\.\d*)?|\.\d+)(?:[eE]([+-]?\d+))?\s*([A-Za-z]*)\s*$")
_PREFIXES = {
    "": 1.0,
    "k": 1e3,
    "m": 1e6,
    "g": 1e9,
    "t": 1e12,
    "ki": 2.0**10,
    "mi": 2.0**20,
    "gi": 2.0**30,
    "ti": 2.0**40,
}


def parse_size(text: str) -> float:
    """Parse a file size such as ``"100KB"``, ``"2MiB"`` or ``"80kbit"`` into bits.

    The unit is required and spelled so that bits and bytes cannot be confused:

    - bytes: ``B`` (upper case), ``byte`` or ``bytes``; 1 byte = 8 bits;
    - bits: ``bit`` or ``bits``;
    - a lone lower-case ``b`` (``"100kb"``) and a bare number (``"100"``) are refused.

    Decimal prefixes ``k``, ``M``, ``G``, ``T`` are powers of 1000 and binary prefixes
    ``Ki``, ``Mi``, ``Gi``, ``Ti`` powers of 1024; prefixes are case-insensitive (a size has
    no use for milli). Examples: ``"100KB"`` = 800,000 bits, ``"2MiB"`` = 16,777,216 bits,
    ``"1.5 kbit"`` = 1,500 bits.

    Returns
    -------
    float
        The size in bits (> 0).

    Raises
    ------
    ValueError
        On a missing, ambiguous or unknown unit, or a size that is not positive and finite.
    """
    if not isinstance(text, str):
        raise TypeError(f"size must be a string such as '100KB', got {text!r}")
    match = _SIZE.match(text)
    if match is None:
        raise MeshbitsError(
            f"cannot read size {text!r}: expected a number and a unit, such as 100KB, 2MiB "
            "or 80000bits"
        )
    mantissa, exponent, unit = match.groups()
    value = float(mantissa + (f"e{exponent}" if exponent else ""))
    lowered = unit.lower()
    for word, bits in (("bits", 1.0), ("bit", 1.0), ("bytes", 8.0), ("byte", 8.0)):
        if lowered.endswith(word):
            prefix, per_unit = lowered[: -len(word)], bits
            break
    else:
        if unit.endswith("B"):
            prefix, per_unit = lowered[:-1], 8.0
        elif unit.endswith("b"):
            raise MeshbitsError(
                f"size {text!r} is ambiguous: lower-case 'b' could mean bits or bytes; write "
                f"{mantissa}{unit[:-1]}B for bytes or {mantissa}{unit[:-1]}bit for bits"
            )
        else:
            raise MeshbitsError(
                f"size {text!r} needs a unit: B or bytes (8 bits), or bit/bits, with an "
                "optional prefix k, M, G, T (1000) or Ki, Mi, Gi, Ti (1024)"
            )
    if prefix not in _PREFIXES:
        raise MeshbitsError(
            f"size {text!r}: unknown prefix {unit[: len(prefix)]!r} (use k, M, G, T or Ki, Mi, "
            "Gi, Ti)"
        )
    size = value * _PREFIXES[prefix] * per_unit
    if not (math.isfinite(size) and size > 0):
        raise MeshbitsError(f"size {text!r} must be positive and finite")
    return size
