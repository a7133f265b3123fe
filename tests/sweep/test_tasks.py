"""Sweep tasks: a task of one point builds as an independent check does (no structure kept
for re-use), a task of several points with one reuse key builds once."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest

import veribattery.pipeline as pipeline
from tests.sweep.helpers import SMALL_FARM
from veribattery.config import MissionConfig, load_config
from veribattery.mission import check_mission, reuse_key
from veribattery.sweep.tasks import PointResult, Task, iter_task, run_task


def _config(p_wsp_c: str) -> MissionConfig:
    return load_config("", (*SMALL_FARM, f"environment.p_wsp_c={p_wsp_c}"))


@pytest.fixture
def reusable_builds(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """Counts the builds that keep a structure for re-use (and record branch kinds)."""
    calls: list[int] = []
    original: Callable[..., Any] = pipeline.build_reusable

    def counting(*args: Any, **kwargs: Any) -> Any:
        calls.append(1)
        return original(*args, **kwargs)

    monkeypatch.setattr(pipeline, "build_reusable", counting)
    return calls


def _values(result: PointResult) -> dict[str, float | bool]:
    return {v.name: v.value for v in result.values}


@pytest.mark.parametrize("run", [run_task, lambda task: list(iter_task(task))],
                         ids=["run_task", "iter_task"])
def test_one_point_task_keeps_no_structure(
    run: Callable[[Task], list[PointResult]], reusable_builds: list[int]
) -> None:
    cfg = _config("0.1")
    [result] = run(Task(((7, cfg),)))
    assert reusable_builds == []
    fresh = check_mission(cfg)
    assert result.index == 7 and result.error is None
    assert _values(result) == fresh.values  # the same build and solves: equal to the bit
    assert result.recharge_cap_probability == fresh.recharge_cap_probability
    assert result.states == fresh.run.dtmc.num_states


def test_task_of_one_key_builds_once(reusable_builds: list[int]) -> None:
    configs = [_config(p) for p in ("0.1", "0.35")]
    assert reuse_key(configs[0]) == reuse_key(configs[1])
    results = run_task(Task(tuple(enumerate(configs))))
    assert reusable_builds == [1]  # the second point re-used the first one's structure
    for result, cfg in zip(results, configs, strict=True):
        fresh = check_mission(cfg).values
        for name, value in _values(result).items():
            assert float(value) == pytest.approx(float(fresh[name]), rel=1e-12)
