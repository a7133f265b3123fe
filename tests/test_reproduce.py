"""The paper's figures from sweep frames: files written, CSV values equal the sweep's."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import pandas as pd
import pytest
from click.testing import CliRunner

from tests.sweep.helpers import SMALL_FARM
from veribattery.analyses import figures
from veribattery.cli import cli
from veribattery.sweep import parse_axis, run_sweep

#: The four models at two capacities inside Fig. 6's zoom window, on the tiny mission.
AXES = (f"battery.model={','.join(figures.MODELS)}", "battery.capacity_ah=12:12.5:0.5")


@pytest.fixture(scope="module")
def frame() -> pd.DataFrame:
    # A stand-in for the conditional expectation, to exercise Fig. 8's third-panel hook.
    given = f"properties.{figures.GIVEN_SUCCESS}=" + "'R{\"mt\"}=? [ F \"done\" ]'"
    sets = [*SMALL_FARM, "properties.p_success='P=? [ F \"success\" ]'",
            "properties.exp_mission_time='R{\"mt\"}=? [ F \"done\" ]'", given]
    return run_sweep("", [parse_axis(a) for a in AXES], sets, jobs=1)


def _value(frame: pd.DataFrame, model: str, capacity: float, prop: str) -> float:
    rows = frame[(frame["battery.model"] == model) & (frame["battery.capacity_ah"] == capacity)
                 & (frame["property"] == prop)]
    return float(rows["value"].iloc[0])


def test_fig6_files_and_values(frame: pd.DataFrame, tmp_path: Path) -> None:
    paths = figures.draw_fig6(frame, tmp_path)
    assert [p.name for p in paths] == ["fig6.png", "fig6.svg", "fig6.csv"]
    assert paths[0].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert b"<svg" in paths[1].read_bytes()[:500]
    table = pd.read_csv(paths[2], index_col="capacity_ah")
    assert list(table.columns) == [f"p_success:{m}" for m in figures.MODELS]
    for model in figures.MODELS:
        for capacity in (12, 12.5):
            assert table.loc[capacity, f"p_success:{model}"] == _value(
                frame, model, capacity, "p_success")


def test_fig8_difference_and_third_panel_hook(frame: pd.DataFrame, tmp_path: Path) -> None:
    paths = figures.draw_fig8(frame, tmp_path)
    table = pd.read_csv(paths[2], index_col="capacity_ah")
    advanced = _value(frame, "advanced", 12.5, "exp_mission_time")
    basic_low = _value(frame, "basic_low", 12.5, "exp_mission_time")
    assert table.loc[12.5, "exp_mission_time:basic_low"] == basic_low
    assert table.loc[12.5, "minus_advanced:basic_low"] == basic_low - advanced
    # The property is present, so the third panel (and its columns) is drawn.
    assert f"{figures.GIVEN_SUCCESS}:advanced" in table.columns
    without = frame[frame["property"] != figures.GIVEN_SUCCESS]
    table = pd.read_csv(figures.draw_fig8(without, tmp_path / "two")[2])
    assert not any(c.startswith(figures.GIVEN_SUCCESS) for c in table.columns)


def test_reproduce_all_needs_an_output_folder() -> None:
    result = CliRunner().invoke(cli, ["reproduce", "all"])
    assert result.exit_code == 2
    assert "-o DIR" in result.stderr


def _finished_sweep(folder: Path, name: str, axes: Sequence[str], sets: Sequence[str],
                    skip: int | None = None) -> None:
    """A sweep's results on disk as `reproduce` writes them, with synthetic values
    (``value`` = capacity / 20, or 0.5 without a capacity), every point but *skip*."""
    from veribattery.config import load_config
    from veribattery.sweep import grid
    from veribattery.sweep.fingerprint import fingerprint
    from veribattery.sweep.run import FIXED_COLUMNS

    parsed = [parse_axis(a) for a in axes]
    cfg = load_config("", sets)
    (folder / f"{name}.sweep.json").write_text(fingerprint(cfg, sets, parsed).as_json())
    rows = []
    for index, point in enumerate(grid(parsed)):
        value = float(point.get("battery.capacity_ah", 10)) / 20  # type: ignore[arg-type]
        rows += [{"point": index, **point, "property": prop, "value": value, "states": 1,
                  "transitions": 1, "seconds": 0.0, "recharge_cap_probability": 0.0}
                 for prop in cfg.properties if index != skip]
    columns = ["point", *(a.key for a in parsed), *FIXED_COLUMNS]
    pd.DataFrame(rows, columns=columns).to_csv(folder / name, index=False)


def test_reproduce_fig6_resumes_a_finished_sweep_and_draws(tmp_path: Path) -> None:
    # A complete capacity sweep already on disk (synthetic values): `reproduce` must
    # resume it (checking nothing) and draw from it.
    from veribattery.config import load_config

    sets = figures.capacity_sets(["fig6"])  # Fig. 6 alone checks P(success) alone
    assert load_config("", sets).properties == {"p_success": 'P=? [ F "success" ]'}
    _finished_sweep(tmp_path, figures.capacity_results(["fig6"]), figures.CAPACITY_AXES, sets)
    result = CliRunner().invoke(cli, ["reproduce", "fig6", "-o", str(tmp_path), "-j", "1"])
    assert result.exit_code == 0, result.output
    assert "604 of 604 points already done" in result.stderr
    table = pd.read_csv(tmp_path / "fig6.csv", index_col="capacity_ah")
    assert len(table) == 151
    assert table.loc[12.3, "p_success:basic_low"] == pytest.approx(12.3 / 20, rel=1e-15)
    assert (tmp_path / "fig6.png").stat().st_size > 10_000


def test_reproduce_all_resumes_and_checks_only_what_is_missing(tmp_path: Path) -> None:
    # Table 3's sweep finished, the capacity sweep interrupted one point short (the
    # advanced model at 5.0 Ah: a 3-state model, checked for real here): `all` resumes.
    _finished_sweep(tmp_path, figures.TABLE3_RESULTS, figures.TABLE3_AXES, ())
    _finished_sweep(tmp_path, figures.CAPACITY_RESULTS, figures.CAPACITY_AXES,
                    figures.capacity_sets(figures.FIGURES), skip=0)
    result = CliRunner().invoke(cli, ["reproduce", "all", "-o", str(tmp_path), "-j", "1"])
    assert result.exit_code == 0, result.output
    assert "4 of 4 points already done" in result.stderr
    assert "603 of 604 points already done" in result.stderr
    done = pd.read_csv(tmp_path / figures.CAPACITY_RESULTS)
    first = done[done["point"] == 0].set_index("property")
    assert list(first.index) == ["p_success", "exp_mission_time", figures.GIVEN_SUCCESS]
    assert (first["states"] > 1).all()  # really checked (the synthetic rows say 1 state)
    assert first.loc["p_success", "value"] == 0.0  # 5.0 Ah cannot fly the mission
    for name in ("table3.csv", "fig6.png", "fig6.svg", "fig6.csv", "fig8.png", "fig8.csv"):
        assert (tmp_path / name).stat().st_size > 0


def test_each_figure_checks_only_the_properties_it_draws() -> None:
    from veribattery.config import load_config

    def checked(drawn: list[str]) -> list[str]:
        return list(load_config("", figures.capacity_sets(drawn)).properties)

    assert checked(["fig6"]) == ["p_success"]
    assert checked(["fig8"]) == ["exp_mission_time", figures.GIVEN_SUCCESS]
    assert checked(["fig8", "fig6"]) == ["p_success", "exp_mission_time",
                                         figures.GIVEN_SUCCESS]
    assert figures.capacity_results(["fig6", "fig8"]) == figures.CAPACITY_RESULTS
    assert figures.capacity_results(["fig8"]) == "fig8_sweep.csv"


def _optimal(frame: pd.DataFrame) -> pd.DataFrame:
    """A stand-in for Pmax: BS1's P(success) raised half-way to 1, within +-1e-9."""
    points = frame[frame["property"] == "p_success"]
    best = points[["battery.model", "battery.capacity_ah"]].reset_index(drop=True)
    value = (points["value"].to_numpy() + 1) / 2
    best["p_success_max"], best["p_success_max_lower"] = value, value - 1e-9
    best["p_success_max_upper"] = value + 1e-9
    return best


