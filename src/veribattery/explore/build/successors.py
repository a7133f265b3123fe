"""Successors of a whole frontier for one choice group, vectorised over states.

A group's choices are enumerated part by part: the choice rows start as the
frontier states and each part (module) multiplies every row by that module's
enabled commands. Branches are then the product of the chosen commands'
updates: probabilities multiply, and each module's assignments write its own
columns, every right-hand side evaluated in the *source* state.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from veribattery._types import FloatArray, IntArray
from veribattery.errors import ModelError
from veribattery.explore.build.branches import BranchLayout, branch_layout, constant_row
from veribattery.explore.compile.equalities import EqualityIndex
from veribattery.explore.compile.program import (
    ChoiceGroup,
    CompiledCommand,
    CompiledUpdate,
    Program,
)

__all__ = ["GroupSuccessors", "check_update_ranges", "expand_group", "expand_groups",
           "format_state"]

_TOLERANCE = 1e-6  # allowed deviation of a choice's probabilities from 1


@dataclass(frozen=True, slots=True)
class GroupSuccessors:
    """Branches of one group over a frontier.

    :param source: frontier-local index of each branch's source state.
    :param targets: successor rows, one per branch.
    :param probability: branch probability within its choice.
    :param choices: number of choices the group offers in each frontier state.
    :param combination: per branch, the number of its choice's combination of commands
        within the group (one command per part, the last part's varying fastest, as
        ``itertools.product`` numbers them); None where the group has only one.
    """

    source: IntArray
    targets: IntArray
    probability: FloatArray
    choices: IntArray
    combination: IntArray | None = None


@dataclass(frozen=True, slots=True)
class _Choices:
    """The joint choices of a group: a source row and one pick per part."""

    source: IntArray
    picks: tuple[IntArray, ...]


def expand_group(
    program: Program, group: ChoiceGroup, states: IntArray, bounds: bool = True
) -> GroupSuccessors | None:
    """All branches of *group* from the frontier *states*; None when nothing is enabled.

    :param bounds: check that updates stay in their variables' ranges; a caller
        that checks all the targets of a layer at once passes False.
    :raises ModelError: for an out-of-range update, a negative probability or a
        choice whose probabilities do not sum to 1.
    """
    if len(group.parts) == 1:
        return _expand_single(program, group.parts[0], states, bounds, group.index(0))
    if all(len(part) == 1 for part in group.parts):
        return _expand_one_each(program, [part[0] for part in group.parts], states, bounds)
    return _expand_product(program, group, states, bounds)


def expand_groups(
    program: Program, states: IntArray, bounds: bool
) -> list[tuple[str | None, GroupSuccessors]]:
    """Every group's branches from the frontier *states*, with its action: the groups
    that enable nothing left out (:func:`expand_group`)."""
    parts = [(g.action, expand_group(program, g, states, bounds)) for g in program.groups]
    return [(a, s) for a, s in parts if s is not None]


def _expand_product(
    program: Program, group: ChoiceGroup, states: IntArray, bounds: bool = True
) -> GroupSuccessors | None:
    """The general case: every combination of one enabled command per part."""
    choices = _enumerate_choices(group, states)
    if choices is None:
        return None
    sources = states[choices.source]
    tables = [
        _part_table(program, part, pick, sources, bounds)
        for part, pick in zip(group.parts, choices.picks, strict=True)
    ]
    _check_sums(program, group, choices, tables, sources)
    choice, updates = _expand_updates(group, choices)
    targets = sources[choice]
    probability = np.ones(choice.size, dtype=np.float64)
    for table, update in zip(tables, updates, strict=True):
        cell = update * table.probability.shape[1] + choice  # flat index into the tables
        probability *= table.probability.ravel().take(cell)
        for column, values in table.values.items():
            targets[:, column] = values.ravel().take(cell)
    counts = np.bincount(choices.source, minlength=states.shape[0])
    return GroupSuccessors(choices.source[choice], targets, probability, counts,
                           _combination(group, choices)[choice])


def _expand_one_each(
    program: Program, commands: Sequence[CompiledCommand], states: IntArray, bounds: bool = True
) -> GroupSuccessors | None:
    """:func:`expand_group` when every part has one command: at most one choice per state.

    The same branches in the same order as the general product (one choice per
    enabled state; per choice, the first part's update outermost), built on
    ``(choices, branches)`` grids with a handful of whole-array operations.
    """
    enabled: np.ndarray | None = None
    for command in commands:
        if not command.always:
            guard = np.asarray(command.guard(states), dtype=bool)
            enabled = guard if enabled is None else enabled & guard
            if not enabled.any():
                return None
    source = np.arange(states.shape[0]) if enabled is None else np.flatnonzero(enabled)
    sources = states[source]
    n = source.size
    layout = branch_layout(tuple(len(c.updates) for c in commands))
    width = layout.width
    targets = np.repeat(sources, width, axis=0) if width > 1 else sources.copy()
    grid = targets.reshape(n, width, states.shape[1])
    constants = constant_row(tuple(tuple(u.constant_probability for u in c.updates)
                                    for c in commands))
    total: FloatArray | float
    if constants is not None:  # every probability folded: one row for all choices
        row, total = constants
        probability = np.empty((n, width), dtype=np.float64)
        probability[:] = row
        for command, part_branches in zip(commands, layout.branches, strict=True):
            _assign_grid(program, command, part_branches, sources, grid, bounds)
    else:
        probability, total = _grid_probabilities(program, commands, layout, sources, grid, bounds)
    if isinstance(total, float):
        if not abs(total - 1.0) <= _TOLERANCE:  # also catches NaN
            raise _sum_error(program, commands, total, sources[0])
    else:
        wrong = ~(np.abs(total - 1.0) <= _TOLERANCE)
        if wrong.any():
            bad = int(np.argmax(wrong))
            raise _sum_error(program, commands, float(total[bad]), sources[bad])
    counts = np.zeros(states.shape[0], dtype=np.int64)
    counts[source] = 1
    return GroupSuccessors(np.repeat(source, width), targets, probability.ravel(), counts)


def _grid_probabilities(
    program: Program,
    commands: Sequence[CompiledCommand],
    layout: BranchLayout,
    sources: IntArray,
    grid: IntArray,
    bounds: bool,
) -> tuple[FloatArray, FloatArray | float]:
    """Branch probabilities ``(choices, branches)`` and the product of the parts' sums
    (as in ``_check_sums``), with each part's assignments written into *grid*.
    """
    probability = np.ones((sources.shape[0], layout.width), dtype=np.float64)
    total: FloatArray | float = 1.0
    for command, part_branches in zip(commands, layout.branches, strict=True):
        sums: FloatArray | float = 0.0
        for update, branches in zip(command.updates, part_branches, strict=True):
            constant = update.constant_probability
            if constant is not None and constant >= 0:
                if constant != 1.0:  # x * 1.0 == x: nothing to do
                    probability[:, branches] *= constant
                sums = sums + constant
            else:
                p = _probability(program, command, update, sources)
                probability[:, branches] *= p[:, None]
                sums = sums + p
        _assign_grid(program, command, part_branches, sources, grid, bounds)
        total = total * (sums if command.constant_total is None else command.constant_total)
    return probability, total


def _assign_grid(
    program: Program,
    command: CompiledCommand,
    part_branches: tuple[slice | IntArray, ...],
    sources: IntArray,
    grid: IntArray,
    bounds: bool,
) -> None:
    """Write each update's assignments into the branches (columns of *grid*) taking it.

    Without *bounds* (the caller checks the whole layer), an integer constant is
    written as it is, with no array evaluated for it.
    """
    for update, branches in zip(command.updates, part_branches, strict=True):
        constants = update.constants if not bounds else ()
        for i, (column, rhs) in enumerate(update.assignments):
            constant = constants[i] if constants else None
            if constant is not None:
                grid[:, branches, column] = constant
                continue
            values = rhs(sources)
            _check_range(program, command, column, values, sources,
                         bounds and column not in update.unchecked)
            grid[:, branches, column] = values[:, None]


def format_state(names: Sequence[str], row: IntArray) -> str:
    """``x=1, y=2`` for a state row."""
    return ", ".join(f"{n}={int(v)}" for n, v in zip(names, row, strict=True))


# ---------------------------------------------------------------------------
# One module: every enabled command is a choice (no products needed)
# ---------------------------------------------------------------------------


def _expand_single(
    program: Program, part: Sequence[CompiledCommand], states: IntArray, bounds: bool = True,
    index: EqualityIndex | None = None,
) -> GroupSuccessors | None:
    """Branches in blocks, one per (command, update); the caller orders them by source."""
    enabled = _guards(part, states, index)
    blocks: list[tuple[IntArray, IntArray, FloatArray]] = []
    commands: list[IntArray] = []
    # (only the commands enabled somewhere: a part of 10^5 commands, one per state, is
    # not walked whole on every layer)
    for j in np.flatnonzero(enabled.any(axis=0)).tolist():
        rows = np.flatnonzero(enabled[:, j])
        found = _command_branches(program, part[j], rows, states[rows], bounds)
        blocks.extend(found)
        commands.extend(np.full(rows.size, j, dtype=np.int64) for _ in found)
    if not blocks:
        return None
    source, targets, probability = (np.concatenate(b) for b in zip(*blocks, strict=True))
    counts = np.count_nonzero(enabled, axis=1)
    return GroupSuccessors(source, targets, probability, counts,
                           np.concatenate(commands) if len(part) > 1 else None)


def _command_branches(
    program: Program, command: CompiledCommand, rows: IntArray, sources: IntArray, bounds: bool
) -> list[tuple[IntArray, IntArray, FloatArray]]:
    blocks = []
    total = np.zeros(rows.size, dtype=np.float64)
    for update in command.updates:
        p = _probability(program, command, update, sources)
        total += p
        targets = sources.copy()
        _assign(program, command, update, sources, targets, bounds)
        blocks.append((rows, targets, p))
    constant = command.constant_total
    if constant is not None and abs(constant - 1.0) <= _TOLERANCE:
        return blocks  # every row sums to the same, correct, total
    wrong = ~(np.abs(total - 1.0) <= _TOLERANCE)  # also catches NaN
    if wrong.any():
        bad = int(np.argmax(wrong))
        raise _sum_error(program, [command], total[bad], sources[bad])
    return blocks


# ---------------------------------------------------------------------------
# Several modules: choices and branches are products
# ---------------------------------------------------------------------------


def _enumerate_choices(group: ChoiceGroup, states: IntArray) -> _Choices | None:
    source = np.arange(states.shape[0])
    picks: list[IntArray] = []
    for p, part in enumerate(group.parts):
        if not part:
            return None
        enabled = _guards(part, states, group.index(p))
        rows, columns = np.nonzero(enabled[source])
        source = source[rows]
        picks = [p[rows] for p in picks]
        picks.append(columns.astype(np.int64))
        if source.size == 0:
            return None
    return _Choices(source, tuple(picks))


def _combination(group: ChoiceGroup, choices: _Choices) -> IntArray:
    """Per choice, its combination's number within *group* (mixed radix over the
    parts' commands, the last part's fastest)."""
    number = np.zeros(choices.source.size, dtype=np.int64)
    for part, pick in zip(group.parts, choices.picks, strict=True):
        number *= len(part)
        number += pick
    return number


def _guards(part: Sequence[CompiledCommand], states: IntArray,
            index: EqualityIndex | None = None) -> np.ndarray:
    """Enabledness ``(n, n_commands)`` of the part's commands (by *index*, if given, the
    same as their guards give)."""
    if index is not None:
        return index.enabled(states)
    enabled = np.empty((states.shape[0], len(part)), dtype=bool)
    for j, command in enumerate(part):
        enabled[:, j] = command.guard(states)
    return enabled


def _expand_updates(group: ChoiceGroup, choices: _Choices) -> tuple[IntArray, list[IntArray]]:
    """Branch-to-choice map and, per part, each branch's update index."""
    choice = np.arange(choices.source.size)
    updates: list[IntArray] = []
    for part, pick in zip(group.parts, choices.picks, strict=True):
        sizes = np.array([len(c.updates) for c in part], dtype=np.int64)
        repeats = sizes[pick[choice]]
        if np.all(repeats == 1):
            updates.append(np.zeros(choice.size, dtype=np.int64))
            continue
        starts = np.cumsum(repeats) - repeats
        choice = np.repeat(choice, repeats)
        updates = [np.repeat(u, repeats) for u in updates]
        updates.append(np.arange(choice.size) - np.repeat(starts, repeats))
    return choice, updates


