"""Checks of a mesh file's own structure before trimesh parses it, and plain words for the
parser's failures.

trimesh reads a header's counts and trusts them: an ASCII PLY or an OFF file declaring
10**12 faces but holding four is read as four faces, a binary STL whose triangle count
disagrees with its length is re-read as text. Each check here compares what a header
declares with what the file holds, from the header and the file's size (and, for a
binary PLY, the list lengths), without allocating anything the size of a declared count,
and names the disagreement.
"""

from __future__ import annotations

import json
import re
from typing import Any

import numpy as np

from .errors import MeshFileError
from .gltf import unread_required_extensions

__all__ = ["check_structure", "explain"]

#: Longest PLY or OFF header read (bytes); real headers are a few hundred bytes.
HEADER_LIMIT = 1 << 20

# PLY property types, as trimesh reads them.
_PLY_TYPES = {
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
_PLY_FORMATS = {"ascii": "", "binary_little_endian": "<", "binary_big_endian": ">"}

_WHOLE = re.compile(r"\+?[0-9]+")


_PLURALS = {"vertex": "vertices"}


def _plural(count: int, word: str) -> str:
    return f"{count:,} " + (word if count == 1 else _PLURALS.get(word, word + "s"))


def _text(head: bytes, what: str) -> str:
    try:
        return head.decode("utf-8")
    except UnicodeDecodeError as err:
        raise MeshFileError(
            f"the {what} holds a byte that is not text (0x{head[err.start]:02x} at offset "
            f"{err.start}): the file is damaged"
        ) from None


def _count(text: str, what: str) -> int:
    if not _WHOLE.fullmatch(text):
        raise MeshFileError(f"{what} is {text!r}, not a whole number >= 0")
    return int(text)


class _Element:
    def __init__(self, name: str, count: int) -> None:
        self.name, self.count = name, count
        self.properties: list[tuple[str, str, str | None]] = []  # (name, type, count type)


def _ply_header(head: bytes) -> tuple[str, list[_Element], int]:
    """The format, the elements and the offset of the data of a PLY file."""
    match = re.search(rb"(?:^|[\r\n])end_header[ \t]*(?:\r\n|\r|\n)", head)
    if match is None:
        if re.search(rb"(?:^|[\r\n])end_header", head) and len(head) < HEADER_LIMIT:
            raise MeshFileError("the file ends right after the PLY header: no data")
        raise MeshFileError("the PLY header has no end_header line: truncated or not a PLY file")
    lines = _text(head[: match.start()], "PLY header").splitlines()
    if not lines or lines[0].strip() != "ply":
        raise MeshFileError("the file does not start with 'ply': not a PLY file")
    fmt, elements = None, []
    for number, raw in enumerate(lines[1:], start=2):
        words = raw.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        where = f"PLY header line {number}"
        if words[0] == "format":
            if len(words) < 2 or words[1] not in _PLY_FORMATS:
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
                _Element(words[1], _count(words[2], f"{where}: the count of {words[1]}"))
            )
        elif words[0] == "property":
            if not elements:
                raise MeshFileError(f"{where}: a property before any element")
            element = elements[-1]
            if len(words) == 3 and words[1] in _PLY_TYPES:
                element.properties.append((words[2], _PLY_TYPES[words[1]], None))
            elif len(words) == 5 and words[1] == "list":
                count_type, item_type = _PLY_TYPES.get(words[2]), _PLY_TYPES.get(words[3])
                if count_type is None or count_type[0] not in "iu":
                    raise MeshFileError(
                        f"{where}: the length of list {words[4]!r} has type {words[2]!r}, "
                        "not an integer type"
                    )
                if item_type is None:
                    raise MeshFileError(f"{where}: unknown property type {words[3]!r}")
                element.properties.append((words[4], item_type, count_type))
            else:
                unknown = words[1] if len(words) > 1 else ""
                raise MeshFileError(
                    f"{where}: expected 'property <type> <name>' or 'property list <count "
                    f"type> <type> <name>' with a known type, got {raw!r}"
                    + (f" (unknown type {unknown!r})" if len(words) == 3 else "")
                )
    if fmt is None:
        raise MeshFileError("the PLY header has no format line")
    vertex = next((e for e in elements if e.name == "vertex"), None)
    if vertex is not None and vertex.count:
        names = [p[0] for p in vertex.properties]
        for axis in "xyz":
            if axis not in names:
                raise MeshFileError(f"the PLY vertex element has no property {axis!r}")
    return fmt, elements, match.end()


