"""The randomised strategy of a ``multi(...)`` property, with its memory, as text.

A multi-objective answer is attained by a randomised strategy with finite memory
(:mod:`~veribattery.checker.mdp.multi_strategy`): per memory state -- the model's
state plus memory variables -- a distribution over the choices. The memory
variables have reserved names (one more leading ``_`` each while a name is taken
by the model):

* ``_visited_i`` (bool, ``i`` = 1, 2, ...): the *i*-th reachability objective's
  target (``F phi``: *phi*; ``G phi``: ``!phi``) has been entered; set on entering
  such a state, never reset.
* ``_mode`` (0 running, 1 stopped; only when needed): the run has decided to stay
  forever in a zero-reward end component; set by the moves marked so, never reset.

Both files list the memory states reached from the initial one, in the induced
chain's order, each by the model's variables then the memory variables.

PRISM-like text (any name but ``*.json``): one line per memory state,
``(v1,...,vn,m1,...)=p1:action1 + p2:action2``, booleans as ``true``/``false``, an
unlabelled choice as nothing before the ``+``; a move that sets ``_mode`` to 1 is
written ``p:action(_mode'=1)``.

Storm-like JSON (``*.json``): a list with one object per memory state,
``{"s": {variable: value, ..., "_visited_1": bool, "_mode": 0}, "c": [{"labels":
[action], "index": i, "prob": p}, ...]}`` -- ``index`` the choice's number in this
MDP, as for the deterministic strategies (:mod:`~veribattery.strategies.formats`);
a move that sets ``_mode`` carries ``"memory": {"_mode": 1}``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from veribattery.checker import CheckResult
from veribattery.checker.mdp import MDP
from veribattery.lang import FlatModel
from veribattery.strategies.valuation_text import state_text

if TYPE_CHECKING:  # its module (and the LP's) is imported only for multi(...) properties
    from veribattery.checker.mdp.multi_strategy import MultiStrategy

__all__ = ["ChosenMulti", "memory_names", "multi_strategy_text"]


@dataclass(frozen=True, slots=True)
class ChosenMulti:
    """A ``multi(...)`` property's witness strategy and the model it acts on.

    :param result: the checked property and its answer.
    :param strategy: the verified strategy (:class:`MultiStrategy`).
    :param visited: the names of the visited bits, in order.
    :param mode: the name of the mode variable, or None when the memory has no mode.
    """

    result: CheckResult
    strategy: MultiStrategy
    mdp: MDP
    model: FlatModel
    visited: tuple[str, ...]
    mode: str | None

    @classmethod
    def of(cls, result: CheckResult, strategy: MultiStrategy, mdp: MDP,
           model: FlatModel) -> ChosenMulti:
        """Name the memory variables so that none clashes with a name of *model*."""
        visited, mode = memory_names(model, strategy.targets)
        return cls(result, strategy, mdp, model, visited,
                   mode if strategy.has_mode else None)

    @property
    def nodes(self) -> range:
        """The memory states (the induced chain's states), in order."""
        return range(self.strategy.num_nodes)

    def valuation(self, node: int) -> dict[str, int | bool]:
        """The model's variables, then the memory variables, in *node*."""
        assert self.mdp.states is not None
        row = self.mdp.states[int(self.strategy.node_state[node])]
        values: dict[str, int | bool] = {
            v.name: bool(x) if v.is_bool else int(x)
            for v, x in zip(self.model.variables, row, strict=True)}
        bits = int(self.strategy.node_visited[node])
        values.update({name: bool(bits >> i & 1) for i, name in enumerate(self.visited)})
        if self.mode is not None:
            values[self.mode] = int(self.strategy.node_stopped[node])
        return values


def memory_names(model: FlatModel, targets: int) -> tuple[tuple[str, ...], str]:
    """``_visited_1..``, ``_mode``, each with leading ``_`` added until no name of
    *model* (variable, label, formula, constant) is the same."""
    taken = {v.name for v in model.variables} | {lab.name for lab in model.labels}
    taken |= {f.name for f in model.formulas} | {name for name, _ in model.constants}

    def free(name: str) -> str:
        while name in taken:
            name = f"_{name}"
        return name

    return tuple(free(f"_visited_{i}") for i in range(1, targets + 1)), free("_mode")


def multi_strategy_text(chosen: ChosenMulti, path: Path) -> str:
    """The strategy in the format *path* asks for: ``.json`` Storm-like, else PRISM-like."""
    if path.suffix.lower() == ".json":
        entries = [_storm_entry(chosen, node) for node in chosen.nodes]
        return json.dumps(entries, indent=4) + "\n"
    lines = (f"{state_text(chosen.valuation(node))}={_moves_text(chosen, node)}"
             for node in chosen.nodes)
    return "".join(f"{line}\n" for line in lines)


def _moves_text(chosen: ChosenMulti, node: int) -> str:
    strategy = chosen.strategy
    parts = []
    for move in strategy.moves(node):
        action = chosen.mdp.action_of(int(strategy.move_choice[move]))
        stops = f"({chosen.mode}'=1)" if _switches(chosen, node, move) else ""
        parts.append(f"{float(strategy.move_probability[move])!r}:{action}{stops}")
    return " + ".join(parts)


def _storm_entry(chosen: ChosenMulti, node: int) -> dict[str, object]:
    strategy = chosen.strategy
    choices: list[dict[str, object]] = []
    for move in strategy.moves(node):
        choice = int(strategy.move_choice[move])
        action = chosen.mdp.action_of(choice)
        entry: dict[str, object] = {"labels": [action] if action else [], "index": choice,
                                    "prob": float(strategy.move_probability[move])}
        if chosen.mode is not None and _switches(chosen, node, move):
            entry["memory"] = {chosen.mode: 1}
        choices.append(entry)
    return {"s": chosen.valuation(node), "c": choices}


def _switches(chosen: ChosenMulti, node: int, move: int) -> bool:
    """Whether *move* sets the mode to stopped (from running)."""
    strategy = chosen.strategy
    return bool(strategy.move_stops[move] and not strategy.node_stopped[node])
