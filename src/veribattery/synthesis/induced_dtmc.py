"""The DTMC a strategy of the mission MDP induces, for the mission analyses.

``explain``, ``simulate`` and ``distribution --strategy optimal`` analyse the mission
under the synthesised strategy rather than BS1: the config's MDP
(:func:`~veribattery.synthesis.model.mission_model`), the strategy the threshold table
shows (:func:`~veribattery.synthesis.optimal.safest_fastest`: safest, then fastest),
and the chain it induces over the states it reaches, with the MDP's variables, labels
and reward structures (a choice's transition reward becomes the step's reward of its
state). ``--strategy FILE`` does the same with a strategy file written by
``synthesize --export-strategy`` (:mod:`~veribattery.synthesis.strategy_file`).
The questions ``synthesize`` answers for a strategy come with it, so that
``simulate`` estimates the same values.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
from scipy.sparse.csgraph import breadth_first_order

from veribattery._types import IntArray
from veribattery.checker.api import check
from veribattery.checker.mdp import MDP, reach_probability
from veribattery.config import MissionConfig
from veribattery.explore import DTMC
from veribattery.explore.dtmc import RewardVectors
from veribattery.lang import FlatModel, Property, parse_properties
from veribattery.lang.properties import resolve_property
from veribattery.pipeline import ProgressCallback
from veribattery.synthesis.exports import INDUCED_QUESTIONS
from veribattery.synthesis.model import mission_model
from veribattery.synthesis.optimal import safest_fastest
from veribattery.synthesis.strategy_file import read_strategy_file

__all__ = ["InducedMission", "file_mission", "induced_dtmc", "optimal_mission"]

StrArray = npt.NDArray[np.str_]


@dataclass(frozen=True, slots=True)
class InducedMission:
    """The mission under a strategy of its MDP.

    :ivar flat: the flat PRISM model of the mission MDP (its variables, labels, rewards).
    :ivar dtmc: the chain the strategy induces, over the states it reaches.
    :ivar properties: :data:`~veribattery.synthesis.exports.INDUCED_QUESTIONS`, resolved
        against *flat*.
    :ivar values: each property's value under the strategy, by its name.
    :ivar actions: per state of *dtmc*, the action the strategy takes there (the MDP's
        commands leave several enabled; this is the one chosen).
    """

    flat: FlatModel
    dtmc: DTMC
    properties: tuple[Property, ...]
    values: dict[str, float]
    actions: StrArray


def optimal_mission(cfg: MissionConfig, *,
                    progress: ProgressCallback | None = None) -> InducedMission:
    """Build *cfg*'s MDP, choose its safest-then-fastest strategy and induce its DTMC;
    the values are ``synthesize``'s of that strategy (certified on the MDP).

    :param progress: told ``(states found, frontier)`` while the MDP is built.
    :raises VeribatteryError: when the config cannot be rendered, built or checked.
    """
    flat, mdp = mission_model(cfg, progress=progress)
    chosen = safest_fastest(mdp, reach_probability(mdp, mdp.labels["success"],
                                                   objective="max"))
    values = {"p_success": chosen.p_success.value,
              "exp_mission_time": chosen.exp_mission_time.value,
              "exp_recharges": chosen.exp_recharges.value}
    return InducedMission(flat, induced_dtmc(mdp, chosen.choices, chosen.reached),
                          _questions(flat), values,
                          _taken_actions(mdp, chosen.choices, chosen.reached))


def file_mission(cfg: MissionConfig, path: Path, *,
                 progress: ProgressCallback | None = None) -> InducedMission:
    """Build *cfg*'s MDP and induce the DTMC of the strategy in the file *path*; the
    values are checked on that DTMC.

    :raises StrategyError: when the file does not fit the MDP.
    :raises OSError: when the file cannot be read.
    """
    flat, mdp = mission_model(cfg, progress=progress)
    choices = read_strategy_file(path, mdp)
    reached = _reached(mdp, choices)
    dtmc = induced_dtmc(mdp, choices, reached)
    questions = _questions(flat)
    values = {str(p.name): float(check(dtmc, p, keep="answers").value)
              for p in questions}
    return InducedMission(flat, dtmc, questions, values, _taken_actions(mdp, choices, reached))


def induced_dtmc(mdp: MDP, choices: IntArray, reached: IntArray) -> DTMC:
    """The DTMC the strategy *choices* (a row per state) induces on *mdp*, over the
    states *reached* (sorted, closed under the strategy), in the order of *mdp*'s."""
    assert mdp.states is not None
    rows = choices[reached]
    renumber = np.full(mdp.num_states, -1, dtype=np.int64)
    renumber[reached] = np.arange(reached.size)
    labels = {name: np.asarray(mask[reached], dtype=bool) for name, mask in mdp.labels.items()}
    # A choice's transition reward is paid on the step its state takes under the strategy.
    rewards = tuple(RewardVectors(r.name, np.asarray(r.state[reached], dtype=np.float64),
                                  np.asarray(r.choice[rows], dtype=np.float64))
                    for r in mdp.rewards)
    deadlocks = int(labels["deadlock"].sum()) if "deadlock" in labels else 0
    return DTMC(sp.csr_matrix(mdp.transitions[rows][:, reached]),
                np.asarray(mdp.states[reached], dtype=np.int64), mdp.variable_names,
                renumber[mdp.initial], labels, rewards, deadlocks=deadlocks)


def _reached(mdp: MDP, choices: IntArray) -> IntArray:
    """The states reachable from the initial state under *choices* (all named)."""
    named = np.flatnonzero(choices >= 0)
    step = sp.csr_matrix((np.ones(named.size), (named, np.arange(named.size))),
                         shape=(mdp.num_states, named.size)) @ mdp.transitions[choices[named]]
    order = breadth_first_order(sp.csr_matrix(step), int(mdp.initial[0]), directed=True,
                                return_predecessors=False)
    return np.sort(np.asarray(order, dtype=np.int64))


def _taken_actions(mdp: MDP, choices: IntArray, reached: IntArray) -> StrArray:
    assert mdp.choice_actions is not None
    picked = mdp.choice_actions[choices[reached]]
    return np.asarray(mdp.actions, dtype=np.str_)[picked]


def _questions(flat: FlatModel) -> tuple[Property, ...]:
    text = "".join(f'"{name}": {question};\n' for name, question in INDUCED_QUESTIONS)
    return tuple(resolve_property(p, flat) for p in parse_properties(text).properties)
