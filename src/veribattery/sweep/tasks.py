"""Units of sweep work: tasks of grid points and what checking one point gives back.

A task is a run of consecutive grid points checked in order by one
:class:`~veribattery.mission.MissionSession`, so that points with equal
:func:`~veribattery.mission.reuse_key` can share one state space. A task is what an
executor ships to a worker (each point's config with its rendered texts: a point is
rendered once); a :class:`PointResult` is what comes back: plain numbers and strings
only, never the DTMC, so it pickles small. A :class:`Worker` runs tasks one after
another in one process.
"""

from __future__ import annotations

import gc
import math
import multiprocessing
import os
import signal
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from veribattery.checker import Workspace
from veribattery.config import MissionConfig
from veribattery.mission import (
    MissionReport,
    MissionSession,
    ParseCache,
    RenderedMission,
    reuse_key,
)
from veribattery.sweep.point_result import PointResult, PropertyValue

if TYPE_CHECKING:
    from multiprocessing.connection import Connection
    from multiprocessing.context import BaseContext

__all__ = ["PointCheck", "PointResult", "PointStream", "PropertyValue", "ReusePlan", "Task",
           "Worker", "plan_tasks", "run_task", "start_worker"]


#: A grid point to check: its index and its rendered mission.
Point = tuple[int, RenderedMission]


@dataclass(frozen=True, slots=True)
class Task:
    """Consecutive grid points, checked in order in one session.

    *shared*: the points belong to a run of points that share one state space; they
    are checked on bisimulation quotients (whether the run was cut into one task or
    several, so that -j never changes a value).
    """

    points: tuple[Point, ...]
    shared: bool = False

    def session(self, parses: ParseCache, workspace: Workspace) -> MissionSession:
        """The session of this task's points: one that keeps the structure of its builds
        only when a later point of the task may re-use it.

        :param parses: the worker's parse cache.
        :param workspace: the worker's checker caches.
        """
        return MissionSession.for_sweep(reuse=len(self.points) > 1, lump=self.shared,
                                        parses=parses, workspace=workspace)


@dataclass(frozen=True, slots=True)
class ReusePlan:
    """How the pending points are built: how many share state spaces, and how many."""

    shared_points: int
    state_spaces: int
    total_points: int

    def describe(self) -> str:
        """``structure reuse: 50 points share 1 state space`` or ``full build at every point``."""
        if self.shared_points == 0:
            return "full build at every point"
        spaces = f"{self.state_spaces} state space{'s' if self.state_spaces != 1 else ''}"
        text = f"structure reuse: {self.shared_points} points share {spaces}"
        rest = self.total_points - self.shared_points
        return text + (f"; full build at the other {rest}" if rest else "")


def plan_tasks(
    points: Sequence[Point], jobs: int,
    grid: Sequence[tuple[int, MissionConfig]] | None = None,
    parses: ParseCache | None = None,
) -> tuple[list[Task], ReusePlan]:
    """Group consecutive *points* with equal non-None reuse keys into tasks.

    A run of equal keys longer than an even share of the points (``len / jobs``) is cut
    into pieces, each building once, so that every worker has work.

    :param grid: the whole grid's configs, when *points* are what is left of it (a
        resumed sweep). A point is checked on a quotient (:attr:`Task.shared`) when its
        run in the grid has two points or more, so that resuming never changes a value.
    :param parses: the parse cache for the keys (consecutive points differ little).
    """
    parses = parses or ParseCache()
    keys = {index: reuse_key(mission, parses) for index, mission in points}
    whole = grid if grid is not None else [(index, m.config) for index, m in points]
    in_shared = _in_shared_runs(points, keys, whole, parses)
    runs = [piece for run in _runs(points, keys) for piece in _split(run, in_shared)]
    shared = [run for run in runs if len(run) > 1]
    plan = ReusePlan(sum(map(len, shared)), len(shared), len(points))
    share = max(1, math.ceil(len(points) / max(jobs, 1)))
    tasks = [Task(tuple(run[i:i + share]), shared=run[0][0] in in_shared)
             for run in runs for i in range(0, len(run), share)]
    return tasks, plan


