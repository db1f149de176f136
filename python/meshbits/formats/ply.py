"""PLY: the header check, what a PLY header declares against what the file holds.

The Rust reader (:mod:`.native`) reads uncompressed PLY files; trimesh parses those it
leaves aside (damaged, or gzip-compressed) and writes them. This check runs before
trimesh reads one: the counts of an ASCII header against the lines that follow,
the row layout of a binary header (lists as long as in each element's first row, as
trimesh reads them) against the file's size, and every list as long as the first.
"""

from __future__ import annotations

import re
from typing import Any

import numpy as np

from ..errors import MeshFileError
from .sniff import HEADER_LIMIT, count_of, header_text, plural

__all__ = ["check_header"]

# PLY property types, as trimesh reads them.
PLY_TYPES = {
    "char": "i1",
    "uchar": "u1",
    "short": "i2",
    "ushort": "u2",
    "int": "i4",
    "uint": "u4",
    "float": "f4",
    "double": "f8",
    "int8": "i1",
    "uint8": "u1",
    "int16": "i2",
    "uint16": "u2",
    "int32": "i4",
    "uint32": "u4",
    "int64": "i8",
    "uint64": "u8",
    "float16": "f2",
    "float32": "f4",
    "float64": "f8",
}
PLY_FORMATS = {"ascii": "", "binary_little_endian": "<", "binary_big_endian": ">"}


class _Element:
    def __init__(self, name: str, count: int) -> None:
        self.name, self.count = name, count
        self.properties: list[tuple[str, str, str | None]] = []  # (name, type, count type)


def check_header(buffer: Any, size: int) -> None:
    """Compare what a PLY file's header declares with what ``buffer`` (the whole file,
    ``size`` bytes) holds; raise :class:`MeshFileError` naming the first disagreement."""
    fmt, elements, start = _ply_header(bytes(buffer[: min(size, HEADER_LIMIT)]))
    if fmt == "ascii":
        _ascii_sizes(buffer, size, elements, start)
    else:
        _binary_sizes(buffer, size, fmt, elements, start)


def _ply_header(head: bytes) -> tuple[str, list[_Element], int]:
    """The format, the elements and the offset of the data of a PLY file."""
    match = re.search(rb"(?:^|[\r\n])end_header[ \t]*(?:\r\n|\r|\n)", head)
    if match is None:
        if re.search(rb"(?:^|[\r\n])end_header", head) and len(head) < HEADER_LIMIT:
            raise MeshFileError("the file ends right after the PLY header: no data")
        raise MeshFileError("the PLY header has no end_header line: truncated or not a PLY file")
    lines = header_text(head[: match.start()], "PLY header").splitlines()
    if not lines or lines[0].strip() != "ply":
        raise MeshFileError("the file does not start with 'ply': not a PLY file")
    fmt, elements = None, []
    for number, raw in enumerate(lines[1:], start=2):
        words = raw.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        where = f"PLY header line {number}"
        if words[0] == "format":
            if len(words) < 2 or words[1] not in PLY_FORMATS:
                shown = words[1] if len(words) > 1 else ""
                raise MeshFileError(
                    f"{where}: unknown format {shown!r} (ascii, binary_little_endian or "
                    "binary_big_endian)"
                )
            fmt = words[1]
        elif words[0] == "element":
            if len(words) != 3:
                raise MeshFileError(f"{where}: expected 'element <name> <count>', got {raw!r}")
            elements.append(
                _Element(words[1], count_of(words[2], f"{where}: the count of {words[1]}"))
            )
        elif words[0] == "property":
            if not elements:
                raise MeshFileError(f"{where}: a property before any element")
            elements[-1].properties.append(_property(words, raw, where))
    if fmt is None:
        raise MeshFileError("the PLY header has no format line")
    vertex = next((e for e in elements if e.name == "vertex"), None)
    if vertex is not None and vertex.count:
        names = [p[0] for p in vertex.properties]
        for axis in "xyz":
            if axis not in names:
                raise MeshFileError(f"the PLY vertex element has no property {axis!r}")
    return fmt, elements, match.end()


def _property(words: list[str], raw: str, where: str) -> tuple[str, str, str | None]:
    """A ``property`` line as ``(name, type, count type or None)``."""
    if len(words) == 3 and words[1] in PLY_TYPES:
        return (words[2], PLY_TYPES[words[1]], None)
    if len(words) == 5 and words[1] == "list":
        count_type, item_type = PLY_TYPES.get(words[2]), PLY_TYPES.get(words[3])
        if count_type is None or count_type[0] not in "iu":
            raise MeshFileError(
                f"{where}: the length of list {words[4]!r} has type {words[2]!r}, "
                "not an integer type"
            )
        if item_type is None:
            raise MeshFileError(f"{where}: unknown property type {words[3]!r}")
        return (words[4], item_type, count_type)
    unknown = words[1] if len(words) > 1 else ""
    raise MeshFileError(
        f"{where}: expected 'property <type> <name>' or 'property list <count "
        f"type> <type> <name>' with a known type, got {raw!r}"
        + (f" (unknown type {unknown!r})" if len(words) == 3 else "")
    )


