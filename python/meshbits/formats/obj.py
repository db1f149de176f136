"""OBJ and OFF, the text formats: the OFF header check, a writer that keeps every digit,
and an OBJ's material libraries.

trimesh parses both. An OFF header's counts are checked against the lines that follow
(:func:`check_off_header`); both are written by :func:`text_mesh` with 17 significant
digits, which read back exactly; an OBJ whose material library is missing is said so
(:func:`missing_material_libraries`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ..errors import MeshFileError
from .sniff import count_of, plural

__all__ = ["check_off_header", "missing_material_libraries", "text_mesh"]


def check_off_header(buffer: Any, size: int) -> None:
    """Compare the vertex and face counts an OFF file declares with the lines that follow
    them in ``buffer`` (the whole file, ``size`` bytes)."""
    text = bytes(buffer[:size]).decode("utf-8", "replace")
    lines = [line.split("#")[0].split() for line in text.splitlines()]
    lines = [words for words in lines if words]
    if not lines or not lines[0][0].upper().endswith("OFF"):
        raise MeshFileError("the file does not start with 'OFF': not an OFF file")
    counts, rest = lines[0][1:], lines[1:]
    if not counts and rest:
        counts, rest = rest[0], rest[1:]
    if len(counts) < 2:
        raise MeshFileError("the OFF file has no line with its vertex and face counts")
    vertices = count_of(counts[0], "the OFF vertex count")
    faces = count_of(counts[1], "the OFF face count")
    if len(rest) < vertices + faces:
        raise MeshFileError(
            f"the OFF header declares {plural(vertices, 'vertex')} and "
            f"{plural(faces, 'face')}, but {plural(len(rest), 'line')} follow: truncated "
            "or damaged"
        )


def text_mesh(suffix: str, vertices: np.ndarray, faces: np.ndarray) -> bytes:
    """An OBJ or OFF (``suffix`` ``"obj"`` or ``"off"``) whose coordinates read back
    exactly: each written with 17 significant digits (trimesh writes a fixed 8 decimals,
    which rounds a small mesh away)."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if suffix == "obj":
        head, v_fmt, f_rows = "", "v %.17g %.17g %.17g", f + 1
        f_fmt = "f %d %d %d"
    else:
        head, v_fmt, f_rows = f"OFF\n{len(v)} {len(f)} 0\n", "%.17g %.17g %.17g", f
        f_fmt = "3 %d %d %d"
    lines = [v_fmt % tuple(row) for row in v.tolist()]
    lines += [f_fmt % tuple(row) for row in f_rows.tolist()]
    return (head + "\n".join(lines) + "\n").encode()


def missing_material_libraries(path: Path) -> list[str]:
    """The ``mtllib`` files an OBJ names that are not beside it (trimesh then invents a
    material, with a placeholder image for one with UVs)."""
    if not path.suffix.lower() == ".obj":
        return []
    missing = []
    with path.open("rb") as lines:
        for line in lines:
            if line.startswith(b"mtllib"):
                for name in line[6:].decode("utf-8", "replace").split():
                    if not (path.parent / name).is_file():
                        missing.append(name)
    return missing
