"""``Pmax [ F "success" ]`` of one mission MDP: what a sweep point in synthesis mode asks.

A sweep (``veribattery sweep`` with ``strategy.mode: synthesize``, ``reproduce fig6
--optimal``) renders each point's MDP once and asks it only this: the best return
policy's certified probability of success, and the size of the model.
"""

from __future__ import annotations

from dataclasses import dataclass

from veribattery.checker.mdp import reach_probability
from veribattery.synthesis.model import Certified, ModelSize, built_model

__all__ = ["MissionPmax", "pmax_of_model"]


@dataclass(frozen=True, slots=True)
class MissionPmax:
    """The certified ``Pmax`` of success of a mission MDP, and the MDP's size."""

    p_success_max: Certified
    size: ModelSize


def pmax_of_model(text: str) -> MissionPmax:
    """Certified ``Pmax [ F "success" ]`` at the initial state of the mission MDP *text*
    (as :func:`~veribattery.render.render_synthesis_model` writes it).

    :raises VeribatteryError: when the model cannot be parsed, built or checked.
    """
    mdp = built_model(text, rewards=False)[1]
    value = reach_probability(mdp, mdp.labels["success"], objective="max")
    return MissionPmax(Certified.at_initial(mdp, value), ModelSize.of(mdp))
