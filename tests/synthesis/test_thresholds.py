"""The threshold table of hand-made strategies on SMALL's MDP: C_NEW 60 (cap 59 after
a recharge), voltage low below 15, medium 15..45, high from 46; route k=0 at the base
with 4 turbines, k=1 one cell away ([1,0]) with 2; BS1's reserve 18 units."""

from __future__ import annotations

import re
from collections.abc import Sequence

import pytest

from tests.render.spec_mdp import State
from veribattery.config import derive_parameters, load_config
from veribattery.synthesis.bs1_rule import bs1_least_go_on
from veribattery.synthesis.strategy import StrategyError, strategy_frame
from veribattery.synthesis.thresholds import ThresholdRow, ThresholdTable, threshold_table

SMALL = ("farm.cols=3", "farm.rows=2", "farm.base=[0,0]", "battery.capacity_ah=6",
         "battery.max_recharges=8", "environment.p_wsp_c=0.3")
PARAMS = derive_parameters(load_config("", SMALL))


def _table(states: Sequence[tuple[State, str]],
           indifferent: Sequence[bool] | None = None) -> ThresholdTable:
    columns = {name: [getattr(x, name) for x, _ in states] for name in State._fields}
    return threshold_table(strategy_frame(columns, [a for _, a in states],
                                          indifferent=indifferent), PARAMS)


def _at_k1(*charges_actions: tuple[int, str], s: int = 2) -> list[tuple[State, str]]:
    """Decisions to inspect cell k=1 (no turbine done), low wind, no recharge."""
    return [(State(s, 1, 0, b, 0, 0), a) for b, a in charges_actions]


def _row(table: ThresholdTable, level: str) -> ThresholdRow:
    (row,) = [r for r in table.rows if r.level == level]
    return row


def test_a_threshold_in_each_level_but_not_across_them() -> None:
    """Medium: back at 20, inspect at 30; high: back at 50, inspect at 55. Each level is a
    threshold, the situation is not (it returns at 50 above going on at 30)."""
    table = _table(_at_k1((20, "back"), (30, "inspect"), (50, "back"), (55, "inspect")))
    medium, high = _row(table, "medium"), _row(table, "high")
    assert (medium.least_go_on, medium.greatest_turn_back, medium.threshold) == (30, 20, True)
    assert (high.least_go_on, high.greatest_turn_back, high.threshold) == (55, 50, True)
    assert not medium.threshold_across_levels and not high.threshold_across_levels
    assert table.non_thresholds == ()
    assert (high.decision, high.k, high.cell, high.turbines_done, high.wind, high.recharges) == (
        "inspect", 1, (1, 0), 0, "low", 0)
    assert (medium.level_from, medium.level_to, high.level_from, high.level_to) == (15, 45, 46, 60)
    # BS1 never inspects at medium voltage here (40 + 18 > 45), from 36 + 18 at high.
    assert (medium.bs1_least_go_on, high.bs1_least_go_on) == (None, 54)


def test_a_threshold_across_levels() -> None:
    table = _table(_at_k1((20, "back"), (30, "back"), (50, "inspect"), (55, "inspect")))
    assert all(r.threshold and r.threshold_across_levels for r in table.rows)
    assert _row(table, "medium").least_go_on is None
    assert _row(table, "high").greatest_turn_back is None


def test_returning_above_going_on_is_not_a_threshold() -> None:
    table = _table(_at_k1((20, "inspect"), (25, "back"), (30, "inspect")))
    (row,) = table.rows
    assert (row.least_go_on, row.greatest_turn_back) == (20, 25)
    assert not row.threshold and not row.threshold_across_levels
    assert table.non_thresholds == (row,)
    assert (row.states, row.going_on, row.returning, row.giving_up) == (3, 2, 1, 0)


def test_giving_up_turns_back_too() -> None:
    (row,) = _table(_at_k1((20, "inspect"), (25, "abort"))).rows
    assert (row.greatest_turn_back, row.giving_up, row.returning, row.threshold) == (
        25, 1, 0, False)


def test_indifferent_states_are_counted_not_judged() -> None:
    (row,) = _table(_at_k1((20, "inspect"), (25, "back"), (30, "inspect")),
                    indifferent=[False, True, False]).rows
    assert (row.states, row.indifferent, row.going_on, row.returning) == (3, 1, 2, 0)
    assert (row.least_go_on, row.greatest_turn_back, row.threshold) == (20, None, True)


