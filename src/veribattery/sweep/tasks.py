"""Units of sweep work: tasks of grid points and what checking one point gives back.

A task is a run of consecutive grid points checked in order by one
:class:`~veribattery.mission.MissionChecker`, so that points with equal
:func:`~veribattery.mission.reuse_key` can share one state space. A task is what an
executor ships to a worker; a :class:`PointResult` is what comes back: plain numbers and
strings only, never the DTMC, so it pickles small.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from veribattery.config import MissionConfig
from veribattery.mission import MissionChecker, MissionReport, reuse_key

if TYPE_CHECKING:
    from multiprocessing.connection import Connection
    from multiprocessing.context import BaseContext

__all__ = ["PointCheck", "PointResult", "PointStream", "PropertyValue", "ReusePlan", "Task",
           "iter_task", "plan_tasks", "run_task", "stream_to"]


@dataclass(frozen=True, slots=True)
class PropertyValue:
    """One property's value at a point, with the requirements on it and their verdict."""

    name: str
    value: float | bool
    requirement: str | None
    holds: bool | None


@dataclass(frozen=True, slots=True)
class PointResult:
    """The outcome of checking one grid point (*error* set, and no values, if it failed)."""

    index: int
    values: tuple[PropertyValue, ...] = ()
    states: int | None = None
    transitions: int | None = None
    seconds: float = 0.0
    recharge_cap_probability: float | None = None
    warnings: tuple[str, ...] = ()
    error: str | None = None


@dataclass(frozen=True, slots=True)
class Task:
    """Consecutive grid points (index, config), checked in order by one checker.

    *shared*: the points belong to a run of points that share one state space; they
    are checked on bisimulation quotients (whether the run was cut into one task or
    several, so that -j never changes a value).
    """

    points: tuple[tuple[int, MissionConfig], ...]
    shared: bool = False

    def checker(self) -> MissionChecker:
        """The checker of this task's points: one that keeps the structure of its builds
        only when a later point of the task may re-use it."""
        return MissionChecker(values_only=True, reuse=len(self.points) > 1, lump=self.shared)


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
    points: Sequence[tuple[int, MissionConfig]], jobs: int,
    grid: Sequence[tuple[int, MissionConfig]] | None = None,
) -> tuple[list[Task], ReusePlan]:
    """Group consecutive *points* with equal non-None reuse keys into tasks.

    A run of equal keys longer than an even share of the points (``len / jobs``) is cut
    into pieces, each building once, so that every worker has work.

    :param grid: the whole grid, when *points* are what is left of it (a resumed
        sweep). A point is checked on a quotient (:attr:`Task.shared`) when its run in
        the grid has two points or more, so that resuming never changes a value.
    """
    keys = {index: reuse_key(cfg) for index, cfg in points}
    in_shared = _in_shared_runs(points, keys, points if grid is None else grid)
    runs = [piece for run in _runs(points, keys) for piece in _split(run, in_shared)]
    shared = [run for run in runs if len(run) > 1]
    plan = ReusePlan(sum(map(len, shared)), len(shared), len(points))
    share = max(1, math.ceil(len(points) / max(jobs, 1)))
    tasks = [Task(tuple(run[i:i + share]), shared=run[0][0] in in_shared)
             for run in runs for i in range(0, len(run), share)]
    return tasks, plan


def _in_shared_runs(points: Sequence[tuple[int, MissionConfig]], keys: dict[int, str | None],
                    grid: Sequence[tuple[int, MissionConfig]]) -> set[int]:
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
                    keys[other] = reuse_key(cfg)
                if keys[other] == key:
                    found.add(index)
    return found


def _runs(points: Sequence[tuple[int, MissionConfig]],
          keys: dict[int, str | None]) -> list[list[tuple[int, MissionConfig]]]:
    runs: list[list[tuple[int, MissionConfig]]] = []
    previous: str | None = None
    for point in points:
        key = keys[point[0]]
        if key is not None and key == previous:
            runs[-1].append(point)
        else:
            runs.append([point])
        previous = key
    return runs


def _split(run: list[tuple[int, MissionConfig]],
           in_shared: set[int]) -> list[list[tuple[int, MissionConfig]]]:
    """*run* cut where its points change between checked on quotients and not."""
    pieces: list[list[tuple[int, MissionConfig]]] = []
    for point in run:
        if pieces and (pieces[-1][0][0] in in_shared) == (point[0] in in_shared):
            pieces[-1].append(point)
        else:
            pieces.append([point])
    return pieces


#: Checks one point: :func:`check_point`, or a stand-in (tests) importable by workers.
PointCheck = Callable[["MissionChecker", int, MissionConfig], "PointResult"]

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


#: Where this worker process reports each point: its index when its check starts, its
#: result the moment it is done (set by :func:`stream_to` when a local pool starts the
#: process).
_STREAM: PointStream | None = None


def stream_to(stream: PointStream | None) -> None:
    """Report every point to *stream* as it starts and ends (a pool's initializer)."""
    global _STREAM
    _STREAM = stream


def run_task(task: Task, check: PointCheck | None = None) -> list[PointResult]:
    """Check every point of *task* (what a worker process runs).

    With a stream (see :func:`stream_to`) each point is reported when it starts and
    when it is done, so that finished points are kept even if the task never finishes,
    and a worker's death is blamed on the point it was checking.
    """
    checker, results = task.checker(), []
    for index, cfg in task.points:
        if _STREAM is not None:
            _STREAM.put(index)
        results.append((check or check_point)(checker, index, cfg))
        if _STREAM is not None:
            _STREAM.put(results[-1])
    return results


def iter_task(task: Task, check: PointCheck | None = None) -> Iterator[PointResult]:
    """Check the points of *task* in order with one checker, yielding each as it is done."""
    checker = task.checker()
    for index, cfg in task.points:
        yield (check or check_point)(checker, index, cfg)


def check_point(checker: MissionChecker, index: int, cfg: MissionConfig) -> PointResult:
    """Check one point; any failure becomes the point's *error* and the sweep goes on."""
    started = time.perf_counter()
    try:
        report = checker.check(cfg)
    except MemoryError:
        return PointResult(index, seconds=time.perf_counter() - started, error="out of memory")
    except Exception as exc:  # a failed point is data in a sweep, whatever the cause
        return PointResult(index, seconds=time.perf_counter() - started,
                           error=one_line(f"{type(exc).__name__}: {exc}"))
    return point_result(index, report, time.perf_counter() - started)


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
