"""A DTMC whose state table is narrow from the start, for answers-only checks."""

from __future__ import annotations

from collections.abc import Callable

from veribattery.explore.build.builder import assemble, explore
from veribattery.explore.compile.program import compile_program
from veribattery.explore.dtmc import DTMC
from veribattery.lang.nodes import FlatModel

__all__ = ["build_compact_dtmc"]


def build_compact_dtmc(model: FlatModel, *,
                       progress: Callable[[int, int], None] | None = None) -> DTMC:
    """``build_dtmc(model).compact()``, the same DTMC, but the state table is made narrow
    as it is decoded: its int64 form (8 bytes per state and variable: 528 MB of crowds
    5/20's 32 variables, more than the rest of its DTMC) never exists.

    For callers that read the table through :meth:`DTMC.column` only (see
    :meth:`DTMC.compact`). Labels and rewards are evaluated on int64 copies of blocks
    of states, so every value is the same as :func:`build_dtmc`'s.

    :param progress: called once per BFS layer with (states found so far, frontier size).
    """
    states, initial, layers = explore(model, compile_program(model), progress, compact=True)
    return assemble(model, states, initial, layers).compact()
