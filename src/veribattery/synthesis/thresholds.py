"""A strategy in the mission's words: the least charge at which the drone goes on.

For each decision (take off, fly out, inspect, move to the next cell), route cell,
turbines done there, wind, recharge count and voltage level, the table gives the least
charge at which the strategy goes on and the greatest at which it turns back (returns
or gives up). Where every charge that goes on lies above every charge that turns back,
the strategy is a *threshold* there, as BS1 is; where not, the row says so. Beside each
row stands BS1's own threshold for the same config, from its rule
(:mod:`veribattery.synthesis.bs1_rule`).

States the caller marks indifferent (going on exactly as good as turning back) are
counted but left out of the thresholds: the strategy's choice there is arbitrary.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields

import numpy as np
import pandas as pd

from veribattery.config import ModelParameters
from veribattery.synthesis.bs1_rule import NO_CHARGE, bs1_least_go_on_at
from veribattery.synthesis.decisions import (
    DECISIONS,
    GIVES_UP,
    GOES_ON,
    RETURNS,
    decision_points,
    outcomes,
)
from veribattery.synthesis.levels import LEVEL_NAMES, level_bands, voltage_levels

__all__ = ["ThresholdRow", "ThresholdTable", "threshold_table"]

WIND_NAMES = ("low", "high")
#: A situation: one decision in one cell, wind and recharge count (levels apart).
_SITUATION = ["decision", "k", "j", "wsp", "rc"]
_KEY = [*_SITUATION, "level"]
#: Sentinels for "no such charge" in the integer columns (charges are >= 0).
_NONE_ABOVE = np.iinfo(np.int64).max


@dataclass(frozen=True, slots=True)
class ThresholdRow:
    """One decision in one situation, at one voltage level; charges in units.

    :ivar decision: ``takeoff``, ``fly``, ``inspect`` or ``next``.
    :ivar k: the route index of the cell; *cell* its ``[x, y]``.
    :ivar turbines_done: ``j``, the cell's turbines already inspected.
    :ivar wind: ``low`` or ``high``; *recharges*: ``rc``; *level*: the voltage level.
    :ivar level_from: the least charge at this level (after *recharges*), *level_to*
        the greatest.
    :ivar states: the states reported (decisive and indifferent).
    :ivar indifferent: those where going on is as good as turning back (not in the
        thresholds).
    :ivar going_on: decisive states that go on; *returning*, *giving_up*: that turn back.
    :ivar least_go_on: the least charge going on (None: none goes on).
    :ivar greatest_turn_back: the greatest charge turning back (None: none does).
    :ivar threshold: every charge going on lies above every charge turning back.
    :ivar threshold_across_levels: the same holds over all levels of the situation.
    :ivar bs1_least_go_on: BS1's least charge going on at this level (None: it never does).
    """

    decision: str
    k: int
    cell: tuple[int, int]
    turbines_done: int
    wind: str
    recharges: int
    level: str
    level_from: int
    level_to: int
    states: int
    indifferent: int
    going_on: int
    returning: int
    giving_up: int
    least_go_on: int | None
    greatest_turn_back: int | None
    threshold: bool
    threshold_across_levels: bool
    bs1_least_go_on: int | None

    def as_dict(self) -> dict[str, object]:
        """The row as plain data (the cell as a list), for JSON."""
        out = asdict(self)
        out["cell"] = list(self.cell)
        return out


@dataclass(frozen=True, slots=True)
class ThresholdTable:
    """The rows of :func:`threshold_table`, in mission order, and the charge unit."""

    rows: tuple[ThresholdRow, ...]
    charge_unit_ah: str

    @property
    def non_thresholds(self) -> tuple[ThresholdRow, ...]:
        """The rows where the strategy is not a threshold within the level."""
        return tuple(row for row in self.rows if not row.threshold)

    def frame(self) -> pd.DataFrame:
        """The rows as a DataFrame, one column per field (missing charges as <NA>)."""
        names = [f.name for f in fields(ThresholdRow)]
        frame = pd.DataFrame([[getattr(r, n) for n in names] for r in self.rows],
                             columns=names)
        for name in ("least_go_on", "greatest_turn_back", "bs1_least_go_on"):
            frame[name] = frame[name].astype("Int64")
        return frame


def threshold_table(strategy: pd.DataFrame, params: ModelParameters) -> ThresholdTable:
    """The threshold table of *strategy* on the MDP of *params*.

    :param strategy: a :func:`~veribattery.synthesis.strategy.strategy_frame` (the
        states to report: normally those reachable under the strategy).
    :raises StrategyError: when an action is not a choice at its decision.
    """
    states = strategy.assign(decision=decision_points(strategy, params.layout))
    states = states[states["decision"] != ""]
    states = states.assign(outcome=outcomes(states["action"], states["decision"]),
                           level=voltage_levels(params, states["b"], states["rc"]))
    groups = _grouped(states)
    least, greatest = level_bands(params, groups["level"], groups["rc"])
    bs1 = bs1_least_go_on_at(params, groups["decision"], groups["k"], groups["wsp"],
                             groups["rc"], groups["level"])
    groups = groups.assign(level_from=least, level_to=greatest, bs1=bs1)
    return ThresholdTable(tuple(_rows(_in_mission_order(groups), params)), params.resolution)


def _grouped(states: pd.DataFrame) -> pd.DataFrame:
    """Per key: counts, the least charge going on and the greatest turning back (the
    sentinels where there is none), and whether the situation is a threshold."""
    decisive = ~states["indifferent"]
    goes_on = decisive & (states["outcome"] == GOES_ON)
    turns_back = decisive & (states["outcome"] != GOES_ON)
    b = states["b"]
    work = states.assign(
        going_on=goes_on, returning=decisive & (states["outcome"] == RETURNS),
        giving_up=decisive & (states["outcome"] == GIVES_UP),
        go_b=b.where(goes_on, _NONE_ABOVE), back_b=b.where(turns_back, -1))
    situation = work.groupby(_SITUATION, sort=False)
    work = work.assign(all_go=situation["go_b"].transform("min"),
                       all_back=situation["back_b"].transform("max"))
    return work.groupby(_KEY, sort=False).agg(
        states=("b", "size"), indifferent=("indifferent", "sum"),
        going_on=("going_on", "sum"), returning=("returning", "sum"),
        giving_up=("giving_up", "sum"), least=("go_b", "min"), greatest=("back_b", "max"),
        all_go=("all_go", "first"), all_back=("all_back", "first"),
    ).reset_index()


def _in_mission_order(groups: pd.DataFrame) -> pd.DataFrame:
    order = groups["decision"].map({kind: i for i, kind in enumerate(DECISIONS)})
    return groups.assign(order=order).sort_values(["k", "j", "order", "rc", "wsp", "level"],
                                                  kind="stable")


def _rows(groups: pd.DataFrame, params: ModelParameters) -> list[ThresholdRow]:
    route = params.layout.route
    return [
        ThresholdRow(
            decision=g.decision, k=int(g.k), cell=(int(route[g.k][0]), int(route[g.k][1])),
            turbines_done=int(g.j), wind=WIND_NAMES[g.wsp], recharges=int(g.rc),
            level=LEVEL_NAMES[g.level], level_from=int(g.level_from), level_to=int(g.level_to),
            states=int(g.states), indifferent=int(g.indifferent), going_on=int(g.going_on),
            returning=int(g.returning), giving_up=int(g.giving_up),
            least_go_on=None if g.least == _NONE_ABOVE else int(g.least),
            greatest_turn_back=None if g.greatest < 0 else int(g.greatest),
            threshold=bool(g.greatest < g.least),
            threshold_across_levels=bool(g.all_back < g.all_go),
            bs1_least_go_on=None if g.bs1 == NO_CHARGE else int(g.bs1),
        )
        for g in groups.itertuples(index=False)
    ]
