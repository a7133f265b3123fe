"""Executors: a local process pool and Dask give the in-process results, bit for bit."""

from __future__ import annotations

import os
import signal
from contextlib import suppress
from pathlib import Path

import pandas as pd
import pytest

from tests.sweep.helpers import PER_POINT, SMALL_FARM, four_axes, same_results
from veribattery.checker import Workspace
from veribattery.config import load_config
from veribattery.errors import ConfigError
from veribattery.mission import ParseCache, RenderedMission
from veribattery.sweep import parse_axis, run_sweep
from veribattery.sweep.execute import LocalPool, check_scheduler, open_executor
from veribattery.sweep.tasks import ReusePlan, Task, plan_tasks


def test_process_pool_equals_in_process(serial_frame: pd.DataFrame, tmp_path: Path) -> None:
    order: list[int] = []
    frame = run_sweep("", four_axes(), SMALL_FARM, jobs=2, results=tmp_path / "r.csv",
                      on_point=lambda result, _: order.append(result.index))
    assert sorted(order) == [0, 1, 2, 3]
    same_results(frame, serial_frame)


def test_a_shared_run_cut_into_tasks_gives_the_serial_values() -> None:
    # Three points of one state space: one task in process, tasks of 2 and 1 points with
    # two workers. Each point is checked on its own quotient either way: bit for bit.
    axis = [parse_axis("environment.p_wsp_c=0.15,0.35,0.65")]
    serial = run_sweep("", axis, SMALL_FARM)
    same_results(run_sweep("", axis, SMALL_FARM, jobs=2), serial)
    # (The small farm's values come out equal on the chain and its quotient, so the
    # rule itself: a one-point task of a shared run checks on the quotient too.)
    mission = RenderedMission.of(load_config("", SMALL_FARM))
    lone = Task(((0, mission),), shared=True).session(ParseCache(), Workspace()).check(mission)
    assert lone.run.quotient is not None and not lone.reused
    alone = Task(((0, mission),)).session(ParseCache(), Workspace()).check(mission)
    assert alone.run.quotient is None


def test_pool_recovers_from_a_dead_worker(serial_frame: pd.DataFrame) -> None:
    # The pool's worker processes are killed after the first point: the pool breaks, is
    # restarted, and the unfinished tasks run again.
    missions = [RenderedMission.of(load_config("", [*SMALL_FARM, "battery.capacity_ah=10"]))] * 3
    tasks = [Task(((i, mission),)) for i, mission in enumerate(missions)]
    pool = LocalPool(2)
    results = pool.results(tasks)
    first = next(results)
    _kill_pool_workers()
    rest = list(results)
    indices = sorted([first.index, *(r.index for r in rest)])
    assert indices == [0, 1, 2]  # every point once, none lost, none duplicated
    assert all(r.error is None for r in [first, *rest])


def _kill_pool_workers() -> None:
    import multiprocessing

    for child in multiprocessing.active_children():
        if child.name.startswith(("SpawnProcess", "Process")):
            os.kill(child.pid or 0, signal.SIGKILL)


def test_plan_full_build_without_reuse_keys(monkeypatch: pytest.MonkeyPatch) -> None:
    import veribattery.sweep.tasks as tasks_module

    monkeypatch.setattr(tasks_module, "reuse_key", lambda mission, parses: None)
    mission = RenderedMission.of(load_config("", SMALL_FARM))
    tasks, plan = plan_tasks([(i, mission) for i in range(5)], jobs=2)
    assert [len(t.points) for t in tasks] == [1] * 5  # no reuse key: one point each
    assert plan.describe() == "full build at every point"


def test_plan_shares_the_state_space_of_equal_configs() -> None:
    mission = RenderedMission.of(load_config("", SMALL_FARM))
    tasks, plan = plan_tasks([(i, mission) for i in range(5)], jobs=1)
    assert [len(t.points) for t in tasks] == [5]
    assert plan.describe() == "structure reuse: 5 points share 1 state space"


def test_plan_groups_equal_reuse_keys(monkeypatch: pytest.MonkeyPatch) -> None:
    import veribattery.sweep.tasks as tasks_module

    keys = iter(["a", "a", "a", None, "b", "b", "a"])
    monkeypatch.setattr(tasks_module, "reuse_key", lambda mission, parses: next(keys))
    mission = RenderedMission.of(load_config("", SMALL_FARM))
    tasks, plan = plan_tasks([(i, mission) for i in range(7)], jobs=1)
    assert [[i for i, _ in t.points] for t in tasks] == [[0, 1, 2], [3], [4, 5], [6]]
    # Points of shared runs are checked on quotients, however the run is cut (below).
    assert [t.shared for t in tasks] == [True, False, True, False]
    assert plan == ReusePlan(5, 2, 7)
    assert plan.describe() == ("structure reuse: 5 points share 2 state spaces; "
                               "full build at the other 2")
    # With two workers a run longer than an even share (4 points) is cut.
    keys = iter(["a"] * 7)
    tasks, _ = plan_tasks([(i, mission) for i in range(7)], jobs=2)
    assert [len(t.points) for t in tasks] == [4, 3]
    assert all(t.shared for t in tasks)


