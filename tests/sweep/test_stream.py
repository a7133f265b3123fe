"""Rows streamed from multi-point tasks: each point is recorded as it is checked, so a
task cut short (its worker killed) keeps its finished points, in the pool and on Dask."""

from __future__ import annotations

import os
from pathlib import Path

import pandas as pd
import pytest

from tests.sweep.helpers import PER_POINT, SMALL_FARM
from veribattery.config import load_config
from veribattery.mission import MissionSession, RenderedMission
from veribattery.sweep import parse_axis, run_sweep
from veribattery.sweep.execute import LocalPool
from veribattery.sweep.tasks import PointResult, Task, check_point

#: Four points sharing one state space (p_wsp_c strictly inside (0, 1)): reuse tasks.
REUSE_AXIS = "environment.p_wsp_c=0.1:0.4:0.1"


def dies_at_point_one(session: MissionSession, index: int,
                      mission: RenderedMission) -> PointResult:
    """A worker's point check that kills its process at point 1, every time."""
    if index == 1:
        os._exit(3)
    return check_point(session, index, mission)


def test_finished_points_of_a_task_survive_its_worker_dying() -> None:
    cfg = RenderedMission.of(load_config("", SMALL_FARM))
    tasks = [Task(((0, cfg), (1, cfg), (2, cfg))), Task(((3, cfg),))]
    results = list(LocalPool(2, check=dies_at_point_one).results(tasks))
    by_index = {r.index: r for r in results}
    assert sorted(r.index for r in results) == [0, 1, 2, 3]  # each point once
    # Point 0 was checked before its task's worker died (three times) at point 1: kept.
    assert by_index[0].error is None and by_index[0].values
    assert by_index[1].error is not None and "worker process died" in by_index[1].error
    # The death is blamed on point 1 alone: the task's later point is retried and checked.
    assert by_index[2].error is None and by_index[3].error is None
    assert by_index[0].values == by_index[2].values == by_index[3].values


def _reuse_sweep(**options: object) -> pd.DataFrame:
    return run_sweep("", [parse_axis(REUSE_AXIS)], SMALL_FARM, **options)  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def reuse_serial() -> pd.DataFrame:
    return _reuse_sweep()


def test_pool_writes_each_point_of_a_reuse_task_as_it_finishes(
    reuse_serial: pd.DataFrame, tmp_path: Path
) -> None:
    # Two reuse tasks of two points each. At the first point, the RESULTS file already
    # has its rows and the whole sweep is then interrupted (as by Ctrl-C or a crash):
    # the point survives, the rerun checks only the others.
    path = tmp_path / "r.csv"
    seen: list[int] = []

    def stop_after_first(result: PointResult, _: object) -> None:
        seen.append(result.index)
        written = pd.read_csv(path)
        assert set(written["point"]) == {result.index}
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        _reuse_sweep(jobs=2, results=path, on_point=stop_after_first)
    assert len(pd.read_csv(path)) == PER_POINT
    notes: list[str] = []
    frame = _reuse_sweep(jobs=2, results=path, notes=notes.append)
    assert notes[0].startswith("1 of 4 points already done")
    assert list(frame["value"]) == list(reuse_serial["value"])


@pytest.mark.filterwarnings("ignore::DeprecationWarning")
@pytest.mark.filterwarnings("ignore::ResourceWarning")
def test_dask_keeps_finished_points_of_a_task_whose_worker_dies() -> None:
    dask = pytest.importorskip("dask")
    distributed = pytest.importorskip("distributed")
    from veribattery.sweep.execute import DaskExecutor

    cfg = RenderedMission.of(load_config("", SMALL_FARM))
    tasks = [Task(((0, cfg), (1, cfg), (2, cfg))), Task(((3, cfg),))]
    # No retries: the first worker death gives the task up (KilledWorker).
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}), \
            distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                     host="127.0.0.1", dashboard_address=":0") as cluster, \
            distributed.Client(cluster) as client:
        executor = DaskExecutor(client, "test", check=dies_at_point_one)
        results = list(executor.results(tasks))
    by_index = {r.index: r for r in results}
    assert sorted(r.index for r in results) == [0, 1, 2, 3]  # each point once
    # Point 0 was streamed before the worker died at point 1: kept, not failed.
    assert by_index[0].error is None and by_index[0].values == by_index[3].values
    assert by_index[1].error is not None and "KilledWorker" in by_index[1].error
