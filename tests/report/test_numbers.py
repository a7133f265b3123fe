"""The report's numbers are those the commands print: ``check``, ``explain``,
``distribution`` and ``simulate``, each run on its own through the CLI."""

from __future__ import annotations

import pytest

from tests.report.conftest import EXAMPLE, TINY_ARGS, Made, command_json


def _without_timings(document: dict[str, object]) -> dict[str, object]:
    return {key: value for key, value in document.items() if key != "timings_s"}


def test_the_verdict_is_check_format_json(tiny_report: Made) -> None:
    check = command_json("check", EXAMPLE, *TINY_ARGS)
    ours = tiny_report.data["check"]
    assert isinstance(ours, dict)
    assert _without_timings(ours) == _without_timings(check)
    assert ours["requirements"] == [
        {"requirement": "p_success >= 0.85", "property": "p_success",
         "value": pytest.approx(0.8954, abs=1e-4), "holds": True, "decided": True}]


def test_the_failure_breakdown_and_paths_are_explains(tiny_report: Made) -> None:
    explain = command_json("explain", EXAMPLE, *TINY_ARGS)
    ours = tiny_report.data["explain"]
    assert isinstance(ours, dict)
    assert ours["p_failure"] == explain["p_failure"]
    assert ours["breakdown"] == explain["breakdown"]
    paths = explain["paths"]
    assert isinstance(paths, list)
    assert ours["paths"] == [{"probability": p["probability"], "steps": p["steps"]}
                             for p in paths]


def test_mission_time_is_distributions(tiny_report: Made) -> None:
    ours = tiny_report.data["distribution"]
    assert isinstance(ours, dict)
    deadlines = [d["deadline"] for d in ours["deadlines"]]
    assert deadlines == ["2d", "3d"]  # the working days this mission can end in
    args = [arg for d in deadlines for arg in ("--deadline", d)]
    assert ours == command_json("distribution", EXAMPLE, *TINY_ARGS, *args)


def test_the_estimates_are_simulates_beside_checks_values(tiny_report: Made) -> None:
    simulate = command_json("simulate", EXAMPLE, *TINY_ARGS, "--runs", "1000")
    check = command_json("check", EXAMPLE, *TINY_ARGS)
    ours = tiny_report.data["simulate"]
    assert isinstance(ours, dict) and isinstance(simulate["results"], dict)
    assert (ours["runs"], ours["seed"], ours["max_steps"]) == (1000, 0, 100_000)
    assert ours["results"].keys() == simulate["results"].keys()
    for name, theirs in simulate["results"].items():
        mine = ours["results"][name]
        for key in ("estimate", "ci95", "runs", "undecided"):
            assert mine[key] == theirs[key], (name, key)
        # The exact value beside an estimate is the verdict's (check's) own.
        assert mine["value"] == check["results"][name]  # type: ignore[index]
