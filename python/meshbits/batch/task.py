"""One input's job: compress it, write its output, and return its report row (a dict, so
that it crosses a process or a Dask worker as plain data). Every failure is recorded in
the row, never raised."""

from __future__ import annotations

import os
import socket
import sys
import time
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .. import _core
from ..compress import compress
from ..errors import MeshbitsError, one_line
from ..files import asset_bytes
from ..formats import load_mesh
from ..scene import compress_scene, merged_away
from ..threads import set_num_threads
from ..units import in_unit, length_unit_of
from .inputs import input_digest
from .report import utc_now

__all__ = [
    "CODECS",
    "FORMATS",
    "SCENE_FORMATS",
    "Task",
    "available_cores",
    "failed_row",
    "run_task",
    "set_worker_threads",
]

#: Output formats: ``drc`` and ``ply`` through :func:`meshbits.compress` (one merged
#: mesh), ``glb`` and ``gltf`` through :func:`meshbits.compress_scene` (the whole scene).
FORMATS = ("drc", "ply", "glb", "gltf")
SCENE_FORMATS = ("glb", "gltf")
CODECS = ("draco", "meshopt", "auto")


@dataclass(frozen=True)
class Task:
    """One input's job: its paths, its output and the batch's options."""

    index: int
    path: str
    relative: str
    output: str  # absolute
    output_relative: str
    options: dict[str, Any]
    #: Kernel threads to set in the worker: None leaves them, -1 lets a Dask worker pick
    #: ``cores // its task threads``.
    threads: int | None = None


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


def set_worker_threads(threads: int | None) -> None:
    """Kernel threads of this worker process (see :class:`Task`), set once."""
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
        count = max(1, available_cores() // slots)
    set_num_threads(count)
    _threads_set = threads


def run_task(task: Task) -> dict[str, Any]:
    """Compress one input and write its output; return its report row as a dict. Every
    failure is caught and recorded: a refused input or file-system error as
    ``"unusable"``, anything else as ``"internal_error"`` with the traceback."""
    set_worker_threads(task.threads)
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
    try:
        path = Path(task.path)
        if not path.is_file():
            raise FileNotFoundError(f"no such file: {path}")
        row["input_bytes"] = asset_bytes(path)
        row["input_sha256"] = input_digest(path)
        output = Path(task.output)
        output.parent.mkdir(parents=True, exist_ok=True)
        if options["format"] in SCENE_FORMATS:
            row |= _scene_row(path, output, options, row["input_bytes"])
        else:
            row |= _mesh_row(path, output, options)
        row["output"] = task.output_relative
        row["status"] = "met" if row["met"] else "unmet"
        if row["met"]:
            row["message"] = None
    except (MeshbitsError, OSError) as err:
        # A refused input (corrupt, empty, no triangles) or a file system that refused a
        # read or a write.
        row |= {"status": "unusable", "met": False, "message": one_line(err)}
    except Exception as err:  # a bug in meshbits: recorded, the batch goes on
        row |= {
            "status": "internal_error",
            "met": False,
            "message": f"internal error: {type(err).__name__}: {one_line(err)}",
            "traceback": traceback.format_exc(),
        }
    row["seconds"] = time.perf_counter() - start
    row["cpu_seconds"] = time.process_time() - cpu_start
    row["peak_rss_bytes"] = _peak_rss()
    row["peak_rss_scope"] = "task" if scoped else "process"
    row["finished"] = utc_now()
    return row


def failed_row(task: Task, message: str, *, trace: str | None = None) -> dict[str, Any]:
    """The row of a task whose worker failed outside :func:`run_task`."""
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
        "finished": utc_now(),
        "meshbits": _core.__version__,
    }


def available_cores() -> int:
    """The cores this process may run on (its CPU affinity where the system has one)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - macOS, Windows
        return os.cpu_count() or 1


# --- runners ---------------------------------------------------------------------------------


def _scene_row(
    path: Path, output: Path, options: dict[str, Any], input_bytes: int
) -> dict[str, Any]:
    """Compress a scene to .glb / .gltf with :func:`meshbits.compress_scene`: the row's
    outcome fields (a size budget in bytes)."""
    size = options["size_bits"]
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
    return {
        "met": scene.met,
        "message": in_unit(scene.message, length_unit_of(path)),
        "budget": scene.budget if size is None else scene.budget / 8,
        "input_bytes": scene.input_bytes or input_bytes,
        "output_bytes": scene.size_bytes,
        "bits": max((p.bits for p in compressed), default=None),
        "vertices": sum(p.vertices for p in scene.primitives),
        "faces": sum(p.faces for p in scene.primitives),
        "input_vertices": sum(p.input_vertices for p in scene.primitives),
        "error": scene.world_error,
        "error_upper": scene.world_error_upper,
    }


def _mesh_row(path: Path, output: Path, options: dict[str, Any]) -> dict[str, Any]:
    """Compress a file as one merged mesh to .drc / .ply with :func:`meshbits.compress`:
    the row's outcome fields (a size budget in bytes)."""
    size = options["size_bits"]
    away = merged_away(path)
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
    return {
        "merged_away": away,
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
