"""Where sweep tasks run: in this process, in a local process pool, or on a Dask cluster.

Every executor yields :class:`~veribattery.sweep.tasks.PointResult` objects as points
finish (in any order; the caller puts rows back in grid order). Executors are opened
before the results file is touched, so an unreachable scheduler is bad input that
writes nothing.
"""

from __future__ import annotations

import gc
import logging
import os
import pickle
import signal
import threading
from collections import deque
from collections.abc import Callable, Generator, Iterable, Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager, suppress
from typing import TYPE_CHECKING, Any, Protocol

from veribattery.errors import ConfigError
from veribattery.mission import ParseCache
from veribattery.sweep.tasks import (
    PointCheck,
    PointResult,
    PointStream,
    Task,
    Worker,
    process_worker,
    run_task,
    start_worker,
)

if TYPE_CHECKING:
    from distributed import Client

__all__ = ["CONNECT_TIMEOUT_S", "Executor", "check_scheduler", "default_jobs", "open_executor"]

#: How long to try to reach a Dask scheduler before calling it unreachable.
CONNECT_TIMEOUT_S = 8

#: A task in flight when a local worker process dies this many times is recorded as failed.
_MAX_BREAKS = 3


class Executor(Protocol):
    """Runs tasks and yields their points' results as they finish."""

    def describe(self, tasks: Sequence[Task]) -> str:
        """Where *tasks* run (``on 2 local worker processes``), for the sweep's note."""
        ...

    def results(self, tasks: Sequence[Task]) -> Iterator[PointResult]:
        """Run *tasks*; yield every point's result once."""
        ...


