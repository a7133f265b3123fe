"""PRISM's symbolic range check: every command over the whole domain of its variables.

PRISM's symbolic engines check each command in every state of the variables'
domain (reachable or not) where its guard holds; if an update can leave a
variable's range there, PRISM refuses the model. The explicit builder only sees
reachable states, so this check is offered separately.

A command whose right-hand sides provably stay in range (interval analysis)
needs no enumeration. Otherwise only the variables that occur in its guard,
probabilities and right-hand sides matter: their ranges' product is enumerated in chunks (the
other columns are fixed at their lower bound, which the command cannot read).
A command whose product exceeds *max_combinations* is not checked; its
description is returned so that the caller can warn -- nothing is skipped
silently.
"""

from __future__ import annotations

import numpy as np

from veribattery._types import IntArray
from veribattery.explore.compile.expr import variables_of
from veribattery.explore.compile.program import CompiledCommand, Program, compile_program
from veribattery.lang.nodes import Command, FlatModel

__all__ = ["check_update_ranges_over_domain"]

_CHUNK = 1 << 18


def check_update_ranges_over_domain(
    model: FlatModel, *, max_combinations: int = 50_000_000
) -> tuple[str, ...]:
    """Check every command's updates stay in range wherever its guard holds.

    :param model: the flat model.
    :param max_combinations: largest variable-domain product checked per command.
    :returns: one warning per command skipped because its domain was too large.
    :raises ModelError: naming module, command (span), variable, value and an
        example state, for the first command that can leave a range.
    """
    program = compile_program(model)
    skipped = []
    for group in program.groups:
        for part in group.parts:
            for command in part:
                size = _check_command(program, command, max_combinations)
                if size is not None:
                    skipped.append(
                        f"module {command.module}, command at {command.span}: not range-checked "
                        f"over its domain ({size} combinations > {max_combinations})"
                    )
    return tuple(skipped)


def _check_command(program: Program, command: CompiledCommand, limit: int) -> int | None:
    """Check one command; return its domain size instead if that exceeds *limit*."""
    from veribattery.explore.build.successors import check_update_ranges  # not a model check's

    if _provably_in_range(command):
        return None
    columns = sorted(program.variable_names.index(v) for v in _mentioned(command.command))
    sizes = [program.highs[c] - program.lows[c] + 1 for c in columns]
    total = int(np.prod(np.array(sizes, dtype=object))) if sizes else 1
    if total > limit:
        return total
    for start in range(0, total, _CHUNK):
        rows = _rows(program, columns, sizes, start, min(start + _CHUNK, total))
        enabled = rows[command.guard(rows).astype(bool)]
        if enabled.shape[0]:
            check_update_ranges(program, command, enabled)
    return None


def _provably_in_range(command: CompiledCommand) -> bool:
    """Whether interval analysis alone shows that no update can leave a range.

    Such a command (e.g. ``(s'=3)``) needs no enumeration, however many variables
    its guard reads: the mission's Drone commands read all six.
    """
    return all(
        column in update.unchecked
        for update in command.updates
        for column, _ in update.assignments
    )


def _mentioned(command: Command) -> set[str]:
    names = variables_of(command.guard)
    for update in command.updates:
        names |= variables_of(update.probability)
        for assignment in update.assignments:
            names |= variables_of(assignment.expr)
    return names


def _rows(
    program: Program, columns: list[int], sizes: list[int], start: int, stop: int
) -> IntArray:
    """Rows ``start..stop-1`` of the product of *columns*' ranges; others at their low bound."""
    flat = np.arange(start, stop, dtype=np.int64)
    rows = np.tile(np.array(program.lows, dtype=np.int64), (flat.size, 1))
    for column, size in zip(reversed(columns), reversed(sizes), strict=True):
        flat, offset = np.divmod(flat, size)
        rows[:, column] += offset
    return rows
