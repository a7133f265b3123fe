"""Where the drone decides whether to go on, and what each choice there means.

Four kinds of state offer the drone a choice between going on and turning back
(model-spec.md, "Synthesis", the choice table):

========  ==========================  ========  =============  =========
decision  states                      goes on   returns        gives up
========  ==========================  ========  =============  =========
takeoff   s=0, low wind               takeoff   (stays down)   abort
fly       s=1                         fly       land           abort
inspect   s=2, or s=3 and j < n       inspect   back           abort
next      s=3, j = n, k < K-1         next      backnext       abort
========  ==========================  ========  =============  =========

Everywhere else the drone either has one way forward (wait, land at s=4, backnext
after the last cell, the landed states) or only gives up; those states are not
decisions about going on. Giving up counts as not going on.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from veribattery.config import FarmLayout
from veribattery.synthesis.strategy import StrategyError

__all__ = ["DECISIONS", "GIVE_UP", "GO_ON", "RETURN", "decision_points", "outcomes"]

#: The decision kinds, in the order a sortie meets them.
DECISIONS = ("takeoff", "fly", "inspect", "next")
#: The action that goes on at each decision.
GO_ON = {"takeoff": "takeoff", "fly": "fly", "inspect": "inspect", "next": "next"}
#: The action that returns to the base at each decision (none on the ground).
RETURN = {"fly": "land", "inspect": "back", "next": "backnext"}
GIVE_UP = "abort"
#: Outcome codes: what the chosen action does at a decision.
GOES_ON, RETURNS, GIVES_UP = "goes on", "returns", "gives up"


def decision_points(states: pd.DataFrame, layout: FarmLayout) -> pd.Series:
    """Per state (a :func:`~veribattery.synthesis.strategy.strategy_frame`), its
    decision kind (one of :data:`DECISIONS`), or "" where it is not a decision."""
    s, k, j = (states[name].to_numpy() for name in ("s", "k", "j"))
    cells = layout.num_cells
    n = np.append(np.asarray(layout.n, dtype=np.int64), 0)[np.clip(k, 0, cells)]
    kinds = np.select(
        [(s == 0) & (states["wsp"].to_numpy() == 0), s == 1,
         (s == 2) | ((s == 3) & (j < n)), (s == 3) & (j == n) & (k < cells - 1)],
        list(DECISIONS), "")
    return pd.Series(kinds, index=states.index, dtype=object)


def outcomes(actions: pd.Series, kinds: pd.Series) -> pd.Series:
    """Per decision state, whether its chosen action goes on, returns or gives up.

    :raises StrategyError: naming the first action that is not a choice at its decision.
    """
    table = {(kind, GO_ON[kind]): GOES_ON for kind in DECISIONS}
    table |= {(kind, action): RETURNS for kind, action in RETURN.items()}
    table |= {(kind, GIVE_UP): GIVES_UP for kind in DECISIONS}
    out = pd.Series([table.get(pair, "") for pair in zip(kinds, actions, strict=True)],
                    index=actions.index, dtype=object)
    bad = out == ""
    if bad.any():
        where = out.index[bad.to_numpy()][0]
        raise StrategyError(f"strategy: '{actions[where]}' is not a choice at a "
                            f"'{kinds[where]}' decision (state row {where})")
    return out