def default_jobs() -> int:
    """The number of cores this process may use."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def check_scheduler(address: str) -> None:
    """Refuse a ``--scheduler`` that is neither ``local`` nor ``[PROTOCOL://]HOST:PORT``,
    before any cluster is started or reached (Dask's own parse says ``invalid literal
    for int()`` of a port that is no number, after the config has been read).

    :raises ConfigError: naming the option, the address as typed and what is wrong.
    """
    problem = None if address == "local" else _address_problem(address)
    if problem is not None:
        raise ConfigError(f"--scheduler {address}: {problem}; give tcp://HOST:PORT, or local "
                          "for a cluster on this machine")


def _address_problem(address: str) -> str | None:
    protocol, separator, place = address.rpartition("://")
    host, colon, port = place.rpartition(":")
    if separator and not protocol:
        return "no protocol before '://'"
    if not place:
        return "no host and port"
    if not colon or place.endswith("]"):  # ([::1]: an IPv6 host in brackets, no port)
        return "no port"
    if not host:
        return "no host before the port"
    if not port:
        return f"no port after {host}:"
    if not (port.isascii() and port.isdigit()) or not 1 <= int(port) <= 65535:
        return f"the port must be a number (1-65535), not {port!r}"
    return None


@contextmanager
def open_executor(
    jobs: int, scheduler: str | None, parses: ParseCache | None = None
) -> Iterator[Executor]:
    """The executor for ``-j JOBS`` and ``--scheduler``, connected, as a context manager.

    :param parses: the parse cache of the points checked in this process (the sweep's,
        which made their reuse keys: the first point's model is then parsed already).

    :raises ConfigError: (on entering) when the scheduler cannot be reached within
        :data:`CONNECT_TIMEOUT_S` seconds or its address is malformed.
    """
    if scheduler is None:
        yield InProcess(parses) if jobs == 1 else LocalPool(jobs, parses=parses)
        return
    with _dask_client(scheduler, jobs) as client:
        yield DaskExecutor(client, scheduler)


class InProcess:
    """``-j 1``: the points one after another in this process (one :class:`Worker`)."""

    def __init__(self, parses: ParseCache | None = None) -> None:
        self.worker = Worker(parses=parses)

    def describe(self, tasks: Sequence[Task]) -> str:
        """In this process, whatever the tasks."""
        return IN_PROCESS

    def results(self, tasks: Sequence[Task]) -> Iterator[PointResult]:
        """Check each task's points in order."""
        for task in tasks:
            yield from self.worker.results(task)


class LocalPool:
    """``-j N``: a pool of N worker processes on this machine (spawned: no forked threads).

    Workers send each point's result through a queue the moment it is checked, so the
    points of a long structure-reuse task are recorded one by one, and a task cut short
    by a dead worker keeps its finished points. A worker that dies (killed, out of
    memory) breaks the pool; the pool is restarted and the unfinished points run again.
    A point that was in flight at :data:`_MAX_BREAKS` breaks is recorded as failed, so
    one bad point cannot stop the sweep.

    :param check: what checks one point in a worker (tests pass a stand-in).
    :param parses: the parse cache of a lone task, which runs in this process.
    """

    def __init__(self, jobs: int, check: PointCheck | None = None, *,
                 parses: ParseCache | None = None):
        self.jobs = jobs
        self.check = check
        self.parses = parses

    def describe(self, tasks: Sequence[Task]) -> str:
        """The workers really started: no more than there are tasks (``-j 100000`` on
        11 points starts 11), and none for a lone task."""
        workers = min(self.jobs, len(tasks))
        return IN_PROCESS if workers <= 1 else f"on {workers} local worker processes"

    def results(self, tasks: Sequence[Task]) -> Iterator[PointResult]:
        """Run the tasks in the pool, yielding each point's result as it is checked."""
        if len(tasks) <= 1:
            worker = Worker(parses=self.parses)
            yield from (r for task in tasks for r in worker.results(task, self.check))
            return
        pending, seen = list(tasks), _Seen()
        breaks = {index: 0 for task in tasks for index, _ in task.points}
        while pending:
            pending = yield from self._round(pending, seen, breaks)

    def _round(
        self, pending: list[Task], seen: _Seen, breaks: dict[int, int]
    ) -> Generator[PointResult, None, list[Task]]:
        """One pool's life: run until done or broken; return the tasks still to run."""
        import multiprocessing

        context = multiprocessing.get_context("spawn")
        stream = PointStream.open(context)
        started: set[int] = set()
        unsent, running = deque(pending), dict[Future[list[PointResult]], Task]()
        with _interrupts_held() as interrupted, ProcessPoolExecutor(
                min(self.jobs, len(pending)), mp_context=context, initializer=start_worker,
                initargs=(stream, gc.get_threshold())) as pool:
            try:
                _submit(pool, unsent, running, self.check)
                while running:
                    interrupted()  # Ctrl-C raises here, where no executor lock is held
                    yield from seen.fresh(_drained(stream, _POLL_S, started))
                    for future in [f for f in running if f.done()]:
                        results = future.result()  # raises if the pool broke: keep the task
                        running.pop(future)
                        yield from seen.fresh(results)
            except BrokenProcessPool:
                yield from seen.fresh(_drained(stream, 0, started))  # sent before the death
                unfinished = [*running.values(), *unsent]
                return (yield from _after_break(unfinished, seen, started, breaks))
            except BaseException:  # Ctrl-C, or the caller stopped: every finished point
                _stop_workers(pool)  # is recorded already, so stop rather than finish
                raise
            finally:
                stream.close()
        return []


#: How :class:`InProcess` (and a pool given one task) describes where the points run.
IN_PROCESS = "in this process"


@contextmanager
def _interrupts_held() -> Iterator[Callable[[], None]]:
    """While a pool runs, Ctrl-C only notes that it was pressed; the function yielded
    raises KeyboardInterrupt then, at a point the caller chooses.

    Raised wherever the main thread happens to be, KeyboardInterrupt could leave a
    future's lock held (in ``Condition.__enter__``, between taking the lock and
    entering the block), and the executor's thread would wait for that lock forever:
    the sweep would hang at exit. The note stays until the pool is stopped, so a second
    Ctrl-C meanwhile is the same request. Only the main thread handles signals, and a
    SIGINT handler other than Python's default (ignored, say) is left as it is.
    """
    pressed = False

    def note(signum: int, frame: object) -> None:
        nonlocal pressed
        pressed = True

    def interrupted() -> None:
        if pressed:
            raise KeyboardInterrupt

    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGINT) is not signal.default_int_handler):
        yield interrupted
        return
    signal.signal(signal.SIGINT, note)
    try:
        yield interrupted
    except BaseException:
        signal.signal(signal.SIGINT, signal.default_int_handler)
        raise
    signal.signal(signal.SIGINT, signal.default_int_handler)
    interrupted()  # pressed as the last points came in: still an interruption


