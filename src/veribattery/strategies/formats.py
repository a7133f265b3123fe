"""A strategy as text other tools read: PRISM's ``-exportstrat`` actions and Storm's
scheduler JSON, chosen by the file's suffix.

Both list the states reachable from the initial states under the strategy (PRISM's
default for strategies; the others' choices never matter), in state order, each by its
variables' values, with the action of the choice taken.

PRISM (``-exportstrat strat.txt``, actions form): one line per state,
``(v1,...,vn)=action``, the values in the model's variable order, booleans as
``true``/``false``, an unlabelled choice as nothing after ``=``.

Storm (``--exportscheduler sched.json``): a JSON list with one object per state,
``{"s": {variable: value, ...}, "c": [{"labels": [action], "index": i, "prob": 1.0}]}``
-- ``labels`` empty for an unlabelled choice, ``index`` the choice's number in this
MDP (choices numbered state by state, as Storm numbers its rows; the numbering of
Storm's own build may differ), ``prob`` 1.0 (the strategy is deterministic).
"""

from __future__ import annotations

import json
from pathlib import Path

from veribattery.strategies.chosen import ChosenStrategy
from veribattery.strategies.valuation_text import state_text

__all__ = ["prism_strategy_text", "storm_scheduler_json", "strategy_text"]


def strategy_text(chosen: ChosenStrategy, path: Path) -> str:
    """The strategy in the format *path* asks for: ``.json`` Storm, else PRISM."""
    if path.suffix.lower() == ".json":
        return storm_scheduler_json(chosen)
    return prism_strategy_text(chosen)


def prism_strategy_text(chosen: ChosenStrategy) -> str:
    """PRISM's actions form: ``(v1,...,vn)=action`` per reachable state."""
    lines = (f"{state_text(chosen.valuation(s))}={chosen.action(s)}"
             for s in chosen.reached_states)
    return "".join(f"{line}\n" for line in lines)


def storm_scheduler_json(chosen: ChosenStrategy) -> str:
    """Storm's scheduler JSON (memoryless, deterministic) over the reachable states."""
    entries = [_storm_entry(chosen, s) for s in chosen.reached_states]
    return json.dumps(entries, indent=4) + "\n"


def _storm_entry(chosen: ChosenStrategy, state: int) -> dict[str, object]:
    action = chosen.action(state)
    choice = {"labels": [action] if action else [],
              "index": int(chosen.strategy.choices[state]), "prob": 1.0}
    return {"s": chosen.valuation(state), "c": [choice]}
