"""The batch itself: check the options, find the inputs, keep what an earlier run did,
run the rest, and report."""

from __future__ import annotations

import dataclasses
import os
import time
from collections import Counter
from pathlib import Path
from typing import Any

from ..budget import Budget
from ..errors import MeshbitsError
from .inputs import IN_OUTPUT_FOLDER, MESH_SUFFIXES, Inputs, find_inputs, input_digest, output_names
from .report import (
    DONE_STATUSES,
    PLOT_NAME,
    SUMMARY_NAME,
    BatchInterrupted,
    BatchResult,
    BatchRow,
    ProgressBar,
    ReportFile,
    normalised_options,
    utc_now,
    write_plot,
    write_summary,
)
from .runners import parse_dask, start_runner
from .task import CODECS, FORMATS, SCENE_FORMATS, Task

__all__ = ["batch", "batch_options"]


def batch_options(
    error: float | str | None,
    size: float | str | None,
    relative: bool,
    format: str,
    codec: str,
    seed: int,
    max_iterations: int,
) -> dict[str, Any]:
    """The options every input of a batch is compressed with, checked, as its report
    stores them (a resumed row must have the same): an error (mesh units, or meters when
    typed with a unit; a fraction of S with ``relative``) or a size in bits.

    Raises
    ------
    MeshbitsError
        Not exactly one positive budget, or another option out of its range.
    """
    budget = Budget.from_options(
        error=error,
        size=size,
        relative=relative,
        kinds=("error", "size"),
        parse_text=True,
        refuse_stray_relative=True,
    )
    if format not in FORMATS:
        raise MeshbitsError(f"format must be one of {FORMATS}, got {format!r}")
    if codec not in CODECS:
        raise MeshbitsError(f"codec must be one of {CODECS}, got {codec!r}")
    if codec not in ("draco", "auto") and format not in SCENE_FORMATS:
        raise MeshbitsError(f"the {codec} codec applies to glb and gltf outputs, not {format}")
    if not isinstance(seed, int) or seed < 0:
        raise MeshbitsError(f"seed must be a whole number >= 0, got {seed!r}")
    if not isinstance(max_iterations, int) or max_iterations < 1:
        raise MeshbitsError(f"max_iterations must be a whole number >= 1, got {max_iterations!r}")
    return normalised_options(
        {
            "format": format,
            "codec": codec if format in SCENE_FORMATS else "draco",
            "error": budget.value if budget.kind == "error" else None,
            "relative": budget.relative,
            "size_bits": budget.value if budget.kind == "size" else None,
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
    codec: str = "auto",
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
        ``"auto"`` (both tried on each glb/gltf output, the better file kept: see
        :func:`meshbits.compress_scene`), ``"draco"`` or ``"meshopt"`` (glb/gltf only; a
        drc/ply output is Draco or PLY whatever is given).
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
    started = utc_now()
    options = batch_options(error, size, relative, format, codec, seed, max_iterations)
    _check_runner(workers, dask)
    out = _out_dir(Path(out_dir).expanduser())
    found = _inputs(source, out_dir, out)
    tasks = _tasks(found, out, options)
    report = ReportFile(out)
    foreign, resumed, to_run = _start_report(tasks, report, out, options, force)
    finished, runner, interrupted = _run(to_run, report, workers, dask, progress)
    result = _result(
        tasks=tasks,
        found=found,
        out=out,
        report=report,
        foreign=foreign,
        resumed=resumed,
        finished=finished,
        runner=runner,
        seconds=time.perf_counter() - started_at,
        interrupted=interrupted,
        options=options,
    )
    return _finish(result, out, started)


def _check_runner(workers: int | None, dask: str | None) -> None:
    """``workers`` a whole number >= 1 or None; ``dask`` a valid address, not with ``workers``."""
    if workers is not None and (not isinstance(workers, int) or workers < 1):
        raise MeshbitsError(f"workers must be a whole number >= 1, got {workers!r}")
    if dask is not None:
        if workers is not None:
            raise MeshbitsError("give workers or dask, not both (local:N sets Dask's workers)")
        parse_dask(dask)


def _start_report(
    tasks: list[Task],
    report: ReportFile,
    out: Path,
    options: dict[str, Any],
    force: bool,
) -> tuple[list[BatchRow], dict[int, BatchRow], list[Task]]:
    """Start the report with the earlier rows it keeps, and return them and the tasks left
    to run: the rows of inputs not in this batch (kept as they are), the rows resumed
    instead of run again, by task index (see :func:`_resumed`), and the other tasks."""
    earlier = report.read()
    ours = {t.relative for t in tasks}
    foreign = [row for key, row in earlier.items() if key not in ours]
    resumed = _resumed(tasks, earlier, out, options, force)
    to_run = [t for t in tasks if t.index not in resumed]
    report.start([*foreign, *resumed.values()])
    return foreign, resumed, to_run


def _finish(result: BatchResult, out: Path, started: str) -> BatchResult:
    """Write the plot (when it can be drawn; the result then names it) and the summary;
    raise :class:`BatchInterrupted` with the result if Ctrl-C stopped the run."""
    if write_plot(out / PLOT_NAME, result):
        result = dataclasses.replace(result, plot=str(out / PLOT_NAME))
    write_summary(out / SUMMARY_NAME, result, started)
    if result.interrupted:
        raise BatchInterrupted(result)
    return result


def _inputs(source: str | os.PathLike[str], out_dir: str | os.PathLike[str], out: Path) -> Inputs:
    """The inputs at ``source``, none inside the output folder ``out``; at least one."""
    found = find_inputs(source, exclude=out)
    if found.paths:
        return found
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


def _tasks(found: Inputs, out: Path, options: dict[str, Any]) -> list[Task]:
    """One task per input, its output mirrored under ``out``."""
    names = output_names(found, out.resolve(), options["format"])
    return [
        Task(
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


def _resumed(
    tasks: list[Task],
    earlier: dict[str, BatchRow],
    out: Path,
    options: dict[str, Any],
    force: bool,
) -> dict[int, BatchRow]:
    """The earlier rows kept, by task index: done with the same options and input bytes,
    their output still there (none with ``force``)."""
    resumed: dict[int, BatchRow] = {}
    for task in tasks:
        row = earlier.get(task.relative)
        if force or row is None or row.status not in DONE_STATUSES or row.output is None:
            continue
        if row.options != options or not (out / row.output).is_file():
            continue
        try:
            same = input_digest(task.path) == row.input_sha256
        except OSError:
            same = False
        if same:
            resumed[task.index] = dataclasses.replace(row, path=task.path, resumed=True)
    return resumed


def _run(
    to_run: list[Task],
    report: ReportFile,
    workers: int | None,
    dask: str | None,
    progress: bool,
) -> tuple[dict[int, BatchRow], Any, bool]:
    """Run the tasks, appending each row to the report as it finishes: the rows by task
    index, the runner (None: nothing ran) and whether Ctrl-C stopped it."""
    finished: dict[int, BatchRow] = {}
    interrupted = False
    runner: Any = None
    bar = ProgressBar(len(to_run), progress)
    try:
        if to_run:
            runner = start_runner(len(to_run), workers, dask)
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
    return finished, runner, interrupted


def _result(
    *,
    tasks: list[Task],
    found: Inputs,
    out: Path,
    report: ReportFile,
    foreign: list[BatchRow],
    resumed: dict[int, BatchRow],
    finished: dict[int, BatchRow],
    runner: Any,
    seconds: float,
    interrupted: bool,
    options: dict[str, Any],
) -> BatchResult:
    """The totals of a batch, its rows in input order (resumed ones included)."""
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
        not_reached=len(tasks) - len(resumed) - len(finished),
        ignored=found.ignored,
        duplicates=found.duplicates,
        blank_manifest_rows=found.blank,
        earlier_rows=len(foreign),
        unreadable_report_lines=report.unreadable,
        input_bytes=input_bytes,
        output_bytes=output_bytes,
        saved_bytes=input_bytes - output_bytes,
        seconds=seconds,
        interrupted=interrupted,
        options=options,
    )
    return result