def _in_shared_runs(points: Sequence[Point], keys: dict[int, str | None],
                    grid: Sequence[tuple[int, MissionConfig]], parses: ParseCache) -> set[int]:
    """The indices of *points* whose run in *grid* has two points or more: a key that
    is not None and equals a grid neighbour's (whose keys are made here, for those
    neighbours alone)."""
    position = {index: at for at, (index, _) in enumerate(grid)}
    found = set()
    for index, _ in points:
        key, at = keys[index], position[index]
        for near in (at - 1, at + 1):
            if key is not None and 0 <= near < len(grid):
                other, cfg = grid[near]
                if other not in keys:
                    keys[other] = reuse_key(RenderedMission.of_point(cfg), parses)
                if keys[other] == key:
                    found.add(index)
    return found


def _runs(points: Sequence[Point], keys: dict[int, str | None]) -> list[list[Point]]:
    runs: list[list[Point]] = []
    previous: str | None = None
    for point in points:
        key = keys[point[0]]
        if key is not None and key == previous:
            runs[-1].append(point)
        else:
            runs.append([point])
        previous = key
    return runs


def _split(run: list[Point], in_shared: set[int]) -> list[list[Point]]:
    """*run* cut where its points change between checked on quotients and not."""
    pieces: list[list[Point]] = []
    for point in run:
        if pieces and (pieces[-1][0][0] in in_shared) == (point[0] in in_shared):
            pieces[-1].append(point)
        else:
            pieces.append([point])
    return pieces


#: Checks one point: :func:`check_point`, or a stand-in (tests) importable by workers.
PointCheck = Callable[[MissionSession, int, RenderedMission], "PointResult"]


@dataclass(frozen=True, slots=True)
class PointStream:
    """A one-way pipe from pool workers to the sweep: point indices and results.

    ``put`` has written the whole message when it returns (no feeder thread, unlike
    ``multiprocessing.Queue``), so a worker killed after it loses nothing; the lock
    keeps messages of concurrent workers whole. Unlike ``SimpleQueue``, the reading
    end can wait with a timeout through public API.
    """

    reader: Connection
    writer: Connection
    lock: Any

    @classmethod
    def open(cls, context: BaseContext) -> PointStream:
        """A new stream whose ends and lock can be handed to processes of *context*."""
        reader, writer = context.Pipe(duplex=False)
        return cls(reader, writer, context.Lock())

    def put(self, message: int | PointResult) -> None:
        """Send *message* whole (workers)."""
        with self.lock:
            self.writer.send(message)

    def poll(self, timeout: float) -> bool:
        """Whether a message arrives within *timeout* seconds (the sweep)."""
        return self.reader.poll(timeout)

    def get(self) -> int | PointResult:
        """The next message (the sweep; call after :meth:`poll`)."""
        message: int | PointResult = self.reader.recv()
        return message

    def close(self) -> None:
        """Close both ends in this process."""
        self.reader.close()
        self.writer.close()


class Worker:
    """Runs tasks one after another in one process, keeping from one task to the next
    its parse cache (consecutive points' texts differ in a constant or two, and most
    tasks of a sweep without shared state spaces are one point long) and its checker
    :class:`Workspace` (points of one farm share sparsity patterns, and so plans and
    graph searches, even where their state spaces differ).

    :param stream: where to report each point, its index when its check starts and its
        result the moment it is done (a local pool's worker), or None.
    :param parses: the parse cache to keep (default: a new one).
    """

    def __init__(self, stream: PointStream | None = None, *,
                 parses: ParseCache | None = None) -> None:
        self.stream = stream
        self.parses = parses or ParseCache()
        self.workspace = Workspace()

    def results(self, task: Task, check: PointCheck | None = None) -> Iterator[PointResult]:
        """Check the points of *task* in order in one session, yielding each as it is done.

        With a stream, each point is reported when it starts and when it is done, so
        that finished points are kept even if the task never finishes, and a worker's
        death is blamed on the point it was checking.
        """
        session = task.session(self.parses, self.workspace)
        for index, mission in task.points:
            if self.stream is not None:
                self.stream.put(index)
            result = (check or check_point)(session, index, mission)
            if self.stream is not None:
                self.stream.put(result)
            yield result


