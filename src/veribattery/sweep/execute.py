"""Where sweep tasks run: in this process, in a local process pool, or on a Dask cluster.

Every executor yields :class:`~veribattery.sweep.tasks.PointResult` objects as points
finish (in any order; the caller puts rows back in grid order). Executors are opened
before the results file is touched, so an unreachable scheduler is bad input that
writes nothing.
"""

from __future__ import annotations

import os
from collections.abc import Generator, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any, Protocol

from veribattery.errors import ConfigError
from veribattery.sweep.tasks import PointResult, Task, iter_task, run_task

if TYPE_CHECKING:
    from distributed import Client

__all__ = ["CONNECT_TIMEOUT_S", "Executor", "default_jobs", "open_executor"]

#: How long to try to reach a Dask scheduler before calling it unreachable.
CONNECT_TIMEOUT_S = 8

#: A task in flight when a local worker process dies this many times is recorded as failed.
_MAX_BREAKS = 3


class Executor(Protocol):
    """Runs tasks and yields their points' results as they finish."""

    description: str

    def results(self, tasks: Sequence[Task]) -> Iterator[PointResult]:
        """Run *tasks*; yield every point's result once."""
        ...


def default_jobs() -> int:
    """The number of cores this process may use."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


@contextmanager
def open_executor(jobs: int, scheduler: str | None) -> Iterator[Executor]:
    """The executor for ``-j JOBS`` and ``--scheduler``, connected, as a context manager.

    :raises ConfigError: (on entering) when the scheduler cannot be reached within
        :data:`CONNECT_TIMEOUT_S` seconds or its address is malformed.
    """
    if scheduler is None:
        yield InProcess() if jobs == 1 else LocalPool(jobs)
        return
    with _dask_client(scheduler, jobs) as client:
        yield DaskExecutor(client, scheduler)


class InProcess:
    """``-j 1``: the points one after another in this process."""

    description = "in this process"

    def results(self, tasks: Sequence[Task]) -> Iterator[PointResult]:
        """Check each task's points in order."""
        for task in tasks:
            yield from iter_task(task)


class LocalPool:
    """``-j N``: a pool of N worker processes on this machine (spawned: no forked threads).

    A worker that dies (killed, out of memory) breaks the pool; the pool is restarted
    and the unfinished tasks resubmitted. A task that was in flight at
    :data:`_MAX_BREAKS` breaks is recorded as failed, so one bad point cannot stop the
    sweep.
    """

    def __init__(self, jobs: int):
        self.jobs = jobs
        self.description = f"on {jobs} local worker processes"

    def results(self, tasks: Sequence[Task]) -> Iterator[PointResult]:
        """Run the tasks in the pool, yielding each task's points when it finishes."""
        if len(tasks) <= 1:
            yield from InProcess().results(tasks)
            return
        pending, breaks = list(tasks), [0] * len(tasks)
        order = {id(task): i for i, task in enumerate(tasks)}
        while pending:
            pending = yield from self._round(pending, breaks, order)

    def _round(
        self, pending: list[Task], breaks: list[int], order: dict[int, int]
    ) -> Generator[PointResult, None, list[Task]]:
        """One pool's life: run until done or broken; return the tasks still to run."""
        import multiprocessing

        context = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(min(self.jobs, len(pending)), mp_context=context) as pool:
            futures: dict[Future[list[PointResult]], Task] = {
                pool.submit(run_task, task): task for task in pending}
            try:
                while futures:
                    done, _ = wait(futures, return_when=FIRST_COMPLETED)
                    for future in done:
                        results = future.result()  # raises if the pool broke: keep the task
                        futures.pop(future)
                        yield from results
            except BrokenProcessPool:
                return (yield from _after_break(list(futures.values()), breaks, order))
            except BaseException:
                pool.shutdown(wait=False, cancel_futures=True)
                raise
        return []


def _after_break(
    unfinished: list[Task], breaks: list[int], order: dict[int, int]
) -> Generator[PointResult, None, list[Task]]:
    """Tasks to retry after a worker died; those in flight too often are recorded failed."""
    retry = []
    for task in unfinished:
        breaks[order[id(task)]] += 1
        if breaks[order[id(task)]] < _MAX_BREAKS:
            retry.append(task)
        else:
            yield from (PointResult(index, error="a worker process died on this point "
                                    "(killed, or out of memory)") for index, _ in task.points)
    return retry


class DaskExecutor:
    """``--scheduler``: tasks on a Dask distributed cluster, resubmitted if a worker dies."""

    def __init__(self, client: Client, scheduler: str):
        self.client = client
        workers = len(client.scheduler_info().get("workers", {}))
        self.description = f"on Dask scheduler {scheduler} ({workers} workers)"

    def results(self, tasks: Sequence[Task]) -> Iterator[PointResult]:
        """Submit every task; yield each one's points as it completes."""
        from distributed import as_completed

        futures = {self.client.submit(run_task, task, pure=False): task for task in tasks}
        try:
            for future in as_completed(futures):  # type: ignore[no-untyped-call]
                yield from _gathered(future, futures[future])
        finally:
            self.client.cancel(list(futures))  # type: ignore[no-untyped-call]


def _gathered(future: Any, task: Task) -> Iterator[PointResult]:
    """The task's results, or every point recorded as failed when Dask gave up on it."""
    try:
        results: list[PointResult] = future.result()
    except Exception as exc:  # KilledWorker after repeated deaths, a worker out of memory, ...
        message = f"worker failed: {type(exc).__name__}: {' '.join(str(exc).split())}"
        yield from (PointResult(index, error=message) for index, _ in task.points)
        return
    yield from results


@contextmanager
def _dask_client(scheduler: str, jobs: int) -> Iterator[Client]:
    """A client of the scheduler at *scheduler*, or of a new loopback ``LocalCluster``."""
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise ConfigError("--scheduler needs Dask: pip install 'veribattery[dask]'") from None
    if scheduler == "local":
        with LocalCluster(  # type: ignore[no-untyped-call]
            n_workers=jobs, threads_per_worker=1, processes=True, host="127.0.0.1",
            dashboard_address=None,
        ) as cluster, Client(cluster) as client:  # type: ignore[no-untyped-call]
            yield client
        return
    try:
        client = Client(scheduler, timeout=CONNECT_TIMEOUT_S)  # type: ignore[no-untyped-call]
    except (OSError, TimeoutError, ValueError, TypeError) as exc:
        reason = " ".join(str(exc).split()) or type(exc).__name__
        raise ConfigError(f"--scheduler {scheduler}: cannot reach the Dask scheduler "
                          f"({reason})") from None
    with client:
        yield client
