"""Sweep points in synthesis mode (``strategy.mode: synthesize``; ``reproduce fig6
--optimal``): the best return policy's certified Pmax of success at each point, at least
BS1's P(success) at the same battery and wind, independent of ``safe_t``, equal to
Storm's Pmax on the emitted MDP; requirements judged on it; a pool gives the same rows."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest
from click.testing import CliRunner

from veribattery.cli import cli
from veribattery.config import load_config
from veribattery.render import render_synthesis_model
from veribattery.sweep import parse_axis, run_sweep

#: Two cells (4 and 2 turbines, the second one cell away): BS1 flies nothing at 4 Ah
#: and loses missions at 5-6 Ah that a better return policy saves.
SMALL = ("farm.cols=3", "farm.rows=2", "farm.base=[0,0]", "battery.max_recharges=8")
AXES = ("battery.capacity_ah=4:6:1", "environment.p_wsp_c=0.1,0.3", "strategy.safe_t=0.1,0.3",
        "strategy.mode=bs1,synthesize")
KEYS = ["battery.capacity_ah", "environment.p_wsp_c", "strategy.safe_t"]


def _sweep(jobs: int, axes: tuple[str, ...] = AXES,
           sets: tuple[str, ...] = SMALL) -> pd.DataFrame:
    return run_sweep("", [parse_axis(a) for a in axes], sets, jobs=jobs)


def _values(frame: pd.DataFrame, prop: str) -> pd.Series:
    rows = frame[frame["property"] == prop]
    return rows.set_index([str(k) for k in KEYS])["value"].astype(float)


@pytest.fixture(scope="module")
def frame() -> pd.DataFrame:
    return _sweep(jobs=1)


def test_a_synthesis_point_gives_pmax_and_its_certified_interval(frame: pd.DataFrame) -> None:
    synthesis = frame[frame["strategy.mode"] == "synthesize"]
    assert synthesis["error"].isna().all()
    assert set(synthesis["property"]) == {"p_success_max", "p_success_max_lower",
                                          "p_success_max_upper"}
    best, lower, upper = (_values(frame, name) for name in
                          ("p_success_max", "p_success_max_lower", "p_success_max_upper"))
    assert ((lower <= best) & (best <= upper)).all()
    assert (upper - lower).max() < 1e-9
    # the 3x2 farm's MDP at 6 Ah in calm wind (tests/synthesis: 1,431 states)
    sizes = synthesis.drop_duplicates("point").set_index(KEYS)["states"]
    assert sizes[6, 0.1, 0.3] == 1431


def test_pmax_does_not_depend_on_safe_t_and_is_at_least_bs1(frame: pd.DataFrame) -> None:
    best, upper = _values(frame, "p_success_max"), _values(frame, "p_success_max_upper")
    bs1 = _values(frame, "p_success")
    for capacity in (4, 5, 6):
        for wind in (0.1, 0.3):
            assert best[capacity, wind, 0.1] == best[capacity, wind, 0.3]  # bit for bit
            for safe_t in (0.1, 0.3):
                assert bs1[capacity, wind, safe_t] <= upper[capacity, wind, safe_t]
    assert best[4, 0.1, 0.3] == 0.0  # 4 Ah: nobody flies the mission
    # 5 Ah, gusty wind: BS1 at safe_t 0.3 never succeeds, the best policy does
    assert bs1[5, 0.3, 0.3] == 0.0
    assert best[5, 0.3, 0.3] == pytest.approx(0.08533337310730925, rel=1e-9)
    assert best[6, 0.1, 0.3] - bs1[6, 0.1, 0.3] > 0.0  # 0.9385 against 0.9270


def test_storm_agrees_on_an_emitted_mdp(frame: pd.DataFrame, tmp_path: Path) -> None:
    stormpy = pytest.importorskip("stormpy")
    path = tmp_path / "model.prism"
    path.write_text(render_synthesis_model(load_config("", (*SMALL, "battery.capacity_ah=6"))))
    program = stormpy.parse_prism_program(str(path))
    prop = stormpy.parse_properties('Pmax=? [ F "success" ]', program)
    model = stormpy.build_model(program, prop)
    storm = float(stormpy.model_checking(model, prop[0]).get_value(model.initial_states[0]))
    assert 0 < storm < 1
    best = _values(frame, "p_success_max")[6, 0.1, 0.3]
    assert best == pytest.approx(storm, rel=1e-9)
    lower, upper = (_values(frame, f"p_success_max_{end}")[6, 0.1, 0.3]
                    for end in ("lower", "upper"))
    assert lower - 1e-12 <= storm <= upper + 1e-12


def test_a_pool_gives_the_same_rows(frame: pd.DataFrame) -> None:
    axes = ("battery.capacity_ah=5:6:1", "environment.p_wsp_c=0.3", "strategy.safe_t=0.3",
            "strategy.mode=synthesize")
    pooled = _sweep(jobs=2, axes=axes)
    mine = _values(frame, "p_success_max")
    for capacity in (5, 6):
        rows = pooled[(pooled["battery.capacity_ah"] == capacity)
                      & (pooled["property"] == "p_success_max")]
        assert float(rows["value"].iloc[0]) == mine[capacity, 0.3, 0.3]


def test_requirements_are_judged_on_pmax_and_the_others_are_warned_about() -> None:
    sets = (*SMALL, "environment.p_wsp_c=0.3", "strategy.mode=synthesize",
            'requirements=["p_success >= 0.05", "exp_mission_time <= 600"]')
    frame = _sweep(jobs=1, axes=("battery.capacity_ah=4:5:1",), sets=sets)
    best = frame[frame["property"] == "p_success_max"].set_index("battery.capacity_ah")
    assert best.loc[4, "requirement"] == "p_success >= 0.05"
    assert not best.loc[4, "holds"]  # Pmax 0
    assert best.loc[5, "holds"]  # Pmax 0.0853: some policy meets 0.05
    warnings = frame.attrs["warnings"]
    assert len(warnings) == 1
    assert warnings[0].startswith("exp_mission_time <= 600 asks nothing of the MDP")


def test_the_cli_sweeps_both_modes_and_plots_pmax(tmp_path: Path) -> None:
    plot, config = tmp_path / "pmax.png", tmp_path / "mission.yaml"
    config.write_text("farm: {cols: 3, rows: 2, base: [0, 0]}\n"
                      "battery: {max_recharges: 8}\n")
    args = ["sweep", str(config), "--vary", "battery.capacity_ah=5:6:1",
            "--vary", "strategy.mode=bs1,synthesize", "-j", "1", "--format", "csv",
            "--plot", str(plot), "--plot-property", "p_success_max"]
    result = CliRunner().invoke(cli, args)
    assert result.exit_code == 0, result.output
    assert plot.stat().st_size > 0
    assert "p_success_max_upper" in result.stdout
    wrong = CliRunner().invoke(cli, [*args[:-1], "nope"])
    assert wrong.exit_code == 2
    assert "p_success_max" in wrong.stderr  # the names a synthesis point gives


def test_the_table_marks_the_cells_a_mode_does_not_give(tmp_path: Path) -> None:
    config = tmp_path / "mission.yaml"
    config.write_text("farm: {cols: 3, rows: 2, base: [0, 0]}\n"
                      "battery: {max_recharges: 8}\n")
    result = CliRunner().invoke(cli, ["sweep", str(config), "--vary", "battery.capacity_ah=6",
                                      "--vary", "strategy.mode=bs1,synthesize", "-j", "1"])
    assert result.exit_code == 0, result.output
    assert "None" not in result.stdout
    bs1 = next(line for line in result.stdout.splitlines() if " bs1 " in line
               and "—" in line)  # the bs1 row of the p_success_max columns
    assert bs1.split()[:2] == ["6", "bs1"]
    assert "—: no value there" in result.stdout
