"""Where the tasks run: in this process, in a pool of spawned worker processes, or on Dask
distributed. Each runner yields the tasks' rows as they finish."""

from __future__ import annotations

import dataclasses
import logging
import multiprocessing
import os
import signal
from collections import Counter, deque
from collections.abc import Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Any

from ..errors import MeshbitsError, one_line
from ..threads import get_num_threads
from .task import Task, available_cores, failed_row, run_task, set_worker_threads

__all__ = [
    "LOCAL_CLUSTER_CONFIG",
    "WORKER_DEATH_RETRIES",
    "DaskRunner",
    "ProcessRunner",
    "SerialRunner",
    "parse_dask",
    "start_runner",
]

#: Times a task is tried again after its worker process died under it (killed for memory,
#: crashed), before it is recorded as an internal error.
WORKER_DEATH_RETRIES = 1


class SerialRunner:
    """Tasks in this process, one after the other, kernels on every core."""

    backend = "serial"

    def __init__(self) -> None:
        self.workers = 1
        self.threads = get_num_threads() or available_cores()

    def results(self, tasks: Sequence[Task]) -> Iterator[dict[str, Any]]:
        for task in tasks:
            yield run_task(task)

    def close(self, interrupted: bool) -> None:
        pass


def _init_worker(threads: int) -> None:
    """Initializer of a pool worker: Ctrl-C is the parent's to handle (it stops the pool),
    and kernels run on ``threads`` threads."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    set_worker_threads(threads)


class ProcessRunner:
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

    def results(self, tasks: Sequence[Task]) -> Iterator[dict[str, Any]]:
        queue = deque(tasks)
        deaths: Counter[int] = Counter()
        pool = self._start()
        running: dict[Future[dict[str, Any]], Task] = {}
        while queue or running:
            while queue and len(running) < self.workers:
                task = queue.popleft()
                running[pool.submit(run_task, task)] = task
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
                    yield failed_row(
                        task,
                        f"internal error: the worker failed: {type(err).__name__}: {one_line(err)}",
                    )
            if broken:
                wait(running)  # every task in flight fails with the pool
                suspects = list(running.values())
                running.clear()
                self._kill(pool)
                for task in reversed(suspects):
                    deaths[task.index] += 1
                    if deaths[task.index] > WORKER_DEATH_RETRIES:
                        yield failed_row(
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


def parse_dask(address: str) -> int | None:
    """``local:N`` -> N; an address -> None."""
    if address.startswith("local:"):
        count = address[len("local:") :]
        if not count.isdigit() or int(count) < 1:
            raise MeshbitsError(f"--dask local:N needs a whole number N >= 1, got {address!r}")
        return int(count)
    if not address.strip():
        raise MeshbitsError("the Dask address is empty")
    return None


#: Dask settings of a LocalCluster started by ``--dask local:N`` (see :class:`DaskRunner`).
LOCAL_CLUSTER_CONFIG = {
    "distributed.worker.profile.enabled": False,
    "distributed.admin.system-monitor.gil.enabled": False,
    "distributed.scheduler.worker-saturation": float("inf"),
}


class DaskRunner:
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
        count = parse_dask(address)
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
            self.threads = max(1, available_cores() // count)
        else:
            try:
                self._client = Client(address, timeout="30s")
            except (OSError, TimeoutError) as err:
                raise MeshbitsError(f"cannot reach the Dask scheduler at {address}: {err}") from err
            self.threads = -1
        self.workers = len(self._client.scheduler_info().get("workers", {})) or (count or 0)

    def results(self, tasks: Sequence[Task]) -> Iterator[dict[str, Any]]:
        from distributed import as_completed

        token = os.urandom(4).hex()
        by_key = {}
        for task in tasks:
            future = self._client.submit(
                run_task,
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
                row = failed_row(
                    task,
                    f"internal error: the Dask task failed: {type(err).__name__}: {one_line(err)}",
                )
            future.release()
            yield row

    def close(self, interrupted: bool) -> None:
        if interrupted and self._futures:
            self._client.cancel(self._futures)
        self._client.close()
        if self._cluster is not None:
            self._cluster.close()


def start_runner(
    tasks: int, workers: int | None, dask: str | None
) -> SerialRunner | ProcessRunner | DaskRunner:
    """The runner of ``tasks`` tasks: Dask with an address; else ``workers`` processes (None:
    one per core), never more than the tasks, and this process for one."""
    count = min(workers or available_cores(), tasks)
    if dask is not None:
        return DaskRunner(dask)
    if count == 1:
        return SerialRunner()
    return ProcessRunner(count, max(1, available_cores() // count))
