"""STL: the header check, a binary STL's triangle count against its length.

trimesh parses STL (binary or ASCII) and writes it; a binary STL whose count disagrees
with its length would be re-read as text, so :func:`check_header` refuses it first.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import MeshFileError
from .sniff import plural

__all__ = ["check_header"]


def check_header(buffer: Any, size: int) -> None:
    """Refuse an STL (the whole file in ``buffer``, ``size`` bytes) that is neither a
    binary STL whose 84-byte header's triangle count fits its length nor ASCII text
    starting with ``solid``."""
    head = bytes(buffer[: min(size, 84)])
    count = int(np.frombuffer(head, "<u4", 1, 80)[0]) if size >= 84 else None
    if count is not None and 84 + 50 * count == size:
        return  # binary, even when its header starts with "solid"
    sample = bytes(buffer[: min(size, 4096)])
    if sample.lstrip().startswith(b"solid") and b"\0" not in sample:
        return  # ASCII: trimesh parses it
    if count is None:
        raise MeshFileError(
            f"the file has {plural(size, 'byte')}: too short for a binary STL (84-byte "
            "header) and not an ASCII STL (no 'solid')"
        )
    if _looks_like_text(sample):
        raise MeshFileError(
            f"the file is text but not an ASCII STL (it does not start with 'solid'), and "
            f"not a binary STL ({size:,} bytes, where its header would declare "
            f"{plural(count, 'triangle')}): not an STL file"
        )
    raise MeshFileError(
        f"the binary STL declares {plural(count, 'triangle')} ({84 + 50 * count:,} bytes) "
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
