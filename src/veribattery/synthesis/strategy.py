"""A memoryless deterministic strategy of the mission MDP, state by state.

This is what the threshold table reads, whoever computed the strategy (veribattery's
MDP engine, Storm, or a strategy file): one row per state with the spec's six
variables, the action the strategy chooses there, and whether going on or turning back
matters there.
Which states to pass is the caller's choice; the states reachable under the strategy
from the initial state are the meaningful ones (a state the strategy never enters says
nothing about it), and that is what ``veribattery synthesize`` reports.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

from veribattery.errors import VeribatteryError

__all__ = ["MDP_ACTIONS", "STATE_VARIABLES", "StrategyError", "strategy_frame"]

#: The spec's state variables, in its order (model-spec.md, "State variables").
STATE_VARIABLES = ("s", "k", "j", "b", "rc", "wsp")
#: The MDP's action labels (synthesis.prism.j2); "" is the absorbing states' loop.
MDP_ACTIONS = frozenset({"wait", "takeoff", "fly", "land", "inspect", "back", "next",
                         "backnext", "finish", "recharge", "oob", "abort", ""})


class StrategyError(VeribatteryError):
    """A strategy does not fit the mission MDP: a missing variable, an unknown action,
    or an action that is not a choice in the state it is given for."""


def strategy_frame(variables: Mapping[str, ArrayLike], actions: Sequence[str], *,
                   indifferent: ArrayLike | None = None) -> pd.DataFrame:
    """The strategy as a frame: columns ``s k j b rc wsp`` (int64), ``action`` (str) and
    ``indifferent`` (bool), one row per state.

    :param variables: each of :data:`STATE_VARIABLES` → its value in every state.
    :param actions: the action chosen in each state, as the MDP labels it.
    :param indifferent: per state, True where going on is exactly as good as the best
        way of turning back (returning or giving up): the strategy's choice between them
        is arbitrary there, and its charge is left out of the thresholds. Default: no
        state is.
    :raises StrategyError: when a variable is missing, the lengths differ or an action
        is not one of the MDP's.
    """
    missing = [name for name in STATE_VARIABLES if name not in variables]
    if missing:
        raise StrategyError(f"strategy: no values for the variable(s) {', '.join(missing)}")
    columns = {name: np.asarray(variables[name], dtype=np.int64) for name in STATE_VARIABLES}
    columns["action"] = np.asarray(actions, dtype=object)
    size = len(columns["action"])
    columns["indifferent"] = (np.zeros(size, dtype=bool) if indifferent is None
                              else np.asarray(indifferent, dtype=bool))
    lengths = {name: len(values) for name, values in columns.items()}
    if len(set(lengths.values())) > 1:
        raise StrategyError(f"strategy: columns of different lengths {lengths}")
    _check_actions(columns["action"])
    return pd.DataFrame(columns)


def _check_actions(actions: np.ndarray) -> None:
    unknown = sorted(set(actions.tolist()) - MDP_ACTIONS)
    if unknown:
        raise StrategyError(f"strategy: unknown action(s) {', '.join(map(repr, unknown))}; "
                            f"the MDP's are {', '.join(sorted(MDP_ACTIONS - {''}))}")