def test_a_resumed_sweep_lumps_the_points_it_would_have_lumped(
    monkeypatch: pytest.MonkeyPatch
) -> None:
    import veribattery.sweep.tasks as tasks_module

    configs = [load_config("", (*SMALL_FARM, f"environment.p_wsp_c=0.{i + 1}")) for i in range(4)]
    keys = {id(cfg): key for cfg, key in zip(configs, "aabc", strict=True)}
    monkeypatch.setattr(tasks_module, "reuse_key", lambda mission, parses: keys[id(mission.config)])
    grid = list(enumerate(configs))
    left = [(i, RenderedMission.of(configs[i])) for i in (1, 3)]
    # Points 1 and 3 left: 1 shares its grid run with 0 (done), 3 is alone.
    tasks, _ = plan_tasks(left, jobs=1, grid=grid)
    assert [([i for i, _ in t.points], t.shared) for t in tasks] == [([1], True), ([3], False)]
    tasks, _ = plan_tasks(left, jobs=1)  # (planned alone: neither)
    assert [t.shared for t in tasks] == [False, False]


# --------------------------------------------------------------------------- Dask

def _local_cluster() -> object:
    distributed = pytest.importorskip("distributed")
    return distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                    host="127.0.0.1", dashboard_address=":0")


@pytest.mark.filterwarnings("ignore::DeprecationWarning")
@pytest.mark.filterwarnings("ignore::ResourceWarning")
def test_dask_cluster_equals_local_and_survives_a_killed_worker(
    serial_frame: pd.DataFrame, tmp_path: Path
) -> None:
    from distributed import Client

    with _local_cluster() as cluster, Client(cluster) as client:  # type: ignore[attr-defined]
        pids = list(client.run(os.getpid).values())
        killed: list[int] = []

        def kill_one(done: int, total: int) -> None:
            if done == 1 and not killed:  # mid-sweep: three points still to come
                os.kill(pids[0], signal.SIGKILL)
                killed.append(pids[0])

        path = tmp_path / "r.csv"
        frame = run_sweep("", four_axes(), SMALL_FARM, kill_one, jobs=2, results=path,
                          scheduler=cluster.scheduler_address)  # type: ignore[attr-defined]
    assert killed
    same_results(frame, serial_frame)
    written = pd.read_csv(path)
    assert list(written["point"]) == [p for p in range(4) for _ in range(PER_POINT)]  # none twice
    assert list(written["value"]) == list(serial_frame["value"].astype(float))


@pytest.mark.filterwarnings("ignore::DeprecationWarning")
@pytest.mark.filterwarnings("ignore::ResourceWarning")
def test_scheduler_local_equals_in_process(serial_frame: pd.DataFrame) -> None:
    pytest.importorskip("distributed")
    frame = run_sweep("", four_axes(), SMALL_FARM, jobs=2, scheduler="local")
    same_results(frame, serial_frame)


def test_unreachable_scheduler_is_one_line() -> None:
    pytest.importorskip("distributed")
    with pytest.raises(ConfigError, match=r"^--scheduler tcp://127.0.0.1:9: cannot reach"),\
            open_executor(1, "tcp://127.0.0.1:9"):
        pass


@pytest.mark.parametrize(("address", "says"), [
    ("tcp://host:abc", "the port must be a number (1-65535), not 'abc'"),
    ("tcp://host:70000", "the port must be a number (1-65535), not '70000'"),
    ("tcp://host:0", "the port must be a number (1-65535), not '0'"),
    ("tcp://[::1]:x1", "the port must be a number (1-65535), not 'x1'"),
    ("tcp://host:", "no port after host:"),
    ("tcp://host", "no port"),
    ("tcp://[::1]", "no port"),
    ("foo", "no port"),
    ("tcp://", "no host and port"),
    ("tcp://:8786", "no host before the port"),
    ("://host:8786", "no protocol before '://'"),
])
def test_a_malformed_scheduler_address_is_refused_before_any_connection(
        address: str, says: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """Dask's own parse said ``invalid literal for int()``; no cluster is reached here."""
    import veribattery.sweep.execute as execute

    def no_connection(*args: object) -> None:
        raise AssertionError("a cluster was reached")

    monkeypatch.setattr(execute, "DaskExecutor", no_connection)
    with pytest.raises(ConfigError) as refused, open_executor(1, address):
        pass
    assert str(refused.value) == (f"--scheduler {address}: {says}; give tcp://HOST:PORT, or "
                                  "local for a cluster on this machine")


@pytest.mark.parametrize("address", ["local", "tcp://127.0.0.1:8786", "tls://host:1",
                                     "host:65535", "tcp://[::1]:8786"])
def test_a_well_formed_scheduler_address_passes_the_check(address: str) -> None:
    check_scheduler(address)


def _children(pid: int) -> set[int]:
    """The live child processes of *pid* (Linux /proc)."""
    found = set()
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            with suppress(OSError):
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
                if int(fields[1]) == pid and fields[0] != "Z":
                    found.add(int(entry.name))
    return found


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")
def test_a_killed_sweep_leaves_no_worker_running(tmp_path: Path) -> None:
    # kill -9 of the sweep's process (a CI timeout): its pool's workers notice the
    # orphaning and exit, instead of checking the rest of their tasks for no one.
    import subprocess
    import sys
    import time

    argv = [sys.executable, "-m", "veribattery", "sweep", "configs/paper/case1.yaml",
            "--vary", "battery.capacity_ah=12:14:0.1", "-j", "2", "--format", "csv"]
    sweep = subprocess.Popen(argv, cwd=Path(__file__).parents[2], stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        while len(workers := _children(sweep.pid)) < 2 and time.monotonic() < deadline:
            time.sleep(0.1)
        assert len(workers) >= 2, "the sweep started no pool"
    finally:
        sweep.kill()
        sweep.wait()
    deadline = time.monotonic() + 60
    while (alive := {w for w in workers if Path(f"/proc/{w}").exists()
                     and "Z" not in (Path(f"/proc/{w}/stat").read_text().rsplit(")", 1)[1]
                                     .split()[:1])}) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not alive, f"workers {sorted(alive)} outlived the sweep"
