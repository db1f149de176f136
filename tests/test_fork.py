"""Kernels in processes forked after the parent ran them (multiprocessing on Linux, Celery
prefork workers): they must neither hang nor change their results."""

from __future__ import annotations

import multiprocessing
import os
import sys
import warnings
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

import meshbits

pytestmark = pytest.mark.skipif(
    sys.platform == "win32" or not hasattr(os, "fork"), reason="needs fork"
)

#: Seconds a forked child may take before it counts as hung (each call takes well under 1 s).
TIMEOUT = 60


def _kernels(mesh: tuple[np.ndarray, np.ndarray]) -> dict[str, Callable[[], Any]]:
    """One call per kernel entry; each returns something comparable across processes."""
    vertices = mesh[0]
    return {
        "shape_complexity": lambda: meshbits.shape_complexity(mesh).k,
        "quantize": lambda: meshbits.quantize(vertices, 10).codes.sum(dtype=np.int64),
        "cluster": lambda: meshbits.cluster(mesh, bits=8).faces.shape,
        "hausdorff": lambda: (
            meshbits.hausdorff(mesh, meshbits.cluster(mesh, bits=9), samples=20_000).distance
        ),
        "closest_points": lambda: float(
            meshbits.ClosestPoints(mesh).query(vertices[:5000] + 0.001).distances.sum()
        ),
        "surface_samples": lambda: meshbits.surface_samples(mesh, samples=50_000).points.sum(),
        "compress": lambda: meshbits.compress(mesh, vertices=2000).size_bits,
    }


def _in_forked_child(call: Callable[[], Any]) -> Any:
    """Run ``call`` in a forked child; fail if it does not finish within TIMEOUT."""
    context = multiprocessing.get_context("fork")
    queue = context.SimpleQueue()

    def child() -> None:
        try:
            queue.put(("ok", call()))
        except BaseException as err:  # reported to the parent, which fails the test
            queue.put(("error", repr(err)))

    with warnings.catch_warnings():
        # Python >= 3.12 warns that forking a multi-threaded process may deadlock: that is
        # the very case under test.
        warnings.simplefilter("ignore", DeprecationWarning)
        process = context.Process(target=child)
        process.start()
    process.join(TIMEOUT)
    if process.is_alive():
        process.kill()
        process.join()
        pytest.fail(f"the forked child hung (no result after {TIMEOUT} s)")
    assert process.exitcode == 0
    status, value = queue.get()
    assert status == "ok", value
    return value


@pytest.mark.parametrize(
    "kernel",
    [
        "shape_complexity",
        "quantize",
        "cluster",
        "hausdorff",
        "closest_points",
        "surface_samples",
        "compress",
    ],
)
def test_forked_child_runs_every_kernel(horse, kernel):
    # horse has 96,966 faces: above the size where the kernels' loops go parallel.
    call = _kernels(horse)[kernel]
    in_parent = call()  # starts the parent's thread pool before the fork
    assert _in_forked_child(call) == in_parent


def test_forked_pool_of_workers(horse):
    """The reported case: a fork Pool(2) whose workers run K after the parent did."""
    expected = meshbits.shape_complexity(horse).k
    context = multiprocessing.get_context("fork")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        with context.Pool(2) as pool:
            pending = pool.map_async(_complexity_of_horse, range(4))
            got = pending.get(timeout=TIMEOUT)
    assert got == [expected] * 4


def _complexity_of_horse(_: int) -> float:
    from conftest import load

    return meshbits.shape_complexity(load("horse.ply")).k


def test_forked_child_may_ask_for_more_threads(horse):
    meshbits.shape_complexity(horse)

    def call() -> tuple[int, float]:
        meshbits.set_num_threads(2)
        try:
            return meshbits.get_num_threads(), meshbits.shape_complexity(horse).k
        finally:
            meshbits.set_num_threads(0)

    threads, k = _in_forked_child(call)
    assert threads == 2 and k == meshbits.shape_complexity(horse).k
