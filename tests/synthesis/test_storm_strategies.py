"""Threshold tables of strategies Storm computes or follows, on small mission MDPs.

Storm builds the rendered MDP (or BS1's DTMC); its scheduler, followed from the initial
state, gives the states and actions; the exact values of the spec's own reading
(tests/render/spec_mdp.py) say where going on and turning back are equally good.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pandas as pd
import pytest

from veribattery.config import MissionConfig, derive_parameters, load_config
from veribattery.render import render_model, render_synthesis_model
from veribattery.synthesis.strategy import STATE_VARIABLES, strategy_frame
from veribattery.synthesis.thresholds import ThresholdRow, ThresholdTable, threshold_table

stormpy = pytest.importorskip("stormpy")

from tests.render.spec_mdp import SpecMission, max_success  # noqa: E402
from tests.synthesis.storm_strategy import (  # noqa: E402
    StormMdp,
    exactly_optimal,
    indifference,
)

#: One cell of four turbines at the base, 5 Ah (C_NEW 50) and 3 recharges: every
#: sortie must inspect exactly one turbine, which it can only in low wind.
TINY = ("farm.cols=2", "farm.rows=2", "farm.base=[0,0]", "battery.capacity_ah=5",
        "battery.max_recharges=3")
SMALL = ("farm.cols=3", "farm.rows=2", "farm.base=[0,0]", "battery.capacity_ah=6",
         "battery.max_recharges=8", "environment.p_wsp_c=0.3")
THREE = ("farm.cols=3", "farm.rows=3", "farm.base=[1,1]", "battery.capacity_ah=6",
         "battery.max_recharges=12")


def _pmax_table(cfg: MissionConfig, folder: Path) -> tuple[ThresholdTable, float, bool]:
    """The table of Storm's Pmax strategy over the states it reaches, indifference
    exact; Storm's Pmax; and whether every choice Storm makes is exactly optimal
    wherever going on and turning back are not equally good."""
    mdp = StormMdp.build(render_synthesis_model(cfg), folder)
    rows, pmax, _ = mdp.optimal('Pmax=? [ F "success" ]')
    reference = SpecMission.of(cfg).reachable()
    value = max_success(reference)
    indifferent = indifference(reference, value)
    states = mdp.reachable(rows)
    named = [mdp.state(s) for s in states]
    strategy = mdp.strategy(rows, states, [indifferent(x) for x in named])
    optimal = all(exactly_optimal(reference, value, x, mdp.labels[rows[s]])
                  for s, x in zip(states, named, strict=True)
                  if x.s < 6 and not indifferent(x))
    return threshold_table(strategy, derive_parameters(cfg)), pmax, optimal


def _find(table: ThresholdTable, decision: str, j: int, wind: str, rc: int,
          level: str) -> ThresholdRow:
    (row,) = [r for r in table.rows if (r.decision, r.turbines_done, r.wind, r.recharges,
                                        r.level) == (decision, j, wind, rc, level)]
    return row


def test_tiny_pmax_strategy_by_hand(tmp_path: Path) -> None:
    """TINY, by hand: a sortie takes off in low wind (1 unit at high voltage: 49 left, or
    48 after a recharge, cap(1..3) = floor(50 x 0.998..0.994) = 49), flies for free (the
    cell is the base) and must find low wind to inspect (36 units; 72 in high wind is
    more than it has): after the take-off and the flight, P(low) = 0.9^2 + 0.1^2 = 0.82,
    so Pmax = 0.82^4. With 13 units left (12 after a recharge: SOC 12/49 < 0.25, low
    voltage) a second inspection (40 or 45) cannot be paid: it returns. BS1 (safe_t 0.3)
    never even takes off: 1 + 36 + 15 > 50."""
    table, pmax, optimal = _pmax_table(load_config("", TINY), tmp_path)
    assert pmax == pytest.approx(0.82**4, rel=1e-12)
    assert optimal
    cap = (50, 49, 49, 49)
    for rc in range(4):  # the sortie that inspects turbine rc + 1
        takeoff = _find(table, "takeoff", rc, "low", rc, "high")
        inspect = _find(table, "inspect", rc, "low", rc, "high")
        assert (takeoff.least_go_on, takeoff.greatest_turn_back) == (cap[rc], None)
        assert (inspect.least_go_on, inspect.greatest_turn_back) == (cap[rc] - 1, None)
        assert takeoff.indifferent == inspect.indifferent == 0
    for rc, level, left in ((0, "medium", 13), (1, "low", 12), (2, "low", 12)):
        after = _find(table, "inspect", rc + 1, "low", rc, level)
        assert (after.least_go_on, after.greatest_turn_back, after.returning) == (None, left, 1)
    assert table.non_thresholds == ()
    assert {r.bs1_least_go_on for r in table.rows} == {None}
    # A sortie that met high wind at the cell has wasted its charge: nothing matters after.
    wasted = _find(table, "takeoff", 0, "low", 1, "high")
    assert (wasted.states, wasted.indifferent, wasted.least_go_on) == (1, 1, None)


@pytest.mark.parametrize("overrides", [SMALL, THREE], ids=["small", "three-by-three"])
def test_pmax_strategies_are_thresholds(overrides: tuple[str, ...], tmp_path: Path) -> None:
    """Storm's Pmax strategies on SMALL and a 3 x 3 farm: exactly optimal wherever the
    choice matters, and a threshold in the charge in every situation, within each
    voltage level and across them."""
    cfg = load_config("", overrides)
    table, pmax, optimal = _pmax_table(cfg, tmp_path)
    spec = SpecMission.of(cfg)
    assert pmax == pytest.approx(float(max_success(spec.reachable())[spec.initial]), rel=1e-9)
    assert optimal
    frame_ = table.frame()
    decisive = frame_["states"] - frame_["indifferent"]
    assert decisive.sum() > 100 and frame_["least_go_on"].notna().sum() > 20
    assert frame_["greatest_turn_back"].notna().sum() > 20
    assert table.non_thresholds == ()
    assert frame_["threshold_across_levels"].all()


def _bs1_strategy(cfg: MissionConfig, folder: Path) -> pd.DataFrame:
    """BS1's DTMC as a strategy of the MDP (every state of it is reachable under BS1):
    its failures in flight and on the ground (oob, infeasible) are the MDP's abort."""
    dtmc = StormMdp.build(render_model(cfg), folder, "bs1.prism")
    s = dtmc.variables["s"]
    labels = dtmc.labels.copy()
    labels[(labels == "infeasible") | ((labels == "oob") & (s != 5))] = "abort"
    return strategy_frame({name: dtmc.variables[name] for name in STATE_VARIABLES},
                          labels.tolist())