def _declared(elements: list[_Element]) -> str:
    return ", ".join(plural(e.count, e.name) for e in elements) or "no elements"


def _ascii_sizes(buffer: Any, size: int, elements: list[_Element], start: int) -> None:
    """Compare the rows an ASCII header declares with the lines that follow it."""
    declared = _declared(elements)
    available = size - start
    rows = sum(e.count for e in elements)
    # A row takes at least two bytes ("0" and a line break): a test without reading.
    if rows > available // 2 + 1:
        raise MeshFileError(
            f"the PLY header declares {declared} ({plural(rows, 'line')} of data) but "
            f"only {plural(available, 'byte')} follow it: truncated or damaged"
        )
    lines = 0
    for at in range(start, size, 1 << 24):
        chunk = bytes(buffer[at : min(size, at + (1 << 24))])
        lines += max(chunk.count(b"\n"), chunk.count(b"\r"))
    if available and bytes(buffer[size - 1 : size]) not in (b"\n", b"\r"):
        lines += 1
    if lines < rows:
        raise MeshFileError(
            f"the PLY header declares {declared} ({plural(rows, 'line')} of data) but "
            f"{plural(lines, 'line')} follow it: truncated or damaged"
        )


def _binary_sizes(buffer: Any, size: int, fmt: str, elements: list[_Element], start: int) -> None:
    """Compare the binary data a header declares with the data the file holds."""
    declared = _declared(elements)
    order = PLY_FORMATS[fmt]
    offset = start
    layouts = []
    for element in elements:
        fields, row = _row_layout(buffer, size, order, element, offset, declared)
        layouts.append((element, offset, fields))
        offset += element.count * row
        if offset > size:
            break
    if offset != size:
        expected = offset - start
        size_text = f"{expected:,} bytes" if offset <= size else f"at least {expected:,} bytes"
        raise MeshFileError(
            f"the PLY header declares {declared}: {size_text} of binary data (lists as long "
            f"as the first one), but {size - start:,} bytes follow it: "
            + ("truncated or damaged" if offset > size else "damaged")
            + " (mixed polygon sizes are read from an uncompressed file only)"
        )
    for element, at, fields in layouts:
        _check_list_lengths(buffer, element, at, fields)


def _row_layout(
    buffer: Any, size: int, order: str, element: _Element, offset: int, declared: str
) -> tuple[list[tuple[str, Any]], int]:
    """An element's row layout, lists as long as in its first row (as trimesh reads
    them), and the row's length in bytes."""
    fields: list[tuple[str, Any]] = []
    row = 0
    for number, (name, item, count_type) in enumerate(element.properties):
        width = np.dtype(item).itemsize
        if count_type is None:
            fields.append((f"p{number}", order + item))
            row += width
            continue
        count_dtype = np.dtype(order + count_type)
        length = 0
        if element.count:
            at = offset + row
            if at + count_dtype.itemsize > size:
                raise MeshFileError(
                    f"the PLY header declares {declared}, but the binary data ends "
                    f"before the first {element.name}: truncated"
                )
            length = int(np.frombuffer(buffer, count_dtype, 1, at)[0])
            if length < 0:
                raise MeshFileError(
                    f"the first {element.name}'s list {name!r} has length {length}: damaged"
                )
        fields.append((f"n{number}", count_dtype))
        fields.append((f"p{number}", (order + item, (length,))))
        row += count_dtype.itemsize + length * width
    return fields, row


def _check_list_lengths(
    buffer: Any, element: _Element, at: int, fields: list[tuple[str, Any]]
) -> None:
    """Refuse an element whose lists are not all as long as in its first row."""
    lists = [key for key, _ in fields if key.startswith("n")]
    if element.count > 1 and lists:
        rows = np.frombuffer(buffer, np.dtype(fields), element.count, at)
        for key in lists:
            lengths = rows[key]
            bad = np.flatnonzero(lengths != lengths[0])
            if len(bad):
                raise MeshFileError(
                    f"{element.name} {int(bad[0])} has a list of {int(lengths[bad[0]])} "
                    f"items where {element.name} 0 has {int(lengths[0])}: the binary PLY "
                    "is damaged (mixed polygon sizes are read from an uncompressed file only)"
                )