#: The worker of this process, when it checks tasks for a pool or a Dask cluster (made by
#: :func:`start_worker`, or on the first task).
_WORKER: Worker | None = None


#: How often a pool's worker looks whether the sweep's process is still there (seconds).
PARENT_POLL_S = 1.0


def start_worker(stream: PointStream | None,
                 collection: tuple[int, ...] | None = None) -> None:
    """Make this process a worker that reports every point to *stream* (a pool's
    initializer), and that exits when the sweep's process is gone.

    It ignores SIGINT: Ctrl-C reaches the whole process group, and the sweep's process
    handles it and stops the workers (each would print a traceback otherwise). With
    *collection* (the sweep process's ``gc.get_threshold()``) it collects garbage as that
    process does: a spawned worker starts with Python's defaults, under which a large
    model's build spent ~40 % of its time in the collector (see ``veribattery._startup``).
    """
    global _WORKER
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if collection is not None:
        gc.set_threshold(*collection)
    _WORKER = Worker(stream)
    _exit_with_parent()


def _exit_with_parent() -> None:
    """Exit at once when the parent process dies. A sweep killed by a signal it cannot
    handle (``kill``, a CI job's timeout) leaves its pool's workers orphaned: without
    this they would finish their tasks, on every core, for no one. The parent is the one
    that started this process (it may have died already, while this one started)."""
    started_by = multiprocessing.parent_process()
    if started_by is None:
        return

    def watch() -> None:
        while os.getppid() == started_by.pid:
            time.sleep(PARENT_POLL_S)
        os._exit(1)

    threading.Thread(target=watch, name="parent-watch", daemon=True).start()


def process_worker() -> Worker:
    """This process's worker (made on first use where no pool started it: Dask)."""
    global _WORKER
    if _WORKER is None:
        _WORKER = Worker()
    return _WORKER


def run_task(task: Task, check: PointCheck | None = None) -> list[PointResult]:
    """Check every point of *task* in this process's worker (what a pool process runs)."""
    return list(process_worker().results(task, check))


def check_point(session: MissionSession, index: int, mission: RenderedMission) -> PointResult:
    """Check one point; any failure becomes the point's *error* and the sweep goes on.

    A point in synthesis mode asks its MDP for ``Pmax`` of success
    (:mod:`~veribattery.sweep.synthesis_point`).
    """
    started = time.perf_counter()
    try:
        if mission.is_mdp:
            return _synthesis_point(index, mission, started)
        report = session.check(mission)
    except MemoryError:
        return PointResult(index, seconds=time.perf_counter() - started, error="out of memory")
    except Exception as exc:  # a failed point is data in a sweep, whatever the cause
        return PointResult(index, seconds=time.perf_counter() - started,
                           error=one_line(f"{type(exc).__name__}: {exc}"))
    return point_result(index, report, time.perf_counter() - started)


def _synthesis_point(index: int, mission: RenderedMission, started: float) -> PointResult:
    # imported here: BS1 sweeps never load the MDP engine
    from veribattery.sweep.synthesis_point import synthesis_point
    from veribattery.synthesis.sweep_pmax import pmax_of_model

    answer = pmax_of_model(mission.model)
    return synthesis_point(index, mission.config, answer, time.perf_counter() - started)


def point_result(index: int, report: MissionReport, seconds: float) -> PointResult:
    """The plain-data summary of *report*."""
    values = []
    for name, value in report.values.items():
        outcomes = [o for o in report.requirements if o.requirement.prop == name]
        values.append(PropertyValue(
            name, value, " and ".join(str(o.requirement) for o in outcomes) or None,
            all(o.holds for o in outcomes) if outcomes else None,
        ))
    dtmc = report.run.dtmc
    return PointResult(index, tuple(values), dtmc.num_states, dtmc.num_transitions, seconds,
                       report.recharge_cap_probability, report.run.warnings)


def one_line(text: str) -> str:
    """*text* on one line (a result cell must not break a CSV/JSONL line)."""
    return " ".join(text.split())