def _submit(pool: ProcessPoolExecutor, unsent: deque[Task],
            running: dict[Future[list[PointResult]], Task], check: PointCheck | None) -> None:
    """Submit the *unsent* tasks, moving each to *running* once submitted (if the pool
    breaks meanwhile, the two hold every task still to run)."""
    with _sigint_held_from_new_workers():
        while unsent:
            future = pool.submit(run_task, unsent[0], check)
            running[future] = unsent.popleft()


@contextmanager
def _sigint_held_from_new_workers() -> Iterator[None]:
    """Block SIGINT in this thread while worker processes start (a pool starts its on
    submit, a Dask ``LocalCluster`` its nannies and workers at once): they inherit the
    blocked signal, so Ctrl-C, which reaches the whole process group, cannot interrupt
    them even while they import their modules (a pool's initializer then ignores it; a
    Dask worker keeps it blocked, where it printed a KeyboardInterrupt traceback each).
    The sweep's own process handles Ctrl-C and stops the workers; a Ctrl-C meanwhile
    waits, and arrives when the block is lifted.

    multiprocessing's resource tracker is started first: starting it unblocks SIGINT.
    """
    if not hasattr(signal, "pthread_sigmask"):  # (Windows: no signal masks)
        yield
        return
    from multiprocessing import resource_tracker

    resource_tracker.ensure_running()
    held = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, held)


def _stop_workers(pool: ProcessPoolExecutor) -> None:
    """Terminate *pool*'s workers, then shut it down without waiting for their tasks.

    The workers go first: on Python < 3.14 ``shutdown`` forgets them (it sets the
    executor's table of processes to None), and the interpreter's exit would then wait
    for them to finish every task they had started. (Python 3.14 does both in
    ``terminate_workers``.)
    """
    terminate = getattr(pool, "terminate_workers", None)
    if terminate is not None:
        terminate()
        return
    processes: dict[int, Any] = getattr(pool, "_processes", None) or {}
    for process in list(processes.values()):
        process.terminate()
    pool.shutdown(wait=False, cancel_futures=True)


#: How long the pool's and Dask's result loops wait for a point before looking at tasks.
_POLL_S = 0.2


class _Seen:
    """The points already yielded: each point's result goes out once, whichever way
    (stream or task result, first run or rerun) it arrives first."""

    def __init__(self) -> None:
        self.indices: set[int] = set()

    def fresh(self, results: Iterable[PointResult]) -> Iterator[PointResult]:
        """The results of points not yielded before."""
        for result in results:
            if result.index not in self.indices:
                self.indices.add(result.index)
                yield result


def _drained(
    stream: PointStream, wait_s: float, started: set[int]
) -> Iterator[PointResult]:
    """The results waiting in *stream* (after waiting up to *wait_s* for a message);
    indices of points whose check started go to *started*."""
    try:
        while stream.poll(wait_s):
            wait_s = 0
            message = stream.get()
            if isinstance(message, int):
                started.add(message)
            else:
                yield message
    except (EOFError, OSError):  # a worker killed mid-message: nothing more to read
        return


