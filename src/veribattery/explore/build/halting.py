"""States a build leaves unexpanded: where its *stop* formula holds.

A caller that knows every property it will check is decided in some states (the
targets of ``F``, see ``pipeline.stopping``) gives the builders that state formula. A
state where it holds is not expanded: it gets one self-loop of probability 1 (no
action, no reward, not a deadlock), as Storm's builder treats its terminal states, so
the states reached only through it are never found.
"""

from __future__ import annotations

import numpy as np

from veribattery._types import BoolArray, FloatArray, IntArray
from veribattery.explore.build.fused import Expansion
from veribattery.explore.compile.expr import CompiledExpr, compile_expr
from veribattery.lang.nodes import Expr, FlatModel

__all__ = ["compile_halt", "count_halted", "halted", "mdp_with_loops", "with_self_loops"]

#: States evaluated at once when counting (a few MB of temporaries).
_BLOCK = 1 << 16


def compile_halt(model: FlatModel, stop: Expr | None) -> CompiledExpr | None:
    """*stop*, a state formula over *model*'s variables, compiled for state rows."""
    if stop is None:
        return None
    ranges = {v.name: (v.low, v.high) for v in model.variables}
    return compile_expr(stop, model.variable_names, ranges=ranges)


def halted(halt: CompiledExpr | None, rows: IntArray) -> BoolArray | None:
    """Where *halt* holds among the state *rows* (int64), or None where nowhere."""
    if halt is None:
        return None
    holds = np.broadcast_to(np.asarray(halt(rows), dtype=bool), (rows.shape[0],))
    return np.array(holds) if holds.any() else None


def count_halted(halt: CompiledExpr | None, states: IntArray) -> int:
    """How many of *states* (a built state table) were left unexpanded."""
    if halt is None:
        return 0
    count = 0
    for start in range(0, states.shape[0], _BLOCK):
        found = halted(halt, np.asarray(states[start : start + _BLOCK], dtype=np.int64))
        count += 0 if found is None else int(np.count_nonzero(found))
    return count


def with_self_loops(found: Expansion, stopped: BoolArray, rows: IntArray) -> Expansion:
    """The expansion of the frontier *rows* whose *stopped* states were left out (*found*:
    the others' expansion), with a self-loop added to each stopped state.

    Its branches stay in source order. Its ``dropped`` positions count the expanded
    states' branches first and the loops after them: they serve a re-usable structure
    only, which a build that stops is not recorded as."""
    live, loops = np.flatnonzero(~stopped), np.flatnonzero(stopped)
    source, order = _by_state(live[found.source], loops)
    choices = np.ones(rows.shape[0], dtype=found.choices.dtype)
    choices[live] = found.choices
    actions = {}
    for action, counts in found.action_choices.items():
        actions[action] = np.zeros(rows.shape[0], dtype=counts.dtype)
        actions[action][live] = counts
    return Expansion(source, np.concatenate([found.targets, rows[loops]])[order],
                     np.concatenate([found.probability, np.ones(loops.size)])[order],
                     choices, actions, found.dropped, found.branches + loops.size)


def mdp_with_loops(stopped: BoolArray, low: int, kind: int, choices: tuple[IntArray, IntArray],
                   entries: tuple[FloatArray, IntArray, IntArray]
                   ) -> tuple[IntArray, IntArray, tuple[FloatArray, IntArray, IntArray]]:
    """An MDP chunk's choices (*choices*: source and atomic group) and entries
    (probability, row, column) of the states not *stopped*, numbered among those, with a
    self-loop of atomic group *kind* added to each stopped state: all numbered within the
    chunk, whose first state is *low*."""
    source, group = choices
    p, row, column = entries
    live, loops = np.flatnonzero(~stopped), np.flatnonzero(stopped)
    every, order = _by_state(live[source], loops)
    position = np.empty_like(order)
    position[order] = np.arange(order.size)
    return every, np.concatenate([group, np.full(loops.size, kind)])[order], (
        np.concatenate([p, np.ones(loops.size)]),
        np.concatenate([position[row], position[source.size:]]),
        np.concatenate([column, low + loops]))


def _by_state(sources: IntArray, loops: IntArray) -> tuple[IntArray, IntArray]:
    """The chunk-local source states of the expanded states' items (*sources*, in state
    order) followed by one per stopped state (*loops*), sorted by state, and the order
    that sorts them (stable: a state's own items keep their order)."""
    every = np.concatenate([sources, loops])
    order = np.argsort(every, kind="stable")
    return every[order], order