@dataclass(frozen=True, slots=True)
class _PartTable:
    """A part's updates evaluated once per choice: ``(max_updates, n_choices)`` tables.

    Branches then gather from these tables, so expressions are evaluated per
    (choice, update) rather than per branch of the product.
    """

    probability: FloatArray
    values: dict[int, IntArray]  # column -> new value (the source value if unassigned)


def _part_table(
    program: Program,
    part: Sequence[CompiledCommand],
    pick: IntArray,
    sources: IntArray,
    bounds: bool = True,
) -> _PartTable:
    width = max(len(c.updates) for c in part)
    probability = np.zeros((width, pick.size), dtype=np.float64)
    columns = sorted({c for cmd in part for u in cmd.updates for c, _ in u.assignments})
    values = {c: np.repeat(sources[None, :, c], width, axis=0) for c in columns}
    for j, command in enumerate(part):
        rows = np.flatnonzero(pick == j)
        if rows.size == 0:
            continue
        sub = sources[rows]
        for u, update in enumerate(command.updates):
            constant = update.constant_probability
            if constant is not None and constant >= 0:
                probability[u][rows] = constant
            else:
                probability[u][rows] = _probability(program, command, update, sub)
            for column, rhs in update.assignments:
                new = rhs(sub)
                _check_range(program, command, column, new, sub,
                             bounds and column not in update.unchecked)
                values[column][u][rows] = new
    return _PartTable(probability, values)