def test_decision_kinds_and_what_is_not_a_decision() -> None:
    """s=0 in low wind: take off; s=1: fly; s=2 and s=3 with turbines left: inspect;
    s=3 with the cell done and a next cell: next. Not decisions: the ground in high
    wind, s=4, the last cell done (only backnext), landed, failed, success."""
    states = [
        (State(0, 0, 0, 60, 0, 0), "takeoff"), (State(0, 0, 0, 60, 0, 1), "wait"),
        (State(1, 0, 0, 59, 0, 0), "land"), (State(3, 0, 3, 40, 0, 0), "back"),
        (State(3, 0, 4, 20, 0, 1), "next"), (State(3, 1, 2, 20, 1, 0), "backnext"),
        (State(4, 1, 2, 10, 1, 0), "land"), (State(5, 1, 0, 5, 1, 0), "recharge"),
        (State(6, 1, 0, 0, 1, 0), ""), (State(7, 2, 0, 3, 1, 0), ""),
    ]
    table = _table(states)
    found = {(r.decision, r.k, r.turbines_done, r.wind, r.least_go_on, r.greatest_turn_back)
             for r in table.rows}
    assert found == {("takeoff", 0, 0, "low", 60, None), ("fly", 0, 0, "low", None, 59),
                     ("inspect", 0, 3, "low", None, 40), ("next", 0, 4, "high", 20, None)}
    assert sum(r.states for r in table.rows) == 4
    assert [r.decision for r in table.rows] == ["takeoff", "fly", "inspect", "next"]


def test_rows_in_mission_order() -> None:
    states = [(State(2, 1, 0, 50, 1, 0), "inspect"), (State(2, 1, 0, 50, 0, 1), "back"),
              (State(1, 1, 0, 50, 0, 0), "fly"), (State(0, 1, 0, 59, 0, 0), "takeoff"),
              (State(2, 0, 1, 50, 0, 0), "inspect"), (State(2, 1, 0, 20, 0, 0), "back")]
    keys = [(r.k, r.turbines_done, r.decision, r.recharges, r.wind, r.level)
            for r in _table(states).rows]
    assert keys == [(0, 1, "inspect", 0, "low", "high"), (1, 0, "takeoff", 0, "low", "high"),
                    (1, 0, "fly", 0, "low", "high"), (1, 0, "inspect", 0, "low", "medium"),
                    (1, 0, "inspect", 0, "high", "high"), (1, 0, "inspect", 1, "low", "high")]


def test_bs1_column_is_the_rule() -> None:
    states = [(State(0, k, 0, 59, rc, 0), "takeoff") for k in (0, 1) for rc in (0, 3, 8)]
    states += [(State(3, 0, 4, b, 2, w), "next") for b in (16, 30, 50) for w in (0, 1)]
    for row in _table(states).rows:
        level = ("low", "medium", "high").index(row.level)
        assert row.bs1_least_go_on == bs1_least_go_on(
            PARAMS, row.decision, row.k, ("low", "high").index(row.wind), row.recharges, level)


def test_frame_has_one_column_per_field() -> None:
    table = _table(_at_k1((20, "back"), (50, "inspect")))
    frame = table.frame()
    assert list(frame.columns) == list(ThresholdRow.__slots__)
    assert len(frame) == 2
    assert frame["least_go_on"].isna().tolist() == [True, False]
    assert str(frame["least_go_on"].dtype) == "Int64"


@pytest.mark.parametrize(("states", "message"), [
    (_at_k1((20, "jump")), "unknown action(s) 'jump'"),
    (_at_k1((20, "land")), "'land' is not a choice at a 'inspect' decision"),
    (_at_k1((20, "next")), "'next' is not a choice at a 'inspect' decision"),
    ([(State(0, 0, 0, 60, 0, 0), "wait")], "'wait' is not a choice at a 'takeoff' decision"),
])
def test_actions_that_do_not_fit(states: list[tuple[State, str]], message: str) -> None:
    with pytest.raises(StrategyError, match=re.escape(message)):
        _table(states)


def test_malformed_strategies() -> None:
    with pytest.raises(StrategyError, match="no values for the variable"):
        strategy_frame({"s": [0], "k": [0]}, ["wait"])
    with pytest.raises(StrategyError, match="different lengths"):
        strategy_frame({name: [0] for name in State._fields}, ["wait", "wait"])


def test_no_decision_no_row() -> None:
    assert _table([]).rows == ()
    assert _table([(State(5, 0, 0, 3, 0, 0), "recharge"), (State(4, 1, 0, 9, 0, 1), "abort")]
                  ).rows == ()
