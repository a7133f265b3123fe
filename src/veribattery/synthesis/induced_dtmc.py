"""The DTMC the table's strategy (safest, then fastest) induces, for the mission analyses.

``explain``, ``simulate`` and ``distribution --strategy optimal`` analyse the mission
under the synthesised strategy rather than BS1: the config's MDP
(:func:`~veribattery.synthesis.model.mission_model`), the strategy of
:func:`~veribattery.synthesis.optimal.safest_fastest`, and the chain it induces over
the states it reaches, with the MDP's variables, labels and reward structures (a
choice's transition reward becomes the step's reward of its state). The questions
``synthesize`` answers for that strategy come with it, so that ``simulate`` estimates
the same values.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

from veribattery.checker.mdp import MDP, reach_probability
from veribattery.config import MissionConfig
from veribattery.explore import DTMC
from veribattery.explore.dtmc import RewardVectors
from veribattery.lang import FlatModel, Property, parse_properties
from veribattery.lang.properties import resolve_property
from veribattery.pipeline import ProgressCallback
from veribattery.synthesis.exports import INDUCED_QUESTIONS
from veribattery.synthesis.model import mission_model
from veribattery.synthesis.optimal import ChosenStrategy, safest_fastest

__all__ = ["InducedMission", "induced_dtmc", "optimal_mission"]

StrArray = npt.NDArray[np.str_]


@dataclass(frozen=True, slots=True)
class InducedMission:
    """The mission under the synthesised strategy.

    :ivar flat: the flat PRISM model of the mission MDP (its variables, labels, rewards).
    :ivar dtmc: the chain the strategy induces, over the states it reaches.
    :ivar strategy: the strategy and its own certified values.
    :ivar properties: :data:`~veribattery.synthesis.exports.INDUCED_QUESTIONS`, resolved
        against *flat*.
    :ivar actions: per state of *dtmc*, the action the strategy takes there (the MDP's
        commands leave several enabled; this is the one chosen).
    """

    flat: FlatModel
    dtmc: DTMC
    strategy: ChosenStrategy
    properties: tuple[Property, ...]
    actions: StrArray


def optimal_mission(cfg: MissionConfig, *,
                    progress: ProgressCallback | None = None) -> InducedMission:
    """Build *cfg*'s MDP, choose its safest-then-fastest strategy and induce its DTMC.

    :param progress: told ``(states found, frontier)`` while the MDP is built.
    :raises VeribatteryError: when the config cannot be rendered, built or checked.
    """
    flat, mdp = mission_model(cfg, progress=progress)
    chosen = safest_fastest(mdp, reach_probability(mdp, mdp.labels["success"],
                                                   objective="max"))
    return InducedMission(flat, induced_dtmc(mdp, chosen), chosen, _questions(flat),
                          _taken_actions(mdp, chosen))


def induced_dtmc(mdp: MDP, chosen: ChosenStrategy) -> DTMC:
    """The DTMC *chosen* induces on *mdp*, restricted to the states it reaches (closed
    under the strategy), in the order of *mdp*'s states."""
    assert mdp.states is not None
    reached = chosen.reached
    rows = chosen.choices[reached]
    renumber = np.full(mdp.num_states, -1, dtype=np.int64)
    renumber[reached] = np.arange(reached.size)
    labels = {name: np.asarray(mask[reached], dtype=bool) for name, mask in mdp.labels.items()}
    # A choice's transition reward is paid on the step its state takes under the strategy.
    rewards = tuple(RewardVectors(r.name, np.asarray(r.state[reached], dtype=np.float64),
                                  np.asarray(r.choice[rows], dtype=np.float64))
                    for r in mdp.rewards)
    deadlocks = int(labels["deadlock"].sum()) if "deadlock" in labels else 0
    return DTMC(sp.csr_matrix(mdp.transitions[rows][:, reached]),
                np.asarray(mdp.states[reached]), mdp.variable_names, renumber[mdp.initial],
                labels, rewards, deadlocks=deadlocks)


def _taken_actions(mdp: MDP, chosen: ChosenStrategy) -> StrArray:
    assert mdp.choice_actions is not None
    picked = mdp.choice_actions[chosen.choices[chosen.reached]]
    return np.asarray(mdp.actions, dtype=np.str_)[picked]


def _questions(flat: FlatModel) -> tuple[Property, ...]:
    text = "".join(f'"{name}": {question};\n' for name, question in INDUCED_QUESTIONS)
    return tuple(resolve_property(p, flat) for p in parse_properties(text).properties)
