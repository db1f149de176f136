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
"""

from __future__ import annotations

import csv
import dataclasses
import datetime
import glob
import hashlib
import io
import json
import logging
import math
import multiprocessing
import os
import signal
import socket
import sys
import time
import traceback
from collections import Counter, deque
from collections.abc import Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from . import _core
from .errors import MeshbitsError
from .files import asset_bytes, external_files, write_atomic
from .formats import load_mesh
from .results import json_ready
from .units import in_unit, length_unit_of

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

#: File names searched for in a folder or a glob's matches (case-insensitive).
MESH_SUFFIXES = (".ply.gz", ".ply", ".obj", ".stl", ".off", ".glb", ".gltf", ".drc")
#: Output formats: ``drc`` and ``ply`` through :func:`meshbits.compress` (one merged
#: mesh), ``glb`` and ``gltf`` through :func:`meshbits.compress_scene` (the whole scene).
FORMATS = ("drc", "ply", "glb", "gltf")
SCENE_FORMATS = ("glb", "gltf")
CODECS = ("draco", "meshopt")
#: What a manifest file is named like.
MANIFEST_SUFFIXES = (".csv", ".jsonl", ".ndjson")
REPORT_NAME = "meshbits-report.jsonl"
SUMMARY_NAME = "meshbits-summary.csv"
PLOT_NAME = "meshbits-report.png"
#: A row's ``status``: the budget met, not met (the closest result is written), an input
#: that cannot be used (unreadable, corrupt, no triangles; or an output that cannot be
#: written), or a bug in meshbits.
STATUSES = ("met", "unmet", "unusable", "internal_error")
#: Statuses whose output a rerun can keep.
_DONE = ("met", "unmet")
#: Times a task is tried again after its worker process died under it (killed for memory,
#: crashed), before it is recorded as an internal error.
WORKER_DEATH_RETRIES = 1

_EXIT_OK, _EXIT_UNMET, _EXIT_UNUSABLE, _EXIT_INTERNAL, _EXIT_INTERRUPTED = 0, 1, 2, 3, 130


# --- rows and results ------------------------------------------------------------------------


@dataclass(frozen=True)
class BatchRow:
    """One input of a batch: one line of ``meshbits-report.jsonl``.

    Attributes
    ----------
    path : str
        The input file (absolute).
    relative : str
        The input relative to the batch's root (the folder searched, the glob's folder,
        the manifest's folder), with ``/`` separators: the key of the row.
    output : str or None
        The output relative to the output folder (``/`` separators); None when nothing
        was written.
    status : str
        ``"met"``, ``"unmet"`` (the closest result is written), ``"unusable"`` (the input
        cannot be used, or the output cannot be written) or ``"internal_error"`` (a bug in
        meshbits).
    met : bool
        Whether the budget was met.
    message : str or None
        None when the budget was met; else why not (the search's sentence, or the error
        in one line).
    constraint : str
        ``"error"`` or ``"size"``.
    budget : float or None
        The error budget in the file's length units (world units for a scene; a relative
        budget already multiplied by the size), or the size budget in bytes.
    input_bytes, output_bytes : int or None
        Sizes of the input (for a ``.gltf``, with the buffers and images it names) and of
        the output (bytes).
    bits : int or None
        B, bits per coordinate (for a scene, the largest of its primitives).
    vertices, faces : int or None
        V and the face count of the output (for a scene, summed over its primitives).
    input_vertices, input_faces : int or None
        The same of the input (``input_faces`` is None for a scene).
    error : float or None
        The measured Hausdorff error of the output (the file's length units; for a
        scene, the largest world-space error of its primitives).
    error_upper : float or None
        Its certified upper bound, in the same units (None when there is none: an error
        budget's bound is refined until it decides the budget; see ``compress``).
    seconds : float
        Wall time of the task in its worker, reading and writing included (s).
    cpu_seconds : float or None
        CPU time of the worker process during the task, all its threads (s): below
        ``seconds`` times the kernel threads when the machine is shared.
    input_sha256 : str or None
        SHA-256 of the input's bytes (a ``.gltf``'s buffers and images included).
    options : dict
        The options the output was made with; a rerun keeps an output only when they
        are the same.
    peak_rss_bytes : int or None
        The worker's peak resident memory during the task (bytes; Linux's ``VmHWM``
        reset before the task, or the process's lifetime peak where it cannot be reset:
        see ``peak_rss_scope``).
    rss_before_bytes : int or None
        The worker's resident memory when the task started (bytes).
    peak_rss_scope : str or None
        ``"task"`` or ``"process"``.
    worker : str
        ``pid@host`` of the process that ran the task.
    traceback : str or None
        For an internal error, the traceback (to report the bug).
    merged_away : dict or None
        For a glTF or OBJ input written to ``drc`` or ``ply`` (one merged mesh of positions):
        what that leaves out, counted (materials, textures, images, skins, animations,
        morph targets, and the names of the vertex ``attributes`` other than positions;
        see :func:`meshbits.scene.omitted_by_merging`). None otherwise.
    resumed : bool
        True when a rerun kept this row and its output from an earlier run.
    finished : str
        When the task finished (ISO 8601, UTC).
    meshbits : str
        Version of meshbits that made the output.
    """

    path: str
    relative: str
    output: str | None
    status: str
    met: bool
    message: str | None
    constraint: str
    budget: float | None = None
    input_bytes: int | None = None
    output_bytes: int | None = None
    bits: int | None = None
    vertices: int | None = None
    faces: int | None = None
    input_vertices: int | None = None
    input_faces: int | None = None
    error: float | None = None
    error_upper: float | None = None
    seconds: float = 0.0
    cpu_seconds: float | None = None
    input_sha256: str | None = None
    options: dict[str, Any] = field(default_factory=dict)
    peak_rss_bytes: int | None = None
    rss_before_bytes: int | None = None
    peak_rss_scope: str | None = None
    worker: str = ""
    traceback: str | None = None
    merged_away: dict[str, Any] | None = None
    resumed: bool = False
    finished: str = ""
    meshbits: str = ""

    @property
    def saved_bytes(self) -> int | None:
        """Input bytes minus output bytes, when an output was written."""
        if self.output is None or self.input_bytes is None or self.output_bytes is None:
            return None
        return self.input_bytes - self.output_bytes

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict of the fields (strict JSON: no NaN or Infinity), with
        ``length_unit`` after ``path``: the unit of ``error`` and ``error_upper`` (and of a
        ``budget`` of an error), ``"m"`` for glTF, else ``"mesh units"``."""
        first, *rest = dataclasses.asdict(self).items()
        return json_ready(dict([first, ("length_unit", length_unit_of(self.path)), *rest]))

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> BatchRow:
        """A row read back from a report (unknown keys ignored, missing ones defaulted)."""
        names = {f.name for f in dataclasses.fields(cls)}
        return cls(**{k: v for k, v in data.items() if k in names})


