"""A DTMC whose state table is narrow from the start, for answers-only checks."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

from veribattery.explore.build.builder import assemble, explore
from veribattery.explore.build.halting import compile_halt, count_halted
from veribattery.explore.compile.program import compile_program
from veribattery.explore.dtmc import DTMC
from veribattery.lang.nodes import Expr, FlatModel

__all__ = ["build_compact_dtmc"]


def build_compact_dtmc(model: FlatModel, *,
                       progress: Callable[[int, int], None] | None = None,
                       stop: Expr | None = None) -> DTMC:
    """``build_dtmc(model).compact()``, the same DTMC, but the state table is made narrow
    as it is decoded: its int64 form (8 bytes per state and variable: 528 MB of crowds
    5/20's 32 variables, more than the rest of its DTMC) never exists.

    For callers that read the table through :meth:`DTMC.column` only (see
    :meth:`DTMC.compact`). Labels and rewards are evaluated on int64 copies of blocks
    of states, so every value is the same as :func:`build_dtmc`'s.

    :param progress: called once per BFS layer with (states found so far, frontier size).
    :param stop: a state formula: where it holds, a state is left unexpanded, with a
        self-loop (:mod:`~veribattery.explore.build.halting`; counted in
        :attr:`DTMC.stopped`).
    """
    halt = compile_halt(model, stop)
    states, initial, layers = explore(model, compile_program(model), progress, compact=True,
                                      halt=halt)
    dtmc = assemble(model, states, initial, layers).compact()
    return dtmc if halt is None else replace(dtmc, stopped=count_halted(halt, states))