def test_fig6_with_the_optimal_curves(frame: pd.DataFrame, tmp_path: Path) -> None:
    optimal = _optimal(frame)
    paths = figures.draw_fig6(frame, tmp_path, optimal)
    table = pd.read_csv(paths[2], index_col="capacity_ah")
    assert list(table.columns) == [f"{column}:{m}" for column in
                                   ("p_success", *figures.OPTIMAL_COLUMNS)
                                   for m in figures.MODELS]
    bs1 = _value(frame, "basic_medium", 12.5, "p_success")
    assert table.loc[12.5, "p_success:basic_medium"] == bs1
    assert table.loc[12.5, "p_success_max:basic_medium"] == (bs1 + 1) / 2
    assert table.loc[12.5, "p_success_max_upper:basic_medium"] == (bs1 + 1) / 2 + 1e-9


def test_reproduce_fig6_optimal_sweeps_pmax_of_each_model_and_capacity_resumably(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # Pmax of the paper's farm is too slow here (tests/sweep/test_synthesis_points.py
    # checks the values): a stand-in records the MDPs asked, in the sweep's order.
    from veribattery.cli import reproduce
    from veribattery.synthesis import sweep_pmax
    from veribattery.synthesis.model import Certified, ModelSize

    asked: list[str] = []

    def pmax(text: str) -> sweep_pmax.MissionPmax:
        asked.append(text)
        return sweep_pmax.MissionPmax(Certified(0.9, 0.8, 1.0), ModelSize(3, 4, 5))

    monkeypatch.setattr(sweep_pmax, "pmax_of_model", pmax)
    monkeypatch.setattr(reproduce, "PROGRESS_EVERY_S", 0.0)  # a line per point, not per 25
    sets = figures.capacity_sets(["fig6"])
    _finished_sweep(tmp_path, figures.capacity_results(["fig6"]), figures.CAPACITY_AXES, sets)
    args = ["reproduce", "fig6", "-o", str(tmp_path), "-j", "1", "--optimal"]
    result = CliRunner().invoke(cli, args)
    assert result.exit_code == 0, result.output
    assert "Pmax of success" in result.stderr
    assert "\n1 of 604 points\n2 of 604 points\n" in result.stderr
    assert len(asked) == 604
    assert "Synthesis mode" in asked[0] and "[abort]" in asked[0]  # the mission MDP
    swept = pd.read_csv(tmp_path / figures.OPTIMAL_RESULTS)
    assert len(swept) == 604 * 3
    first, last = swept.iloc[0], swept.iloc[-1]
    assert (first["battery.model"], first["battery.capacity_ah"]) == ("advanced", 5.0)
    assert (last["battery.model"], last["battery.capacity_ah"]) == ("basic_low", 20.0)
    table = pd.read_csv(tmp_path / "fig6.csv", index_col="capacity_ah")
    assert table.loc[12.8, "p_success_max_lower:advanced"] == 0.8
    assert table.loc[12.8, "p_success_max_upper:basic_low"] == 1.0
    # a rerun resumes the finished Pmax sweep: nothing is asked again
    again = CliRunner().invoke(cli, [*args, "--force"])
    assert again.exit_code == 0, again.output
    assert len(asked) == 604
    assert "604 of 604 points already done" in again.stderr


def test_optimal_is_for_fig6() -> None:
    result = CliRunner().invoke(cli, ["reproduce", "fig8", "-o", "x", "--optimal"])
    assert result.exit_code == 2
    assert "--optimal" in result.stderr
