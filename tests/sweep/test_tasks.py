"""Sweep tasks: a task of one point builds as an independent check does (no structure kept
for re-use), a task of several points with one reuse key builds once."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest

import veribattery.explore.reuse.structure as structure
from tests.sweep.helpers import SMALL_FARM
from veribattery.config import load_config
from veribattery.mission import RenderedMission, check_mission, reuse_key
from veribattery.sweep.tasks import PointResult, Task, Worker, run_task


def _mission(p_wsp_c: str) -> RenderedMission:
    return RenderedMission.of(load_config("", (*SMALL_FARM, f"environment.p_wsp_c={p_wsp_c}")))


@pytest.fixture
def reusable_builds(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """Counts the builds that keep a structure for re-use (and record branch kinds)."""
    calls: list[int] = []
    # Patched where it is defined: the session imports it when it builds (re-use only).
    original: Callable[..., Any] = structure.build_reusable

    def counting(*args: Any, **kwargs: Any) -> Any:
        calls.append(1)
        return original(*args, **kwargs)

    monkeypatch.setattr(structure, "build_reusable", counting)
    return calls


def _values(result: PointResult) -> dict[str, float | bool]:
    return {v.name: v.value for v in result.values}


@pytest.mark.parametrize("run", [run_task, lambda task: list(Worker().results(task))],
                         ids=["run_task", "Worker.results"])
def test_one_point_task_keeps_no_structure(
    run: Callable[[Task], list[PointResult]], reusable_builds: list[int]
) -> None:
    mission = _mission("0.1")
    [result] = run(Task(((7, mission),)))
    assert reusable_builds == []
    fresh = check_mission(mission.config)
    assert result.index == 7 and result.error is None
    assert _values(result) == fresh.values  # the same build and solves: equal to the bit
    assert result.recharge_cap_probability == fresh.recharge_cap_probability
    assert result.states == fresh.run.dtmc.num_states


def test_task_of_one_key_builds_once(reusable_builds: list[int]) -> None:
    missions = [_mission(p) for p in ("0.1", "0.35")]
    assert reuse_key(missions[0]) == reuse_key(missions[1])
    results = run_task(Task(tuple(enumerate(missions))))
    assert reusable_builds == [1]  # the second point re-used the first one's structure
    for result, mission in zip(results, missions, strict=True):
        fresh = check_mission(mission.config).values
        for name, value in _values(result).items():
            assert float(value) == pytest.approx(float(fresh[name]), rel=1e-12)


def test_a_worker_parses_a_model_in_full_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """One-point tasks (a sweep without shared state spaces) in one worker: the second
    point's model differs in a constant, and only that declaration is parsed again."""
    import veribattery.mission.parses as parses

    full: list[int] = []
    original: Callable[..., Any] = parses.parse_model

    def counting(text: str, *args: Any, **kwargs: Any) -> Any:
        if len(text) > 2000:  # a whole model, not one declaration at its own line
            full.append(1)
        return original(text, *args, **kwargs)

    monkeypatch.setattr(parses, "parse_model", counting)
    worker = Worker()
    for index, p in enumerate(("0.1", "0.35")):
        [result] = worker.results(Task(((index, _mission(p)),)))
        assert result.error is None
    assert full == [1]
