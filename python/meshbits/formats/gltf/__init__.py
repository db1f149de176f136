"""glTF 2.0: the specification's constants and conversions (:mod:`.spec`), the in-memory
document (:mod:`.document`), its validation (:mod:`.validate`), reading (:mod:`.read`)
and writing (:mod:`.write`). Imports run one way: spec <- document, validate <- read;
write imports only meshbits.files, and read takes write's frame centre.
"""

from __future__ import annotations

from .document import Document, PrimitiveData

__all__ = ["Document", "PrimitiveData"]
