"""What a batch reports: a row per input (``meshbits-report.jsonl``, appended as each
finishes), the totals (:class:`BatchResult`, ``meshbits-summary.csv``), a progress bar and
a plot of the bytes saved and the errors (``meshbits-report.png``, with matplotlib)."""

from __future__ import annotations

import csv
import dataclasses
import datetime
import io
import json
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .. import _core
from ..files import write_atomic
from ..plot import figure
from ..results import json_ready
from ..units import length_unit_of

__all__ = [
    "DONE_STATUSES",
    "PLOT_NAME",
    "REPORT_NAME",
    "STATUSES",
    "SUMMARY_NAME",
    "BatchInterrupted",
    "BatchResult",
    "BatchRow",
    "ProgressBar",
    "ReportFile",
    "bytes_text",
    "normalised_options",
    "utc_now",
    "write_plot",
    "write_summary",
]

REPORT_NAME = "meshbits-report.jsonl"
SUMMARY_NAME = "meshbits-summary.csv"
PLOT_NAME = "meshbits-report.png"
#: A row's ``status``: the budget met, not met (the closest result is written), an input
#: that cannot be used (unreadable, corrupt, no triangles; or an output that cannot be
#: written), or a bug in meshbits.
STATUSES = ("met", "unmet", "unusable", "internal_error")
#: Statuses whose output a rerun can keep.
DONE_STATUSES = ("met", "unmet")

_EXIT_OK, _EXIT_UNMET, _EXIT_UNUSABLE, _EXIT_INTERNAL, _EXIT_INTERRUPTED = 0, 1, 2, 3, 130


def utc_now() -> str:
    """The time now, UTC, ISO 8601 to the second."""
    return datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")


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


class ReportFile:
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


def normalised_options(options: dict[str, Any]) -> dict[str, Any]:
    """Options as a report stores them (a JSON round trip), to compare with a row's."""
    return json.loads(json.dumps(json_ready(options), allow_nan=False))


# --- progress --------------------------------------------------------------------------------


def bytes_text(count: float) -> str:
    """A byte count for people: ``"1.23 MB"``, ``"512 B"`` (decimal units)."""
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if abs(count) >= scale:
            return f"{count / scale:.3g} {unit}"
    return f"{count:.0f} B"


class ProgressBar:
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
            failed = "" if row.status in DONE_STATUSES else f", {row.status}: {row.relative}"
            self._bar.set_postfix_str(f"saved {bytes_text(self.saved)}{failed}", refresh=False)
            self._bar.update(1)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()


# --- summary and plot ------------------------------------------------------------------------


def _summary_rows(result: BatchResult, started: str) -> list[tuple[str, Any]]:
    """The (metric, value) rows of the summary."""
    rows = [r for r in result.rows if r.output is not None]
    peaks = [r.peak_rss_bytes for r in result.rows if r.peak_rss_bytes is not None]
    ratio = result.output_bytes / result.input_bytes if result.input_bytes else None
    return [
        ("started", started),
        ("finished", utc_now()),
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


def write_summary(path: Path, result: BatchResult, started: str) -> None:
    """``meshbits-summary.csv``: a ``metric,value`` row per total of ``result``."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(("metric", "value"))
    writer.writerows(_summary_rows(result, started))
    write_atomic(path, buffer.getvalue().encode())


def write_plot(path: Path, result: BatchResult) -> bool:
    """``meshbits-report.png``: bytes saved and error per file; False without matplotlib."""
    try:
        fig = figure((1200, 800), 100)
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
        f"{len(done)} outputs: {bytes_text(result.input_bytes)} -> "
        f"{bytes_text(result.output_bytes)} (saved {bytes_text(result.saved_bytes)}); "
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
