"""How many threads the native kernels use.

Results never depend on it: every parallel reduction runs in a fixed order.

By default kernels use every core. A process forked from one that already ran a kernel
(a ``multiprocessing`` pool on Linux, a Celery prefork worker) runs them on one thread
instead, on a pool of its own, so that forked workers neither hang on the parent's pool
nor start cores x workers threads; :func:`set_num_threads` in the child asks for more.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

from . import _core
from .errors import MeshbitsError

__all__ = ["get_num_threads", "set_num_threads", "threads"]


def set_num_threads(count: int) -> None:
    """Run every kernel on ``count`` threads; ``0`` restores the default (all cores, one
    in a forked child)."""
    if not isinstance(count, int) or count < 0:
        raise MeshbitsError(f"thread count must be a non-negative integer, got {count!r}")
    _core.set_num_threads(count)


def get_num_threads() -> int:
    """The count set by :func:`set_num_threads` (``0``: the default, all cores)."""
    return int(_core.get_num_threads())


@contextmanager
def threads(count: int) -> Iterator[None]:
    """Context manager: run kernels on ``count`` threads inside the ``with`` block."""
    previous = get_num_threads()
    set_num_threads(count)
    try:
        yield
    finally:
        set_num_threads(previous)
