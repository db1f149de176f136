"""glTF 2.0: the specification's constants and conversions (:mod:`.spec`), the in-memory
document (:mod:`.document`), its validation (:mod:`.validate`), reading (:mod:`.read`)
and writing (:mod:`.write`, the one writer: scenes rebuilt around their compressed
primitives, and single meshes). Imports run one way: spec <- document <- write <- read,
validate <- read; write imports meshbits.files besides.
"""

from __future__ import annotations

from .document import Document, PrimitiveData

__all__ = ["Document", "PrimitiveData"]
