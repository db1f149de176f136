"""Compress a whole asset library with one set of options: ``meshbits batch``.

The inputs are a folder (searched recursively for mesh and scene files), a glob pattern,
or a manifest (CSV with a ``path`` column, or JSON Lines with a ``"path"`` key). Every
input is compressed to the same budget; ``.drc`` and ``.ply`` outputs go through
:func:`meshbits.compress`, ``.glb`` and ``.gltf`` outputs through
:func:`meshbits.compress_scene`. Outputs mirror the inputs' sub-folders under the output
folder.

Tasks run in this process (one worker), in a pool of spawned worker processes (the
default: one per core, kernels on ``cores // workers`` threads each), or on Dask
distributed. Each finished task appends one row to ``OUT_DIR/meshbits-report.jsonl`` at
once, so an interrupted batch keeps what it did; a rerun skips the inputs whose output
exists and whose row has the same options and input hash. A bad input, an unmet budget
or even a bug in one task is recorded in its row and never stops the batch. See
docs/batch.md.

The modules: :mod:`.inputs` (finding inputs, output names, digests for resuming),
:mod:`.task` (one input's job), :mod:`.runners` (this process, a process pool, Dask),
:mod:`.report` (rows, totals, the report, summary and plot files) and :mod:`.run` (the
batch itself).
"""

from .inputs import MESH_SUFFIXES, Inputs, find_inputs, input_digest
from .report import (
    PLOT_NAME,
    REPORT_NAME,
    SUMMARY_NAME,
    BatchInterrupted,
    BatchResult,
    BatchRow,
)
from .run import batch
from .task import CODECS, FORMATS

__all__ = [
    "CODECS",
    "FORMATS",
    "MESH_SUFFIXES",
    "PLOT_NAME",
    "REPORT_NAME",
    "SUMMARY_NAME",
    "BatchInterrupted",
    "BatchResult",
    "BatchRow",
    "Inputs",
    "batch",
    "find_inputs",
    "input_digest",
]