def _below(charge: Any, threshold: Any) -> bool:
    """*charge* (None: none) lies below *threshold* (None: never goes on)."""
    return pd.isna(charge) or pd.isna(threshold) or charge < threshold


BS1_CASES = {
    "small": SMALL,
    "small-12Ah": (*SMALL, "battery.capacity_ah=12"),
    "basic-low-10Ah": (*SMALL, "battery.model=basic_low", "battery.capacity_ah=10",
                       "strategy.safe_t=0.1"),
    "three-by-three-10Ah": ("farm.cols=3", "farm.rows=3", "farm.base=[1,1]",
                            "battery.capacity_ah=10", "battery.max_recharges=12",
                            "strategy.safe_t=0.2"),
}


@pytest.mark.parametrize("name", list(BS1_CASES))
def test_bs1s_strategy_is_its_rule(name: str, tmp_path: Path) -> None:
    """BS1's own strategy comes out a pure threshold table, each row's charges on either
    side of the rule's threshold computed from the config: every state at or above it
    goes on, every state below turns back."""
    cfg = load_config("", BS1_CASES[name])
    table = threshold_table(_bs1_strategy(cfg, tmp_path), derive_parameters(cfg))
    rows = table.frame()
    assert table.non_thresholds == () and rows["threshold_across_levels"].all()
    assert all(_below(r.greatest_turn_back, r.bs1_least_go_on) for r in rows.itertuples())
    assert all(pd.isna(r.least_go_on) or r.least_go_on >= r.bs1_least_go_on
               for r in rows.itertuples())
    assert rows["going_on"].sum() > 40 and rows["returning"].sum() > 40


def test_bs1_tight_at_its_threshold(tmp_path: Path) -> None:
    """On the 3 x 3 farm at 10 Ah BS1 reaches charges right at its threshold: in 31 rows
    it goes on at exactly the rule's charge, in 31 it returns one unit below."""
    cfg = load_config("", BS1_CASES["three-by-three-10Ah"])
    rows = threshold_table(_bs1_strategy(cfg, tmp_path), derive_parameters(cfg)).frame()
    assert (rows["least_go_on"] == rows["bs1_least_go_on"]).sum() == 31
    assert (rows["greatest_turn_back"] == rows["bs1_least_go_on"] - 1).sum() == 31


def test_a_non_threshold_strategy_is_flagged(tmp_path: Path) -> None:
    """BS1 on the 3 x 3 farm, changed in one state: where it inspected with the most
    charge of its row, it now flies back. That row, and no other, is not a threshold,
    and its situation is not one across the levels either."""
    cfg = load_config("", BS1_CASES["three-by-three-10Ah"])
    params = derive_parameters(cfg)
    strategy = _bs1_strategy(cfg, tmp_path)
    table = threshold_table(strategy, params)
    row = next(r for r in table.rows if r.decision == "inspect" and r.going_on >= 2)
    same = ((strategy["k"] == row.k) & (strategy["j"] == row.turbines_done)
            & (strategy["rc"] == row.recharges)
            & (strategy["wsp"] == ("low", "high").index(row.wind))
            & strategy["b"].between(row.level_from, row.level_to)
            & (strategy["action"] == "inspect") & strategy["s"].isin([2, 3]))
    top = strategy[same]["b"].idxmax()
    changed = strategy.copy()
    changed.loc[top, "action"] = "back"
    after = threshold_table(changed, params)
    (flagged,) = after.non_thresholds
    assert flagged.greatest_turn_back == strategy.loc[top, "b"] > flagged.least_go_on
    assert flagged.least_go_on == row.least_go_on
    assert (flagged.going_on, flagged.returning) == (row.going_on - 1, row.returning + 1)
    situation = [r for r in after.rows if (r.decision, r.k, r.turbines_done, r.wind,
                                           r.recharges) == (row.decision, row.k,
                                                            row.turbines_done, row.wind,
                                                            row.recharges)]
    assert not any(r.threshold_across_levels for r in situation)
    unchanged = [r for r in after.rows if r not in situation]
    assert len(after.rows) == len(table.rows) and len(unchanged) > 100
    assert unchanged == [r for r in table.rows if r in unchanged]
