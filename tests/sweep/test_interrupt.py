"""A local pool stopped midway (Ctrl-C, or its caller gone): its workers are stopped at
once, not left to finish their tasks, and they never see Ctrl-C themselves."""

from __future__ import annotations

import gc
import multiprocessing
import signal
import time

from tests.sweep.helpers import SMALL_FARM
from veribattery.config import load_config
from veribattery.mission import MissionSession, RenderedMission
from veribattery.sweep.execute import LocalPool
from veribattery.sweep.tasks import PointResult, Task

#: Longer than any test waits: a point that takes this long is never finished here.
HUNG_S = 60


def quick_then_endless(session: MissionSession, index: int,
                       mission: RenderedMission) -> PointResult:
    """Point 0 at once; every other point takes :data:`HUNG_S`."""
    if index != 0:
        time.sleep(HUNG_S)
    return PointResult(index)


def sigint_handler(session: MissionSession, index: int,
                   mission: RenderedMission) -> PointResult:
    """What Ctrl-C does to the worker checking the point, as its warning."""
    return PointResult(index, warnings=(repr(signal.getsignal(signal.SIGINT)),))


def _tasks(count: int) -> list[Task]:
    mission = RenderedMission.of(load_config("", SMALL_FARM))
    return [Task(((i, mission),)) for i in range(count)]


def test_a_pool_stopped_midway_terminates_its_workers() -> None:
    results = LocalPool(2, check=quick_then_endless).results(_tasks(3))
    assert next(results).index == 0
    workers = [p for p in multiprocessing.active_children()
               if p.name.startswith("SpawnProcess")]
    assert len(workers) == 2
    results.close()  # as when Ctrl-C stops the sweep reading the results
    # Terminated, not finished: on Python < 3.14 the pool's shutdown forgot its
    # workers, which checked their points to the end (and kept the sweep from exiting).
    assert [_exit_code(p) for p in workers] == [-signal.SIGTERM] * 2


def _exit_code(process: multiprocessing.process.BaseProcess) -> int | None:
    """*process*'s exit code once it has ended (None: still running after HUNG_S)."""
    deadline = time.monotonic() + HUNG_S
    while process.exitcode is None and time.monotonic() < deadline:
        time.sleep(0.05)
    return process.exitcode


def test_workers_ignore_ctrl_c() -> None:
    """Ctrl-C reaches every process of the group: the sweep's process handles it and
    stops the workers, which would each print a traceback."""
    handlers = {w for r in LocalPool(2, check=sigint_handler).results(_tasks(4))
                for w in r.warnings}
    assert handlers == {repr(signal.SIG_IGN)}


def gc_thresholds(session: MissionSession, index: int,
                  mission: RenderedMission) -> PointResult:
    """The worker's garbage-collection thresholds, as its warning."""
    return PointResult(index, warnings=(repr(gc.get_threshold()),))


def test_workers_collect_garbage_as_the_sweep_process_does() -> None:
    """A spawned worker starts with Python's defaults (700, 10, 10); the CLI's process
    collects less often (``veribattery._startup``), and so must the builds it hands out."""
    before = gc.get_threshold()
    gc.set_threshold(12_345, 11, 12)
    try:
        seen = {w for r in LocalPool(2, check=gc_thresholds).results(_tasks(2))
                for w in r.warnings}
    finally:
        gc.set_threshold(*before)
    assert seen == {repr((12_345, 11, 12))}