def _ply_sizes(buffer: Any, size: int, fmt: str, elements: list[_Element], start: int) -> None:
    """Compare the data the header declares with the data the file holds."""
    declared = ", ".join(_plural(e.count, e.name) for e in elements) or "no elements"
    available = size - start
    if fmt == "ascii":
        rows = sum(e.count for e in elements)
        # A row takes at least two bytes ("0" and a line break): a test without reading.
        if rows > available // 2 + 1:
            raise MeshFileError(
                f"the PLY header declares {declared} ({_plural(rows, 'line')} of data) but "
                f"only {_plural(available, 'byte')} follow it: truncated or damaged"
            )
        lines = 0
        for at in range(start, size, 1 << 24):
            chunk = bytes(buffer[at : min(size, at + (1 << 24))])
            lines += max(chunk.count(b"\n"), chunk.count(b"\r"))
        if available and bytes(buffer[size - 1 : size]) not in (b"\n", b"\r"):
            lines += 1
        if lines < rows:
            raise MeshFileError(
                f"the PLY header declares {declared} ({_plural(rows, 'line')} of data) but "
                f"{_plural(lines, 'line')} follow it: truncated or damaged"
            )
        return
    order = _PLY_FORMATS[fmt]
    offset = start
    layouts = []
    for element in elements:
        # Row layout, lists as long as in the element's first row (as trimesh reads them).
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
        layouts.append((element, offset, fields))
        offset += element.count * row
        if offset > size:
            break
    if offset != size:
        expected = offset - start
        size_text = f"{expected:,} bytes" if offset <= size else f"at least {expected:,} bytes"
        raise MeshFileError(
            f"the PLY header declares {declared}: {size_text} of binary data (lists as long "
            f"as the first one), but {available:,} bytes follow it: "
            + ("truncated or damaged" if offset > size else "damaged")
            + ", or the polygons have different numbers of corners (a binary PLY must use "
            "one polygon size to be read)"
        )
    for element, at, fields in layouts:
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
                        "is damaged, or mixes polygon sizes, which cannot be read"
                    )


def _off(buffer: Any, size: int) -> None:
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
    vertices = _count(counts[0], "the OFF vertex count")
    faces = _count(counts[1], "the OFF face count")
    if len(rest) < vertices + faces:
        raise MeshFileError(
            f"the OFF header declares {_plural(vertices, 'vertex')} and "
            f"{_plural(faces, 'face')}, but {_plural(len(rest), 'line')} follow: truncated "
            "or damaged"
        )


def _stl(buffer: Any, size: int) -> None:
    head = bytes(buffer[: min(size, 84)])
    count = int(np.frombuffer(head, "<u4", 1, 80)[0]) if size >= 84 else None
    if count is not None and 84 + 50 * count == size:
        return  # binary, even when its header starts with "solid"
    sample = bytes(buffer[: min(size, 4096)])
    if sample.lstrip().startswith(b"solid") and b"\0" not in sample:
        return  # ASCII: trimesh parses it
    if count is None:
        raise MeshFileError(
            f"the file has {_plural(size, 'byte')}: too short for a binary STL (84-byte "
            "header) and not an ASCII STL (no 'solid')"
        )
    if _looks_like_text(sample):
        raise MeshFileError(
            f"the file is text but not an ASCII STL (it does not start with 'solid'), and "
            f"not a binary STL ({size:,} bytes, where its header would declare "
            f"{_plural(count, 'triangle')}): not an STL file"
        )
    raise MeshFileError(
        f"the binary STL declares {_plural(count, 'triangle')} ({84 + 50 * count:,} bytes) "
        f"but the file has {size:,} bytes: truncated or damaged"
    )


def _looks_like_text(sample: bytes) -> bool:
    """Printable ASCII or UTF-8 text with line breaks, no NUL (a binary STL's 80-byte
    header may be text, but its counts and floats are not)."""
    if b"\0" in sample:
        return False
    # A multi-byte character cut at the sample's end is dropped, not a reason to refuse.
    text = sample.decode("utf-8", errors="ignore")
    return bool(text) and all(c.isprintable() or c in "\r\n\t" for c in text)


