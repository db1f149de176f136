"""Where the benchmarks read public meshes and reference implementations from.

A folder ``shared`` next to the repository, or the folder ``MESHBITS_SHARED`` names, holding
``meshes/`` and ``bench-refs/refs.py``. A clone does not have it: docs/benchmarks.md states
its meshes (any copy of those public models will do) and its reference implementations in
full, so that a ``refs.py`` written from that page reproduces every ratio.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from types import ModuleType

ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("MESHBITS_SHARED", ROOT.parent / "shared"))


def import_refs() -> ModuleType:
    """``bench-refs/refs.py`` of :data:`SHARED`, or exit saying where it was looked for."""
    folder = SHARED / "bench-refs"
    if not (folder / "refs.py").is_file():
        raise SystemExit(
            f"{folder / 'refs.py'} not found: the speed targets are stated against the "
            "reference implementations of docs/benchmarks.md ('Reference implementations'); "
            "set MESHBITS_SHARED to the folder holding bench-refs/refs.py and meshes/"
        )
    sys.path.insert(0, str(folder))
    import refs

    return refs
