"""Sniffing: what a file is and whether it can be parsed, from its name, size and header.

The checks every format shares before a parser reads a mesh file: its type from its name
(``mesh.ply``, ``mesh.ply.gz``), a ``.gz`` inflated within a decompression-bomb limit,
the file read through a memory map so a header check touches only the pages it needs,
the words a header check uses to name a disagreement, and a parser's failure put in
plain words (:func:`explain`). The header checks themselves belong to their formats
(:mod:`.ply`, :mod:`.obj`, :mod:`.stl`, :mod:`.gltf.read`); images are sniffed here too
(:func:`image_size`, :func:`mime_type`).

trimesh reads a header's counts and trusts them: an ASCII PLY or an OFF file declaring
10**12 faces but holding four is read as four faces, a binary STL whose triangle count
disagrees with its length is re-read as text. Each check compares what a header declares
with what the file holds, from the header and the file's size, without allocating
anything the size of a declared count, and names the disagreement.
"""

from __future__ import annotations

import contextlib
import gzip
import io
import mmap
import os
import re
import struct
import zlib
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..errors import MeshFileError

__all__ = [
    "GZIP_MAX_RATIO",
    "GZIP_MIN_LIMIT",
    "HEADER_LIMIT",
    "HeaderCheck",
    "check_mapped",
    "count_of",
    "explain",
    "file_type_of",
    "gunzip",
    "header_text",
    "image_size",
    "mime_type",
    "plural",
]

#: A ``.gz`` mesh may inflate to at most this many times its compressed size (meshes
#: compress 1.5 to 3 times; zeros, a thousand times)...
GZIP_MAX_RATIO = 100
#: ...or to this many bytes (64 MiB), whichever is larger.
GZIP_MIN_LIMIT = 64 << 20

#: Longest PLY or OFF header read (bytes); real headers are a few hundred bytes.
HEADER_LIMIT = 1 << 20

#: A format's header check: ``check(buffer, size)`` compares what the header of the whole
#: file in ``buffer`` (``size`` bytes, anything numpy can read and slice) declares with
#: what it holds, and raises :class:`MeshFileError` naming the first disagreement.
HeaderCheck = Callable[[Any, int], None]

_WHOLE = re.compile(r"\+?[0-9]+")

_PLURALS = {"vertex": "vertices"}


def plural(count: int, word: str) -> str:
    """``"1 face"``, ``"2,000 faces"``, ``"3 vertices"``."""
    return f"{count:,} " + (word if count == 1 else _PLURALS.get(word, word + "s"))


def header_text(head: bytes, what: str) -> str:
    """A header's bytes as UTF-8 text; a byte that is not text is refused, named with its
    offset."""
    try:
        return head.decode("utf-8")
    except UnicodeDecodeError as err:
        raise MeshFileError(
            f"the {what} holds a byte that is not text (0x{head[err.start]:02x} at offset "
            f"{err.start}): the file is damaged"
        ) from None


def count_of(text: str, what: str) -> int:
    """A header's count, a whole number >= 0 written in decimal."""
    if not _WHOLE.fullmatch(text):
        raise MeshFileError(f"{what} is {text!r}, not a whole number >= 0")
    return int(text)


def file_type_of(path: Path) -> tuple[str, bool]:
    """A mesh file's format from its name (``"ply"`` for ``mesh.ply`` and
    ``mesh.ply.gz``) and whether it is gzip-compressed; a name that does not tell is
    refused."""
    suffixes = [s.lower() for s in path.suffixes]
    compressed = bool(suffixes) and suffixes[-1] == ".gz"
    if compressed and len(suffixes) < 2:
        raise MeshFileError(f"cannot tell the format of {path}: name it like mesh.ply.gz")
    file_type = suffixes[-2 if compressed else -1].lstrip(".") if suffixes else ""
    if not file_type:
        raise MeshFileError(f"cannot tell the format of {path}: name it like mesh.ply")
    return file_type, compressed


