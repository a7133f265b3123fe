"""The mission view of a chain a strategy induces: the action is the one it chose.

On BS1's DTMC exactly one command is enabled in a state, so the view reads the action
off the model's guards. A chain induced from the mission MDP keeps the MDP's model,
where several commands are enabled at each decision; the action taken is the
strategy's, given per state.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from veribattery._types import IntArray
from veribattery.analyses.mission_view import Column, MissionModel, MissionView

__all__ = ["StrategyView"]


class StrategyView(MissionView):
    """:class:`~veribattery.analyses.mission_view.MissionView` with the strategy's actions.

    :param mission: the built mission (its DTMC the induced chain).
    :param actions: per state of the chain, the action the strategy takes there.
    """

    def __init__(self, mission: MissionModel, actions: npt.NDArray[np.str_]) -> None:
        super().__init__(mission)
        if actions.shape != (mission.dtmc.num_states,):
            raise ValueError(f"{actions.shape[0]} actions for {mission.dtmc.num_states} states")
        self._taken = actions

    def columns(self, idx: IntArray) -> dict[str, Column]:
        """:meth:`MissionView.columns`, the action the strategy's (an unlabelled command,
        as in the success and failure states, named as the model's view names it)."""
        columns = super().columns(idx)
        taken = self._taken[idx]
        columns["action"] = np.where(taken == "", columns["action"], taken)
        return columns