def _probability(
    program: Program, command: CompiledCommand, update: CompiledUpdate, sources: IntArray
) -> FloatArray:
    constant = update.constant_probability
    if constant is not None and constant >= 0:
        return np.full(sources.shape[0], constant)
    p = np.asarray(update.probability(sources), dtype=np.float64)
    if p.min() < 0:
        bad = int(np.argmax(p < 0))
        where = format_state(program.variable_names, sources[bad])
        raise _error(command, f"negative probability {p[bad]:g} in state ({where})")
    return p


def _assign(
    program: Program,
    command: CompiledCommand,
    update: CompiledUpdate,
    sources: IntArray,
    targets: IntArray,
    bounds: bool,
) -> None:
    """Write the update's assignments (evaluated in *sources*) into *targets*."""
    for column, rhs in update.assignments:
        values = rhs(sources)
        _check_range(program, command, column, values, sources,
                     bounds and column not in update.unchecked)
        targets[:, column] = values


def check_update_ranges(program: Program, command: CompiledCommand, sources: IntArray) -> None:
    """Check that every update of *command* stays in range from each row of *sources*.

    :raises ModelError: naming the variable, the value and the first offending state.
    """
    for update in command.updates:
        for column, rhs in update.assignments:
            _check_range(program, command, column, rhs(sources), sources)