def _glb(buffer: Any, size: int) -> None:
    head = bytes(buffer[: min(size, 20)])
    if size < 20 or head[:4] != b"glTF":
        raise MeshFileError(
            "the file does not start with a GLB header ('glTF' and 16 more bytes): "
            "not a binary glTF"
        )
    version, length = (int(x) for x in np.frombuffer(head, "<u4", 2, 4))
    if version != 2:
        raise MeshFileError(f"GLB version {version}: only version 2 is read")
    if length > size:
        raise MeshFileError(
            f"the GLB header declares {length:,} bytes but the file has {size:,}: truncated "
            "or damaged"
        )
    if head[16:20] != b"JSON":
        raise MeshFileError("the GLB's first chunk is not its JSON: damaged")
    (json_length,) = np.frombuffer(head, "<u4", 1, 12)
    try:
        document = json.loads(bytes(buffer[20 : 20 + min(int(json_length), size - 20)]))
    except (ValueError, UnicodeDecodeError):
        document = None  # the GLB reader says what is wrong with the JSON
    # Meshopt compression (EXT_ and KHR_meshopt_compression) and Draco are decoded, and
    # KHR_mesh_quantization read; any other required extension that changes how geometry
    # is stored cannot be read right.
    unread = unread_required_extensions(document)
    if unread:
        raise MeshFileError(
            f"the GLB requires the extension{'s' if len(unread) > 1 else ''} "
            f"{', '.join(unread)}, which meshbits does not read"
        )
    offset, number = 12, 0
    while offset + 8 <= min(length, size):
        (chunk,) = np.frombuffer(buffer, "<u4", 1, offset)
        if offset + 8 + int(chunk) > size:
            raise MeshFileError(
                f"GLB chunk {number} declares {int(chunk):,} bytes but {size - offset - 8:,} "
                "follow it: truncated or damaged"
            )
        offset += 8 + int(chunk)
        number += 1


def check_structure(file_type: str, buffer: Any, size: int) -> None:
    """Compare what the header of a ``file_type`` file declares with what ``buffer`` (the
    whole file, ``size`` bytes, anything numpy can read and slice) holds; raise
    :class:`MeshFileError` naming the first disagreement. Formats without a header to
    check pass."""
    if size == 0:
        raise MeshFileError("the file is empty")
    if file_type == "ply":
        fmt, elements, start = _ply_header(bytes(buffer[: min(size, HEADER_LIMIT)]))
        _ply_sizes(buffer, size, fmt, elements, start)
    elif file_type == "off":
        _off(buffer, size)
    elif file_type == "stl":
        _stl(buffer, size)
    elif file_type == "glb":
        _glb(buffer, size)


def explain(file_type: str, err: BaseException) -> str:
    """A parser's exception in words about the file (the parser's own words included)."""
    kind = file_type.upper() or "mesh"
    text = " ".join(str(err).split())
    tail = f": the file is damaged or is not a valid {kind} file"
    if isinstance(err, ModuleNotFoundError) and err.name == "charset_normalizer":
        if file_type in ("glb", "gltf"):
            return f"its JSON is not UTF-8 text{tail}"
        return (
            "it holds text that is not UTF-8; trimesh reads other encodings only with the "
            "charset-normalizer package installed (pip install charset-normalizer)"
        )
    if isinstance(err, ImportError):
        return f"trimesh needs another package to read {kind} files ({text})"
    if isinstance(err, NotImplementedError) and "not supported" in text:
        return f"trimesh, which meshbits reads files with, does not read {kind} files"
    if "could not be read to its end due to unmatched data" in text:
        return f"it holds text where numbers were expected{tail}"
    if isinstance(err, UnicodeDecodeError):
        return f"it holds a byte that is not text (0x{err.object[err.start]:02x}){tail}"
    match = re.fullmatch(r"invalid literal for int\(\) with base 10: (.*)", text)
    if match:
        return f"{match.group(1)} where a whole number was expected{tail}"
    match = re.fullmatch(r"could not convert string to float: (.*)", text)
    if match:
        return f"{match.group(1)} where a number was expected{tail}"
    match = re.fullmatch(r"index (-?\d+) is out of bounds for axis 0 with size (\d+)", text)
    if match:
        return (
            f"an index ({match.group(1)}, counted from 0) is beyond the {match.group(2)} items "
            f"the file defines (vertices, normals or texture coordinates){tail}"
        )
    match = re.fullmatch(r"cannot reshape array of size (\d+) into shape .*", text)
    if match:
        return f"it holds {match.group(1)} values where its counts need another number{tail}"
    return f"the {kind} reader failed ({type(err).__name__}: {text or 'no message'}){tail}"