def _after_break(
    unfinished: list[Task], seen: _Seen, started: set[int], breaks: dict[int, int]
) -> Generator[PointResult, None, list[Task]]:
    """The tasks to retry after a worker died, less their finished points.

    The death is blamed on the points being checked then (started, not finished), or,
    if none was seen starting, on the first open point of every unfinished task; a
    point blamed :data:`_MAX_BREAKS` times is recorded as failed.
    """
    open_points = [[p for p in task.points if p[0] not in seen.indices] for task in unfinished]
    blamed = {i for points in open_points for i, _ in points if i in started} or {
        points[0][0] for points in open_points if points}
    for index in blamed:
        breaks[index] += 1
    failed = {i for i in blamed if breaks[i] >= _MAX_BREAKS}
    yield from seen.fresh(PointResult(i, error="a worker process died on this point "
                                      "(killed, or out of memory)") for i in sorted(failed))
    return [Task(tuple(p for p in points if p[0] not in failed), shared=task.shared)
            for task, points in zip(unfinished, open_points, strict=True)
            if any(p[0] not in failed for p in points)]


class DaskExecutor:
    """``--scheduler``: tasks on a Dask distributed cluster, resubmitted if a worker dies.

    Workers put each point's result on a Dask queue the moment it is checked, so the
    points of a long task are recorded one by one; a task rerun after a worker died
    yields only the points not already recorded.

    :param check: what checks one point on a worker (tests pass a stand-in).
    """

    def __init__(self, client: Client, scheduler: str, check: PointCheck | None = None):
        self.client = client
        self.check = check
        workers = len(client.scheduler_info().get("workers", {}))
        self.description = f"on Dask scheduler {scheduler} ({workers} workers)"

    def describe(self, tasks: Sequence[Task]) -> str:
        """The scheduler and its workers (a cluster may grow or shrink as it runs)."""
        return self.description

    def results(self, tasks: Sequence[Task]) -> Iterator[PointResult]:
        """Submit every task; yield each point's result as it is checked.

        Ctrl-C is noted and raised between the client's calls: raised inside one (each a
        sync with the client's event loop) it left the client half closed, and its
        ``__del__`` printed a traceback as the process exited."""
        from distributed import Queue as DaskQueue
        from distributed import wait as dask_wait

        stream = DaskQueue(client=self.client)  # type: ignore[no-untyped-call]
        futures = {self.client.submit(run_dask_task, task, stream.name, self.check,
                                      pure=False): task for task in tasks}
        seen = _Seen()
        try:
            with _interrupts_held() as interrupted:
                while futures:
                    interrupted()  # Ctrl-C raises here, between the client's calls
                    with suppress(TimeoutError):
                        dask_wait(list(futures),  # type: ignore[no-untyped-call]
                                  timeout=_POLL_S, return_when="FIRST_COMPLETED")
                    sent = stream.get(batch=True)  # type: ignore[no-untyped-call]
                    yield from seen.fresh(pickle.loads(data) for data in sent)
                    for future in [f for f in futures
                                   if f.done()]:  # type: ignore[no-untyped-call]
                        yield from seen.fresh(_gathered(future, futures.pop(future)))
        finally:
            self.client.cancel(list(futures))  # type: ignore[no-untyped-call]
            stream.close()  # type: ignore[no-untyped-call]


def run_dask_task(
    task: Task, stream_name: str, check: PointCheck | None = None
) -> list[PointResult]:
    """:func:`run_task` on a Dask worker, each point's result also put on the Dask queue
    *stream_name* (pickled: Dask queues carry msgpack data) as soon as it is checked."""
    from distributed import Queue as DaskQueue

    stream = DaskQueue(stream_name)  # type: ignore[no-untyped-call]
    results = []
    for result in process_worker().results(task, check):
        stream.put(pickle.dumps(result))  # type: ignore[no-untyped-call]
        results.append(result)
    return results


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
    check_scheduler(scheduler)
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise ConfigError("--scheduler needs Dask: pip install 'veribattery[dask]'") from None
    if scheduler == "local":
        with _sigint_held_from_new_workers():
            cluster = LocalCluster(  # type: ignore[no-untyped-call]
                n_workers=jobs, threads_per_worker=1, processes=True, host="127.0.0.1",
                dashboard_address=":0",
                # (its workers' warnings, such as a task cancelled by Ctrl-C, are not
                # the user's business; their errors still show)
                silence_logs=logging.ERROR)
        with cluster, Client(cluster) as client:  # type: ignore[no-untyped-call]
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