def _check_range(
    program: Program,
    command: CompiledCommand,
    column: int,
    values: np.ndarray,
    sources: IntArray,
    bounds: bool = True,
) -> None:
    """Type always; bounds only if *bounds* (interval analysis may have proved them)."""
    name = program.variable_names[column]
    if values.dtype.kind == "f":
        raise _error(command, f"update assigns a non-integer value to '{name}'")
    if not bounds:
        return
    low, high = program.lows[column], program.highs[column]
    if values.min() < low or values.max() > high:
        outside = (values < low) | (values > high)
        bad = int(np.argmax(outside))
        where = format_state(program.variable_names, sources[bad])
        message = (
            f"update sets {name} to {int(values[bad])}, outside its range "
            f"{low}..{high}, in state ({where})"
        )
        raise _error(command, message)


def _check_sums(
    program: Program,
    group: ChoiceGroup,
    choices: _Choices,
    tables: Sequence[_PartTable],
    sources: IntArray,
) -> None:
    """A product distribution's total is the product of its factors' totals."""
    totals = np.prod([t.probability.sum(axis=0) for t in tables], axis=0)
    wrong = ~(np.abs(totals - 1.0) <= _TOLERANCE)  # also catches NaN
    if not wrong.any():
        return
    bad = int(np.argmax(wrong))
    commands = [part[int(pick[bad])] for part, pick in zip(group.parts, choices.picks, strict=True)]
    raise _sum_error(program, commands, totals[bad], sources[bad])


def _sum_error(
    program: Program, commands: Sequence[CompiledCommand], total: float, state: IntArray
) -> ModelError:
    where = format_state(program.variable_names, state)
    message = f"probabilities sum to {total:.10g}, not 1, in state ({where})"
    return _error(commands[0], message, [c.module for c in commands])


def _error(
    command: CompiledCommand, message: str, modules: Sequence[str] | None = None
) -> ModelError:
    """An error located at *command* (the first command of a synchronised choice)."""
    names = ", ".join(modules) if modules else command.module
    label = f" [{command.command.action}]" if command.command.action else ""
    where = f"module{'s' if modules and len(modules) > 1 else ''} {names}, command{label}"
    return ModelError(f"{where}: {message}", command.span)