@dataclass(frozen=True)
class BatchResult:
    """Outcome of :func:`batch`.

    Attributes
    ----------
    rows : tuple of BatchRow
        One per input, in input order (resumed rows included).
    out_dir, report, summary : str
        The output folder, ``meshbits-report.jsonl`` and ``meshbits-summary.csv``.
    plot : str or None
        ``meshbits-report.png``; None without matplotlib.
    backend : str
        ``"serial"`` (in this process), ``"processes"`` (a spawned pool) or ``"dask"``.
    workers : int
        Processes that ran tasks (Dask: the cluster's workers when the batch started).
    kernel_threads : int
        Threads of the native kernels in each worker (0: the worker decides, Dask).
    inputs : int
        Distinct input files.
    ran, resumed : int
        Inputs run by this call (whatever their status: an unusable input runs too), and
        inputs kept from an earlier run.
    met, unmet, unusable, internal_errors : int
        Inputs by status (resumed rows included).
    not_reached : int
        Inputs not run because the batch was interrupted.
    ignored : dict
        Files the search found that are not mesh files, counted by suffix, and mesh files
        inside the output folder (``"(in the output folder)"``: earlier outputs).
    duplicates : int
        Inputs listed more than once (run once).
    blank_manifest_rows : int
        Manifest rows without a path.
    earlier_rows : int
        Rows of the report for inputs outside this batch (kept in the report).
    unreadable_report_lines : int
        Lines of an earlier report that could not be read (their inputs are run again).
    input_bytes, output_bytes, saved_bytes : int
        Totals over the inputs with an output (bytes).
    seconds : float
        Wall time of the batch (s).
    interrupted : bool
        Whether Ctrl-C stopped the batch.
    options : dict
        The options every input was compressed with.
    """

    rows: tuple[BatchRow, ...]
    out_dir: str
    report: str
    summary: str
    plot: str | None
    backend: str
    workers: int
    kernel_threads: int
    inputs: int
    ran: int
    resumed: int
    met: int
    unmet: int
    unusable: int
    internal_errors: int
    not_reached: int
    ignored: dict[str, int]
    duplicates: int
    blank_manifest_rows: int
    earlier_rows: int
    unreadable_report_lines: int
    input_bytes: int
    output_bytes: int
    saved_bytes: int
    seconds: float
    interrupted: bool
    options: dict[str, Any]

    @property
    def exit_code(self) -> int:
        """The ``meshbits batch`` exit code: 130 interrupted, 3 an internal error in some
        task, 2 some input unusable, 1 some budget unmet, 0 every budget met."""
        if self.interrupted:
            return _EXIT_INTERRUPTED
        if self.internal_errors:
            return _EXIT_INTERNAL
        if self.unusable:
            return _EXIT_UNUSABLE
        if self.unmet:
            return _EXIT_UNMET
        return _EXIT_OK

    @property
    def ok(self) -> bool:
        """Every input met its budget."""
        return self.exit_code == _EXIT_OK

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict: the totals, the exit code, and every row."""
        out = {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.name != "rows"}
        out["exit_code"] = self.exit_code
        out["rows"] = [row.to_dict() for row in self.rows]
        return json_ready(out)


class BatchInterrupted(KeyboardInterrupt):
    """Ctrl-C stopped a batch; the report and summary of what finished were written.

    Attributes
    ----------
    result : BatchResult
        What finished (``result.interrupted`` is True).
    """

    def __init__(self, result: BatchResult) -> None:
        super().__init__("batch interrupted")
        self.result = result


# --- finding the inputs ----------------------------------------------------------------------


@dataclass(frozen=True)
class Inputs:
    """The files of a batch.

    Attributes
    ----------
    root : Path
        The folder outputs are mirrored from.
    paths : tuple of Path
        Distinct input files (absolute), sorted for a folder or glob, in manifest order.
    ignored : dict
        Files seen that are not mesh files, counted by suffix (``"(none)"``: no suffix), and
        mesh files inside the output folder (``"(in the output folder)"``).
    duplicates : int
        Paths listed more than once.
    blank : int
        Manifest rows without a path.
    """

    root: Path
    paths: tuple[Path, ...]
    ignored: dict[str, int]
    duplicates: int = 0
    blank: int = 0


def _mesh_suffix(name: str) -> str | None:
    lower = name.lower()
    return next((s for s in MESH_SUFFIXES if lower.endswith(s)), None)


#: The key of ``ignored`` that counts mesh files skipped because they are inside the
#: output folder (earlier outputs, never inputs).
IN_OUTPUT_FOLDER = "(in the output folder)"


def _ignored_suffix(path: Path) -> str:
    return path.suffix.lower() or "(none)"


def _is_glob(text: str) -> bool:
    return any(c in text for c in "*?[")


def _inside(path: Path, folder: Path) -> bool:
    try:
        path.relative_to(folder)
    except ValueError:
        return False
    return True


def find_inputs(source: str | os.PathLike[str], *, exclude: str | Path | None = None) -> Inputs:
    """The mesh files named by ``source``.

    Parameters
    ----------
    source
        A folder (searched recursively for ``.ply .ply.gz .obj .stl .off .glb .gltf .drc``), a
        glob pattern (``**`` matches sub-folders), a manifest (``.csv`` with a ``path``
        column, or ``.jsonl`` / ``.ndjson`` with a ``"path"`` key on each line; relative
        paths are relative to the manifest's folder), or one mesh file.
    exclude
        A folder whose files are never inputs (the output folder).

    Raises
    ------
    MeshbitsError
        Nothing is at ``source``, or a manifest cannot be read.
    """
    text = os.fspath(source)
    path = Path(text).expanduser()
    skip = Path(exclude).expanduser().resolve() if exclude is not None else None
    ignored: Counter[str] = Counter()

    def keep(found: Path) -> bool:
        if skip is not None and _inside(found.resolve(), skip):
            if _mesh_suffix(found.name) is not None:
                ignored[IN_OUTPUT_FOLDER] += 1
            return False
        if _mesh_suffix(found.name) is None:
            ignored[_ignored_suffix(found)] += 1
            return False
        return True

    if path.is_dir():
        root = path.resolve()
        files = sorted(p for p in root.rglob("*") if p.is_file() and keep(p))
        return Inputs(root, tuple(p.resolve() for p in files), dict(ignored))
    if path.is_file() and path.name.lower().endswith(MANIFEST_SUFFIXES):
        return _read_manifest(path)
    if path.is_file():
        return Inputs(path.resolve().parent, (path.resolve(),), {})
    if _is_glob(text):
        parts = Path(text).expanduser().parts
        first = next(i for i, part in enumerate(parts) if _is_glob(part))
        root = (Path(*parts[:first]) if first else Path(".")).resolve()
        matches = sorted(Path(m) for m in glob.glob(str(path), recursive=True))
        files = [m.resolve() for m in matches if m.is_file() and keep(m)]
        return Inputs(root, tuple(dict.fromkeys(files)), dict(ignored))
    raise MeshbitsError(f"no such folder, file or glob match: {text}")


def _read_manifest(path: Path) -> Inputs:
    """A CSV manifest (a ``path`` column) or a JSON Lines one (a ``"path"`` key)."""
    entries: list[str] = []
    blank = 0
    try:
        content = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as err:
        raise MeshbitsError(f"manifest {path} is not UTF-8 text: {err}") from None
    if path.suffix.lower() == ".csv":
        reader = csv.DictReader(io.StringIO(content))
        if reader.fieldnames is None or "path" not in [n.strip() for n in reader.fieldnames]:
            raise MeshbitsError(f"manifest {path} has no 'path' column (a CSV header line)")
        column = next(n for n in reader.fieldnames if n.strip() == "path")
        for record in reader:
            value = (record.get(column) or "").strip()
            if value:
                entries.append(value)
            else:
                blank += 1
    else:
        for number, line in enumerate(content.splitlines(), start=1):
            if not line.strip():
                continue
            try:
                record = json.loads(line)
            except json.JSONDecodeError as err:
                raise MeshbitsError(f"manifest {path}, line {number}: not JSON ({err})") from None
            if not isinstance(record, dict):
                raise MeshbitsError(f"manifest {path}, line {number}: not a JSON object")
            value = record.get("path")
            if value is None or (isinstance(value, str) and not value.strip()):
                blank += 1
                continue
            if not isinstance(value, str):
                raise MeshbitsError(f"manifest {path}, line {number}: 'path' is not a string")
            entries.append(value.strip())
    folder = path.resolve().parent
    resolved = [
        (folder / Path(e).expanduser()).resolve()
        if not Path(e).expanduser().is_absolute()
        # resolve() of an absolute path only normalises it
        else Path(e).expanduser().resolve()
        for e in entries
    ]
    distinct = tuple(dict.fromkeys(resolved))
    if distinct and not all(_inside(p, folder) for p in distinct):
        root = Path(os.path.commonpath([str(p.parent) for p in distinct]))
    else:
        root = folder
    return Inputs(root, distinct, {}, duplicates=len(resolved) - len(distinct), blank=blank)


def input_digest(path: str | Path) -> str:
    """SHA-256 (hex) of a file's bytes; for a ``.gltf``, also of the buffers and images it
    names by relative URI (the parts that change its meaning)."""
    path = Path(path)
    digest = hashlib.sha256()

    def feed(file: Path) -> None:
        with open(file, "rb") as handle:
            while chunk := handle.read(1 << 20):
                digest.update(chunk)

    feed(path)
    for uri, part in external_files(path):
        if part.is_file():
            digest.update(b"\0" + uri.encode() + b"\0")
            feed(part)
    return digest.hexdigest()


# --- one task --------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Task:
    index: int
    path: str
    relative: str
    output: str  # absolute
    output_relative: str
    options: dict[str, Any]
    #: Kernel threads to set in the worker: None leaves them, -1 lets a Dask worker pick
    #: ``cores // its task threads``.
    threads: int | None = None


def _output_names(inputs: Inputs, out_dir: Path, fmt: str) -> list[tuple[str, str]]:
    """(relative input, relative output) per input: the input's sub-folder under OUT_DIR,
    its name with the mesh suffix replaced by the format (``a.ply.gz`` -> ``a.drc``), or
    kept before it (``a.ply.drc``) when two inputs would write one output."""
    pairs = []
    for path in inputs.paths:
        try:
            relative = path.relative_to(inputs.root)
        except ValueError:  # pragma: no cover - the root is a common ancestor
            relative = Path(path.name)
        suffix = _mesh_suffix(relative.name) or relative.suffix
        stem = relative.name[: len(relative.name) - len(suffix)] if suffix else relative.name
        pairs.append((relative, (relative.parent / f"{stem}.{fmt}")))
    counts = Counter(str(out).lower() for _, out in pairs)
    names = []
    for relative, out in pairs:
        if counts[str(out).lower()] > 1:
            out = relative.parent / f"{relative.name}.{fmt}"
        names.append((relative.as_posix(), out.as_posix()))
    return names


def _one_line(err: BaseException) -> str:
    return " ".join(str(err).split()) or type(err).__name__


def _proc_status_bytes(key: str) -> int | None:
    try:
        with open("/proc/self/status") as handle:
            for line in handle:
                if line.startswith(key + ":"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return None


def _reset_peak_rss() -> bool:
    """Reset Linux's peak RSS (``VmHWM``) of this process, so that it measures one task."""
    try:
        with open("/proc/self/clear_refs", "w") as handle:
            handle.write("5")
    except OSError:
        return False
    return _proc_status_bytes("VmHWM") is not None


def _peak_rss() -> int | None:
    peak = _proc_status_bytes("VmHWM")
    if peak is not None:
        return peak
    try:
        import resource
    except ImportError:  # pragma: no cover - Windows
        return None
    scale = 1 if sys.platform == "darwin" else 1024  # bytes on macOS, KiB on Linux
    return int(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss) * scale


_threads_set: int | None = None


def _set_threads(threads: int | None) -> None:
    """Kernel threads of this worker process (see :class:`_Task`), set once."""
    global _threads_set
    if threads is None or threads == _threads_set:
        return
    count = threads
    if threads < 0:
        try:
            from distributed import get_worker

            slots = max(1, int(get_worker().state.nthreads))
        except (ImportError, ValueError, AttributeError):
            slots = 1
        count = max(1, _cores() // slots)
    from .threads import set_num_threads

    set_num_threads(count)
    _threads_set = threads


def _run_task(task: _Task) -> dict[str, Any]:
    """Compress one input and write its output; return its report row as a dict. Every
    failure is caught and recorded: a refused input or file-system error as
    ``"unusable"``, anything else as ``"internal_error"`` with the traceback."""
    from .compress import compress
    from .scene import compress_scene, merged_away

    _set_threads(task.threads)
    start = time.perf_counter()
    cpu_start = time.process_time()
    scoped = _reset_peak_rss()
    options = task.options
    row: dict[str, Any] = {
        "path": task.path,
        "relative": task.relative,
        "output": None,
        "status": "internal_error",
        "met": False,
        "message": None,
        "constraint": "error" if options["error"] is not None else "size",
        "options": options,
        "rss_before_bytes": _proc_status_bytes("VmRSS"),
        "worker": f"{os.getpid()}@{socket.gethostname()}",
        "meshbits": _core.__version__,
    }
    size = options["size_bits"]
    try:
        path = Path(task.path)
        if not path.is_file():
            raise FileNotFoundError(f"no such file: {path}")
        row["input_bytes"] = asset_bytes(path)
        row["input_sha256"] = input_digest(path)
        output = Path(task.output)
        output.parent.mkdir(parents=True, exist_ok=True)
        if options["format"] in SCENE_FORMATS:
            scene = compress_scene(
                path,
                error=options["error"],
                size=size,
                relative=options["relative"],
                codec=options["codec"],
                output=output,
                seed=options["seed"],
            )
            compressed = [p for p in scene.primitives if p.kept is None]
            row |= {
                "met": scene.met,
                "message": in_unit(scene.message, length_unit_of(path)),
                "budget": scene.budget if size is None else scene.budget / 8,
                "input_bytes": scene.input_bytes or row["input_bytes"],
                "output_bytes": scene.size_bytes,
                "bits": max((p.bits for p in compressed), default=None),
                "vertices": sum(p.vertices for p in scene.primitives),
                "faces": sum(p.faces for p in scene.primitives),
                "input_vertices": sum(p.input_vertices for p in scene.primitives),
                "error": scene.world_error,
                "error_upper": scene.world_error_upper,
            }
        else:
            row["merged_away"] = merged_away(path)
            vertices, faces = load_mesh(path)
            result = compress(
                (vertices, faces),
                error=options["error"],
                size=size,
                relative=options["relative"],
                format="draco" if options["format"] == "drc" else "ply",
                max_iterations=options["max_iterations"],
                seed=options["seed"],
            )
            result.write(output)
            row |= {
                "met": result.met,
                "message": in_unit(result.message, length_unit_of(path)),
                "budget": result.budget if size is None else result.budget / 8,
                "output_bytes": result.size_bytes,
                "bits": result.bits,
                "vertices": result.vertex_count,
                "faces": len(result.faces),
                "input_vertices": len(vertices),
                "input_faces": len(faces),
                "error": result.error,
                "error_upper": result.error_upper,
            }
        row["output"] = task.output_relative
        row["status"] = "met" if row["met"] else "unmet"
        if row["met"]:
            row["message"] = None
    except (MeshbitsError, OSError) as err:
        # A refused input (corrupt, empty, no triangles) or a file system that refused a
        # read or a write.
        row |= {"status": "unusable", "met": False, "message": _one_line(err)}
    except Exception as err:  # a bug in meshbits: recorded, the batch goes on
        row |= {
            "status": "internal_error",
            "met": False,
            "message": f"internal error: {type(err).__name__}: {_one_line(err)}",
            "traceback": traceback.format_exc(),
        }
    row["seconds"] = time.perf_counter() - start
    row["cpu_seconds"] = time.process_time() - cpu_start
    row["peak_rss_bytes"] = _peak_rss()
    row["peak_rss_scope"] = "task" if scoped else "process"
    row["finished"] = _now()
    return row


def _failed_row(task: _Task, message: str, *, trace: str | None = None) -> dict[str, Any]:
    """The row of a task whose worker failed outside :func:`_run_task`."""
    return {
        "path": task.path,
        "relative": task.relative,
        "output": None,
        "status": "internal_error",
        "met": False,
        "message": message,
        "constraint": "error" if task.options["error"] is not None else "size",
        "options": task.options,
        "traceback": trace,
        "finished": _now(),
        "meshbits": _core.__version__,
    }


def _now() -> str:
    return datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")


def _cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - macOS, Windows
        return os.cpu_count() or 1


# --- runners ---------------------------------------------------------------------------------


class _Serial:
    """Tasks in this process, one after the other, kernels on every core."""

    backend = "serial"

    def __init__(self) -> None:
        from .threads import get_num_threads

        self.workers = 1
        self.threads = get_num_threads() or _cores()

    def results(self, tasks: Sequence[_Task]) -> Iterator[dict[str, Any]]:
        for task in tasks:
            yield _run_task(task)

    def close(self, interrupted: bool) -> None:
        pass


def _init_worker(threads: int) -> None:
    """Initializer of a pool worker: Ctrl-C is the parent's to handle (it stops the pool),
    and kernels run on ``threads`` threads."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _set_threads(threads)


class _Processes:
    """A pool of spawned worker processes (spawn: a fork of this process could inherit
    locked thread pools and would copy its memory). At most ``workers`` tasks are in
    flight, so that when a worker dies (killed for memory, crashed) the tasks it may have
    been running are known: they are tried again once on a new pool, then recorded."""

    backend = "processes"

    def __init__(self, workers: int, threads: int) -> None:
        self.workers = workers
        self.threads = threads
        self._pool: ProcessPoolExecutor | None = None

    def _start(self) -> ProcessPoolExecutor:
        self._pool = ProcessPoolExecutor(
            self.workers,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=_init_worker,
            initargs=(self.threads,),
        )
        return self._pool

    def results(self, tasks: Sequence[_Task]) -> Iterator[dict[str, Any]]:
        queue = deque(tasks)
        deaths: Counter[int] = Counter()
        pool = self._start()
        running: dict[Future[dict[str, Any]], _Task] = {}
        while queue or running:
            while queue and len(running) < self.workers:
                task = queue.popleft()
                running[pool.submit(_run_task, task)] = task
            done, _ = wait(running, return_when=FIRST_COMPLETED)
            broken = False
            for future in done:
                task = running.pop(future)
                try:
                    yield future.result()
                except BrokenProcessPool:
                    broken = True
                    running[future] = task
                except Exception as err:  # the task could not be sent or received back
                    yield _failed_row(
                        task,
                        f"internal error: the worker failed: {type(err).__name__}: "
                        f"{_one_line(err)}",
                    )
            if broken:
                wait(running)  # every task in flight fails with the pool
                suspects = list(running.values())
                running.clear()
                self._kill(pool)
                for task in reversed(suspects):
                    deaths[task.index] += 1
                    if deaths[task.index] > WORKER_DEATH_RETRIES:
                        yield _failed_row(
                            task,
                            "internal error: the worker process died while running this "
                            f"task, {deaths[task.index]} times (killed by the system, for "
                            "instance for memory, or crashed)",
                        )
                    else:
                        queue.appendleft(task)
                pool = self._start()

    def _kill(self, pool: ProcessPoolExecutor) -> None:
        processes = list((getattr(pool, "_processes", None) or {}).values())
        pool.shutdown(wait=False, cancel_futures=True)
        for process in processes:
            if process.is_alive():
                process.terminate()
        for process in processes:
            process.join(timeout=10)

    def close(self, interrupted: bool) -> None:
        if self._pool is None:
            return
        if interrupted:
            self._kill(self._pool)
        else:
            self._pool.shutdown(wait=True)
        self._pool = None


def _parse_dask(address: str) -> int | None:
    """``local:N`` -> N; an address -> None."""
    if address.startswith("local:"):
        count = address[len("local:") :]
        if not count.isdigit() or int(count) < 1:
            raise MeshbitsError(f"--dask local:N needs a whole number N >= 1, got {address!r}")
        return int(count)
    if not address.strip():
        raise MeshbitsError("the Dask address is empty")
    return None


#: Dask settings of a LocalCluster started by ``--dask local:N`` (see :class:`_Dask`).
LOCAL_CLUSTER_CONFIG = {
    "distributed.worker.profile.enabled": False,
    "distributed.admin.system-monitor.gil.enabled": False,
    "distributed.scheduler.worker-saturation": float("inf"),
}


class _Dask:
    """Tasks on Dask distributed: a scheduler at an address, or a LocalCluster of worker
    processes started here (``local:N``). Workers read the inputs and write the outputs
    themselves: with a remote cluster, both must be at the same paths on every worker (a
    shared file system)."""

    backend = "dask"

    def __init__(self, address: str) -> None:
        try:
            from distributed import Client, LocalCluster
        except ImportError as err:
            raise MeshbitsError(
                "--dask needs Dask distributed: pip install 'meshbits[dask]'"
            ) from err
        count = _parse_dask(address)
        self._cluster = None
        self._futures: list[Any] = []
        if count is not None:
            import dask

            # The tasks are seconds of native code: the workers' statistical profiler
            # (a stack sample every 10 ms) and GIL monitor only cost CPU here, and with
            # every task sent to a worker ahead (no root-task queuing) a worker never waits
            # a scheduler round trip for its next one. Spawned workers inherit this.
            with dask.config.set(LOCAL_CLUSTER_CONFIG):
                self._cluster = LocalCluster(
                    n_workers=count,
                    threads_per_worker=1,
                    processes=True,
                    dashboard_address=None,
                    # A worker that outlives the scheduler by a heartbeat at shutdown logs
                    # an ERROR with a traceback; a task's own failure reaches its report row.
                    silence_logs=logging.CRITICAL,
                )
            self._client = Client(self._cluster)
            self.threads = max(1, _cores() // count)
        else:
            try:
                self._client = Client(address, timeout="30s")
            except (OSError, TimeoutError) as err:
                raise MeshbitsError(f"cannot reach the Dask scheduler at {address}: {err}") from err
            self.threads = -1
        self.workers = len(self._client.scheduler_info().get("workers", {})) or (count or 0)

    def results(self, tasks: Sequence[_Task]) -> Iterator[dict[str, Any]]:
        from distributed import as_completed

        token = os.urandom(4).hex()
        by_key = {}
        for task in tasks:
            future = self._client.submit(
                _run_task,
                dataclasses.replace(task, threads=self.threads),
                key=f"meshbits-batch-{token}-{task.index}",
                pure=False,
            )
            by_key[future.key] = task
            self._futures.append(future)
        for future in as_completed(self._futures):
            task = by_key[future.key]
            try:
                row = future.result()
            except Exception as err:  # KilledWorker, a lost connection, ...
                row = _failed_row(
                    task,
                    f"internal error: the Dask task failed: {type(err).__name__}: {_one_line(err)}",
                )
            future.release()
            yield row

    def close(self, interrupted: bool) -> None:
        if interrupted and self._futures:
            self._client.cancel(self._futures)
        self._client.close()
        if self._cluster is not None:
            self._cluster.close()


# --- the report ------------------------------------------------------------------------------


class _Report:
    """``meshbits-report.jsonl``: the rows kept from earlier runs, rewritten at the start,
    then one line appended (and flushed) per finished task."""

    def __init__(self, out_dir: Path) -> None:
        self.path = out_dir / REPORT_NAME
        self.unreadable = 0
        self._handle: Any = None

    def read(self) -> dict[str, BatchRow]:
        """The rows of an earlier run by relative input path (the last one wins)."""
        rows: dict[str, BatchRow] = {}
        if not self.path.is_file():
            return rows
        with open(self.path, encoding="utf-8") as handle:
            for line in handle:
                if not line.strip():
                    continue
                try:
                    data = json.loads(line)
                    row = BatchRow.from_dict(data)
                except (ValueError, TypeError):  # a line cut by a crash, an edited file
                    self.unreadable += 1
                    continue
                rows[row.relative] = row
        return rows

    def start(self, kept: Sequence[BatchRow]) -> None:
        write_atomic(self.path, "".join(_line(row.to_dict()) for row in kept).encode())
        self._handle = open(self.path, "a", encoding="utf-8")

    def append(self, row: dict[str, Any]) -> None:
        self._handle.write(_line(row))
        self._handle.flush()

    def close(self) -> None:
        if self._handle is not None:
            self._handle.close()
            self._handle = None


def _line(data: dict[str, Any]) -> str:
    return json.dumps(json_ready(data), allow_nan=False) + "\n"


def _normalised(options: dict[str, Any]) -> dict[str, Any]:
    """Options as a report stores them (a JSON round trip), to compare with a row's."""
    return json.loads(json.dumps(json_ready(options), allow_nan=False))


# --- progress --------------------------------------------------------------------------------


def _bytes_text(count: float) -> str:
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if abs(count) >= scale:
            return f"{count / scale:.3g} {unit}"
    return f"{count:.0f} B"


class _Progress:
    """A tqdm bar on stderr (count, rate, ETA, bytes saved so far), or nothing."""

    def __init__(self, total: int, enabled: bool) -> None:
        self.saved = 0
        self._bar = None
        if enabled and total:
            from tqdm import tqdm

            self._bar = tqdm(
                total=total,
                unit="mesh",
                desc="meshbits batch",
                file=sys.stderr,
                dynamic_ncols=True,
                smoothing=0.1,
            )

    def update(self, row: BatchRow) -> None:
        self.saved += row.saved_bytes or 0
        if self._bar is not None:
            failed = "" if row.status in _DONE else f", {row.status}: {row.relative}"
            self._bar.set_postfix_str(f"saved {_bytes_text(self.saved)}{failed}", refresh=False)
            self._bar.update(1)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()


# --- summary and plot ------------------------------------------------------------------------


def _summary_rows(result: BatchResult, started: str) -> list[tuple[str, Any]]:
    rows = [r for r in result.rows if r.output is not None]
    peaks = [r.peak_rss_bytes for r in result.rows if r.peak_rss_bytes is not None]
    ratio = result.output_bytes / result.input_bytes if result.input_bytes else None
    return [
        ("started", started),
        ("finished", _now()),
        ("meshbits", _core.__version__),
        ("exit_code", result.exit_code),
        ("interrupted", result.interrupted),
        ("inputs", result.inputs),
        ("ran", result.ran),
        ("resumed", result.resumed),
        ("not_reached", result.not_reached),
        ("met", result.met),
        ("unmet", result.unmet),
        ("unusable", result.unusable),
        ("internal_errors", result.internal_errors),
        ("ignored_files", sum(result.ignored.values())),
        ("ignored_by_suffix", json.dumps(result.ignored, sort_keys=True)),
        ("duplicate_inputs", result.duplicates),
        ("blank_manifest_rows", result.blank_manifest_rows),
        ("earlier_rows", result.earlier_rows),
        ("unreadable_report_lines", result.unreadable_report_lines),
        ("outputs", len(rows)),
        ("input_bytes", result.input_bytes),
        ("output_bytes", result.output_bytes),
        ("saved_bytes", result.saved_bytes),
        ("output_to_input_ratio", "" if ratio is None else f"{ratio:.6g}"),
        ("seconds", f"{result.seconds:.3f}"),
        ("task_seconds", f"{sum(r.seconds for r in result.rows if not r.resumed):.3f}"),
        (
            "task_cpu_seconds",
            f"{sum(r.cpu_seconds or 0.0 for r in result.rows if not r.resumed):.3f}",
        ),
        ("peak_rss_max_bytes", max(peaks) if peaks else ""),
        ("backend", result.backend),
        ("workers", result.workers),
        ("kernel_threads", result.kernel_threads),
        ("options", json.dumps(result.options, sort_keys=True)),
    ]


def _write_summary(path: Path, result: BatchResult, started: str) -> None:
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(("metric", "value"))
    writer.writerows(_summary_rows(result, started))
    write_atomic(path, buffer.getvalue().encode())


def _write_plot(path: Path, result: BatchResult) -> bool:
    """``meshbits-report.png``: bytes saved and error per file; False without matplotlib."""
    try:
        from .plot import _figure
    except ImportError:  # pragma: no cover - matplotlib is an optional extra
        return False
    try:
        fig = _figure((1200, 800), 100)
    except ImportError:
        return False
    done = sorted(
        (r for r in result.rows if r.output is not None and r.input_bytes is not None),
        key=lambda r: r.input_bytes or 0,
    )
    top, bottom = fig.subplots(2, 1, sharex=True)
    x = list(range(len(done)))
    saved = [(r.saved_bytes or 0) / 1e3 for r in done]
    colours = ["tab:green" if r.met else "tab:red" for r in done]
    top.bar(x, saved, width=0.9, color=colours)
    top.set_ylabel("bytes saved (kB)")
    top.set_title(
        f"{len(done)} outputs: {_bytes_text(result.input_bytes)} -> "
        f"{_bytes_text(result.output_bytes)} (saved {_bytes_text(result.saved_bytes)}); "
        f"{result.met} met, {result.unmet} unmet (red), {result.unusable} unusable, "
        f"{result.internal_errors} internal errors (not shown)",
        fontsize=10,
    )
    if result.options.get("error") is not None:
        values = [
            (r.error or 0.0) / r.budget if r.budget and r.error is not None else 0.0 for r in done
        ]
        bottom.axhline(1.0, color="black", linewidth=0.8, linestyle="--")
        bottom.set_ylim(bottom=0.0, top=max([1.05, *(1.05 * v for v in values)]))
        bottom.set_ylabel("measured error / budget")
    else:
        values = [r.error or 0.0 for r in done]
        bottom.set_ylabel("measured error (file units)")
        if any(v > 0 for v in values):
            bottom.set_yscale("log")
    bottom.scatter(x, values, c=colours, s=12)
    bottom.set_xlabel("file, by input size (smallest first)")
    if len(done) <= 40:
        bottom.set_xticks(x)
        bottom.set_xticklabels([r.relative for r in done], rotation=60, ha="right", fontsize=7)
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png")
    write_atomic(path, buffer.getvalue())
    return True


# --- the batch -------------------------------------------------------------------------------


def _options(
    error: float | str | None,
    size: float | str | None,
    relative: bool,
    format: str,
    codec: str,
    seed: int,
    max_iterations: int,
) -> dict[str, Any]:
    from .units import parse_length, parse_size

    if (error is None) == (size is None):
        raise MeshbitsError("give exactly one of error, size")
    if relative and error is None:
        raise MeshbitsError("relative applies to an error budget only")
    if isinstance(error, str):
        if relative and error.strip()[-1:].isalpha():
            raise MeshbitsError(
                f"error {error!r} has a unit, and relative makes it a fraction of S: give a "
                "plain number with relative, or drop relative"
            )
        error = parse_length(error)
    size_bits = parse_size(size) if isinstance(size, str) else size
    for name, value in (("error", error), ("size", size_bits)):
        if value is not None and not (
            isinstance(value, (int, float)) and math.isfinite(value) and value > 0
        ):
            raise MeshbitsError(f"the {name} budget must be a positive finite number, got {value}")
    if format not in FORMATS:
        raise MeshbitsError(f"format must be one of {FORMATS}, got {format!r}")
    if codec not in CODECS:
        raise MeshbitsError(f"codec must be one of {CODECS}, got {codec!r}")
    if codec != "draco" and format not in SCENE_FORMATS:
        raise MeshbitsError(f"the {codec} codec applies to glb and gltf outputs, not {format}")
    if not isinstance(seed, int) or seed < 0:
        raise MeshbitsError(f"seed must be a whole number >= 0, got {seed!r}")
    if not isinstance(max_iterations, int) or max_iterations < 1:
        raise MeshbitsError(f"max_iterations must be a whole number >= 1, got {max_iterations!r}")
    return _normalised(
        {
            "format": format,
            "codec": codec,
            "error": None if error is None else float(error),
            "relative": bool(relative),
            "size_bits": None if size_bits is None else float(size_bits),
            "seed": seed,
            "max_iterations": max_iterations,
        }
    )


def _out_dir(path: Path) -> Path:
    """Make the output folder (its parent must exist) and check that it can be written."""
    if path.exists() and not path.is_dir():
        raise MeshbitsError(f"cannot write to {path}: it is a file, not a folder")
    if not path.parent.is_dir():
        raise MeshbitsError(f"cannot make {path}: the folder {path.parent} does not exist")
    path.mkdir(exist_ok=True)
    if not os.access(path, os.W_OK | os.X_OK):
        raise MeshbitsError(f"cannot write to {path}: the folder is not writable")
    return path


def batch(
    source: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    *,
    error: float | str | None = None,
    size: float | str | None = None,
    relative: bool = False,
    format: str = "drc",
    codec: str = "draco",
    seed: int = 0,
    max_iterations: int = 6,
    workers: int | None = None,
    dask: str | None = None,
    force: bool = False,
    progress: bool = False,
) -> BatchResult:
    """Compress every mesh of a library to one budget, in parallel, with a report.

    Parameters
    ----------
    source
        A folder (searched recursively for ``.ply .ply.gz .obj .stl .off .glb .gltf .drc``), a
        glob pattern, a manifest (``.csv`` with a ``path`` column or ``.jsonl`` with a
        ``"path"`` key; relative paths are relative to the manifest), or one mesh file.
    out_dir
        Output folder (made if missing; its parent must exist). Outputs mirror the
        inputs' sub-folders; the report, summary and plot are written in it.
    error
        Hausdorff error budget of every input, in each file's length units (a scene's
        world units), or a fraction of its largest bounding-box side with ``relative``;
        or a text with a unit (``"5cm"``, read by :func:`meshbits.parse_length` as meters,
        glTF's unit, and as the units of a file that names none).
    size
        Size budget of every output: bits, or a text with a unit (``"100KB"``).
    relative
        ``error`` is a fraction of each input's size S.
    format
        ``"drc"`` (Draco) or ``"ply"`` (quantized PLY) through :func:`meshbits.compress`,
        ``"glb"`` or ``"gltf"`` through :func:`meshbits.compress_scene`.
    codec
        ``"draco"`` or ``"meshopt"`` (glb/gltf only).
    seed
        Seed of every measurement (each input is compressed with it: results do not
        depend on the order or the worker).
    max_iterations
        Passes of :func:`meshbits.compress`'s search at most (drc/ply).
    workers
        Processes: 1 runs the tasks in this process with the kernels on every core;
        N > 1 starts N spawned workers with the kernels on ``cores // N`` threads each;
        None: one per core, at most one per input. Scripts must call :func:`batch` under
        ``if __name__ == "__main__":`` (spawned workers import the main module).
    dask
        Run on Dask distributed instead: a scheduler address (``tcp://host:8786``; the
        inputs and ``out_dir`` must be at the same paths on the workers), or
        ``"local:N"`` for a LocalCluster of N worker processes. Needs ``meshbits[dask]``.
    force
        Redo every input, even those whose output and report row are up to date.
    progress
        Show a progress bar on stderr (count, ETA, bytes saved).

    Returns
    -------
    BatchResult
        Its ``exit_code`` is the ``meshbits batch`` exit code.

    Raises
    ------
    MeshbitsError
        Bad options, no input found, a manifest that cannot be read, an output folder
        that cannot be made or written (before any input is read).
    BatchInterrupted
        Ctrl-C (a ``KeyboardInterrupt``): the report and summary of what finished were
        written; its ``result`` holds them.
    """
    started_at = time.perf_counter()
    started = _now()
    options = _options(error, size, relative, format, codec, seed, max_iterations)
    if workers is not None and (not isinstance(workers, int) or workers < 1):
        raise MeshbitsError(f"workers must be a whole number >= 1, got {workers!r}")
    if dask is not None:
        if workers is not None:
            raise MeshbitsError("give workers or dask, not both (local:N sets Dask's workers)")
        _parse_dask(dask)
    out = _out_dir(Path(out_dir).expanduser())
    found = find_inputs(source, exclude=out)
    if not found.paths:
        inside = found.ignored.get(IN_OUTPUT_FOLDER, 0)
        ignored = sum(found.ignored.values()) - inside
        raise MeshbitsError(
            f"no mesh files in {os.fspath(source)} ({', '.join(MESH_SUFFIXES)})"
            + (f"; {ignored} other files ignored" if ignored else "")
            + (
                f"; {inside} mesh file{'' if inside == 1 else 's'} inside the output folder "
                f"{os.fspath(out_dir)}, whose files are never inputs: write the outputs to "
                "another folder"
                if inside
                else ""
            )
        )
    names = _output_names(found, out.resolve(), options["format"])
    tasks = [
        _Task(
            index=i,
            path=str(path),
            relative=relative_in,
            output=str(out.resolve() / relative_out),
            output_relative=relative_out,
            options=options,
        )
        for i, (path, (relative_in, relative_out)) in enumerate(
            zip(found.paths, names, strict=True)
        )
    ]

    report = _Report(out)
    earlier = report.read()
    ours = {t.relative for t in tasks}
    foreign = [row for key, row in earlier.items() if key not in ours]
    resumed: dict[int, BatchRow] = {}
    for task in tasks:
        row = earlier.get(task.relative)
        if force or row is None or row.status not in _DONE or row.output is None:
            continue
        if row.options != options or not (out / row.output).is_file():
            continue
        try:
            same = input_digest(task.path) == row.input_sha256
        except OSError:
            same = False
        if same:
            resumed[task.index] = dataclasses.replace(row, path=task.path, resumed=True)
    to_run = [t for t in tasks if t.index not in resumed]

    finished: dict[int, BatchRow] = {}
    interrupted = False
    runner: Any = None
    bar = _Progress(len(to_run), progress)
    report.start([*foreign, *resumed.values()])
    try:
        if to_run:
            count = min(workers or _cores(), len(to_run))
            if dask is not None:
                runner = _Dask(dask)
            elif count == 1:
                runner = _Serial()
            else:
                runner = _Processes(count, max(1, _cores() // count))
            by_relative = {t.relative: t for t in to_run}
            for data in runner.results(to_run):
                row = BatchRow.from_dict(data)
                # Counted before it is written, so that a Ctrl-C between the two cannot
                # leave a row in the report that the summary does not count.
                finished[by_relative[row.relative].index] = row
                report.append(row.to_dict())
                bar.update(row)
    except KeyboardInterrupt:
        interrupted = True
    finally:
        bar.close()
        report.close()
        if runner is not None:
            runner.close(interrupted)

    rows = tuple(
        (resumed.get(t.index) or finished[t.index])
        for t in tasks
        if t.index in resumed or t.index in finished
    )
    statuses = Counter(r.status for r in rows)
    written = [r for r in rows if r.output is not None and r.input_bytes is not None]
    input_bytes = sum(r.input_bytes or 0 for r in written)
    output_bytes = sum(r.output_bytes or 0 for r in written)
    result = BatchResult(
        rows=rows,
        out_dir=str(out),
        report=str(report.path),
        summary=str(out / SUMMARY_NAME),
        plot=None,
        backend=runner.backend if runner is not None else "none",
        workers=runner.workers if runner is not None else 0,
        kernel_threads=max(0, runner.threads) if runner is not None else 0,
        inputs=len(tasks),
        ran=len(finished),
        resumed=len(resumed),
        met=statuses["met"],
        unmet=statuses["unmet"],
        unusable=statuses["unusable"],
        internal_errors=statuses["internal_error"],
        not_reached=len(to_run) - len(finished),
        ignored=found.ignored,
        duplicates=found.duplicates,
        blank_manifest_rows=found.blank,
        earlier_rows=len(foreign),
        unreadable_report_lines=report.unreadable,
        input_bytes=input_bytes,
        output_bytes=output_bytes,
        saved_bytes=input_bytes - output_bytes,
        seconds=time.perf_counter() - started_at,
        interrupted=interrupted,
        options=options,
    )
    if _write_plot(out / PLOT_NAME, result):
        result = dataclasses.replace(result, plot=str(out / PLOT_NAME))
    _write_summary(out / SUMMARY_NAME, result, started)
    if interrupted:
        raise BatchInterrupted(result)
    return result