def gunzip(path: Path) -> io.BytesIO:
    """The decompressed content of a gzip file, refused beyond the bomb limit
    (:data:`GZIP_MAX_RATIO` times its size, at least :data:`GZIP_MIN_LIMIT` bytes)."""
    limit = max(GZIP_MIN_LIMIT, GZIP_MAX_RATIO * path.stat().st_size)
    out = io.BytesIO()
    try:
        with gzip.open(path, "rb") as handle:
            while chunk := handle.read(1 << 20):
                out.write(chunk)
                if out.tell() > limit:
                    raise MeshFileError(
                        f"it inflates to more than {limit:,} bytes, over {GZIP_MAX_RATIO} "
                        f"times its size: no mesh compresses that well (a decompression bomb?)"
                    )
    except (gzip.BadGzipFile, zlib.error) as err:
        raise MeshFileError(f"it is not a valid gzip file ({err})") from err
    except EOFError:
        raise MeshFileError("the gzip data is truncated") from None
    out.seek(0)
    return out


def check_mapped(path: Path, check: Callable[[Any, int], None]) -> None:
    """``check(buffer, size)`` on a file read through a memory map (only the pages the
    check touches are read); an empty file is refused."""
    with open(path, "rb") as handle:
        size = os.fstat(handle.fileno()).st_size
        if size == 0:
            raise MeshFileError("the file is empty")
        mapped = mmap.mmap(handle.fileno(), 0, access=mmap.ACCESS_READ)
        try:
            try:
                check(mapped, size)
            except MeshFileError as err:
                # Re-raised once the map is closed: the traceback's frames hold numpy
                # views of the map, which keep it from closing.
                refusal = str(err)
            else:
                refusal = None
        finally:
            with contextlib.suppress(BufferError):  # only after an unexpected error
                mapped.close()
    if refusal is not None:
        raise MeshFileError(refusal)


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
    return _explain_message(text, tail) or (
        f"the {kind} reader failed ({type(err).__name__}: {text or 'no message'}){tail}"
    )


def _explain_message(text: str, tail: str) -> str | None:
    """A parser's message about a number or an index, in words about the file."""
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
    return None


def mime_type(name: str) -> str | None:
    """An image's MIME type from its file name; None if unknown."""
    suffix = name.rsplit(".", 1)[-1].lower()
    return {
        "png": "image/png",
        "jpg": "image/jpeg",
        "jpeg": "image/jpeg",
        "webp": "image/webp",
        "ktx2": "image/ktx2",
    }.get(suffix)


def image_size(data: bytes) -> tuple[int, int] | None:
    """``(width, height)`` of a PNG, JPEG or WebP image from its header; None if unknown."""
    if data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) >= 24:
        width, height = struct.unpack(">II", data[16:24])
        return int(width), int(height)
    if data[:2] == b"\xff\xd8":
        return _jpeg_size(data)
    if data[:4] == b"RIFF" and data[8:12] == b"WEBP" and len(data) >= 30:
        return _webp_size(data)
    return None


def _jpeg_size(data: bytes) -> tuple[int, int] | None:
    """A JPEG's size, from its first start-of-frame marker."""
    i = 2
    while i + 9 < len(data):
        if data[i] != 0xFF:
            return None
        marker = data[i + 1]
        length = struct.unpack(">H", data[i + 2 : i + 4])[0]
        if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
            height, width = struct.unpack(">HH", data[i + 5 : i + 9])
            return int(width), int(height)
        i += 2 + length
    return None


def _webp_size(data: bytes) -> tuple[int, int] | None:
    """A WebP's size, from its lossy, lossless or extended header."""
    chunk = data[12:16]
    if chunk == b"VP8 ":
        width, height = struct.unpack("<HH", data[26:30])
        return int(width & 0x3FFF), int(height & 0x3FFF)
    if chunk == b"VP8L":
        b = data[21:25]
        width = 1 + (((b[1] & 0x3F) << 8) | b[0])
        height = 1 + (((b[3] & 0xF) << 10) | (b[2] << 2) | ((b[1] & 0xC0) >> 6))
        return int(width), int(height)
    if chunk == b"VP8X":
        width = 1 + int.from_bytes(data[24:27], "little")
        height = 1 + int.from_bytes(data[27:30], "little")
        return width, height
    return None
