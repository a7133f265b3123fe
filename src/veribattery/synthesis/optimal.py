"""The strategy the threshold table shows: the safest, and among the safest the fastest.

``Pmax`` alone leaves most choices open: on the paper's farms it is 1 to double
precision, and nearly every choice attains it. The table therefore shows the
lexicographic optimum: among the choices that may attain ``Pmax`` (a choice is kept
unless its certified value lies below the state's certified ``Pmax``), the strategy
of least expected mission time (``Rmin [ F "done" ]`` on the MDP of those choices).
Both steps are the MDP engine's, certified; the strategy is memoryless and
deterministic, and its own P(success), expected mission time and recharges are
checked on it afterwards (an MDP of one choice per state).

A decision state is *indifferent* when going on and the best way of turning back are
both kept and their expected times agree to :data:`TIME_TIES` relative: there the
choice is arbitrary, and the table does not judge it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import breadth_first_order

from veribattery._types import BoolArray, FloatArray, IntArray
from veribattery.checker.mdp import MDP, MdpResult, MdpRewards, reach_probability, reach_reward
from veribattery.checker.mdp.attain import may_attain
from veribattery.synthesis.decisions import GIVE_UP, GO_ON, RETURN
from veribattery.synthesis.model import Certified
from veribattery.synthesis.strategy import STATE_VARIABLES

__all__ = ["TIME_TIES", "ChosenStrategy", "chosen_actions", "safest_fastest", "strategy_columns"]

#: Relative (and absolute, in minutes) difference of expected times taken as a tie.
TIME_TIES = 1e-9
_GOING_ON = frozenset(GO_ON.values())
_TURNING_BACK = frozenset(RETURN.values()) | {GIVE_UP}


@dataclass(frozen=True, slots=True)
class ChosenStrategy:
    """A memoryless deterministic strategy and its own values at the initial state.

    :ivar choices: per state, the choice (row of the MDP) it takes.
    :ivar indifferent: per state, whether going on and turning back tie there.
    :ivar reached: the states reachable from the initial state under it (sorted).
    """

    choices: IntArray
    indifferent: BoolArray
    reached: IntArray
    p_success: Certified
    exp_mission_time: Certified
    exp_recharges: Certified


def safest_fastest(mdp: MDP, pmax: MdpResult) -> ChosenStrategy:
    """The fastest of the strategies that attain *pmax* (``Pmax [ F "success" ]`` of
    *mdp*), with its ties and its own certified values."""
    safest = _possibly_optimal(mdp, pmax)
    restricted, rows = _restricted(mdp, safest)
    done = mdp.labels["done"]
    time = reach_reward(restricted, _per_choice(restricted, "mt"), done, objective="min")
    choices = rows[time.strategy.choices]  # type: ignore[union-attr]
    indifferent = _ties(mdp, safest, time.values)
    own = _restricted(mdp, _only(mdp, choices))[0]
    return ChosenStrategy(
        choices, indifferent, _reached(mdp, choices),
        Certified.at_initial(own, reach_probability(own, mdp.labels["success"],
                                                    objective="max")),
        Certified.at_initial(restricted, time),
        Certified.at_initial(own, reach_reward(own, _per_choice(own, "rc"), done,
                                               objective="min")),
    )


def strategy_columns(mdp: MDP, strategy: ChosenStrategy) -> dict[str, IntArray]:
    """The spec's six variables over the states the strategy reaches."""
    assert mdp.states is not None
    index = {name: i for i, name in enumerate(mdp.variable_names)}
    return {name: np.asarray(mdp.states[strategy.reached, index[name]], dtype=np.int64)
            for name in STATE_VARIABLES}


def chosen_actions(mdp: MDP, strategy: ChosenStrategy) -> list[str]:
    """The action the strategy takes in each state it reaches."""
    assert mdp.choice_actions is not None
    picked = mdp.choice_actions[strategy.choices[strategy.reached]]
    return [mdp.actions[int(a)] for a in picked]


def _per_choice(mdp: MDP, name: str) -> FloatArray:
    return mdp.reward(name).per_choice(mdp)


def _possibly_optimal(mdp: MDP, pmax: MdpResult) -> BoolArray:
    """The choices whose certified value may reach the state's Pmax, and the engine's
    own optimal choice in every state (so each state keeps one)."""
    keep = may_attain(mdp, pmax.upper, pmax.lower)
    keep[pmax.strategy.choices] = True  # type: ignore[union-attr]
    return keep


def _only(mdp: MDP, choices: IntArray) -> BoolArray:
    keep = np.zeros(mdp.num_choices, dtype=bool)
    keep[choices] = True
    return keep


def _restricted(mdp: MDP, keep: BoolArray) -> tuple[MDP, IntArray]:
    """*mdp* with only the choices *keep* (each state keeps at least one), and per
    choice of the result, its row in *mdp*."""
    rows = np.flatnonzero(keep)
    counts = np.add.reduceat(keep.astype(np.int64), mdp.row_groups[:-1])
    groups = np.concatenate([[0], np.cumsum(counts)])
    assert mdp.choice_actions is not None
    restricted = MDP(
        sp.csr_matrix(mdp.transitions[rows]), groups, mdp.initial, labels=mdp.labels,
        choice_actions=mdp.choice_actions[rows], actions=mdp.actions,
        rewards=tuple(MdpRewards(r.name, r.state, r.choice[rows]) for r in mdp.rewards),
        states=mdp.states, variable_names=mdp.variable_names)
    return restricted, rows


def _ties(mdp: MDP, safest: BoolArray, time: FloatArray) -> BoolArray:
    """Per state: going on and the best way of turning back are both among the safest
    choices and equally fast (:data:`TIME_TIES`)."""
    assert mdp.choice_actions is not None
    action = np.asarray(mdp.actions, dtype=object)[mdp.choice_actions]
    worth = _per_choice(mdp, "mt") + mdp.transitions @ time
    worth = np.where(safest, worth, np.inf)
    going_on = np.isin(action, list(_GOING_ON))
    turning_back = np.isin(action, list(_TURNING_BACK))
    starts = mdp.row_groups[:-1]
    go = np.minimum.reduceat(np.where(going_on, worth, np.inf), starts)
    back = np.minimum.reduceat(np.where(turning_back, worth, np.inf), starts)
    both = np.isfinite(go) & np.isfinite(back)
    tied = np.zeros(mdp.num_states, dtype=bool)
    tied[both] = np.abs(go[both] - back[both]) <= TIME_TIES * np.maximum(1.0, go[both])
    return tied


def _reached(mdp: MDP, choices: IntArray) -> IntArray:
    order = breadth_first_order(sp.csr_matrix(mdp.transitions[choices]), int(mdp.initial[0]),
                                directed=True, return_predecessors=False)
    return np.sort(np.asarray(order, dtype=np.int64))
