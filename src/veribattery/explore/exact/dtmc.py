"""Exact rational transition probabilities and rewards of an already-built DTMC.

The builder explores the state space in floating point; :func:`exact_dtmc` then
re-derives, for every transition of that DTMC, its probability as an exact
rational (:mod:`~veribattery.explore.exact.rational`): each command's updates are
re-expanded over all states at once (guards and assignments are the builder's
compiled ones, so the successors are the same), and each update's probability
is evaluated from the model's *source* expression -- formulas inlined and
modules renamed, but constants kept exact rather than folded into doubles --
once per distinct valuation of the variables it reads. Branches with the same
source and target are summed, and the result is aligned with the float CSR
matrix entry by entry (a mismatch is reported, never papered over). Rewards are
recomputed the same way.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from gmpy2 import mpq

from veribattery._named import by_key
from veribattery._types import BoolArray, IntArray
from veribattery.errors import ModelError
from veribattery.explore.build.builder import assemble, explore
from veribattery.explore.build.store import StateStore
from veribattery.explore.build.successors import format_state
from veribattery.explore.compile.expr import compile_expr
from veribattery.explore.compile.program import (
    ChoiceGroup,
    CompiledCommand,
    Program,
    compile_program,
)
from veribattery.explore.dtmc import DTMC
from veribattery.explore.exact.constants import exact_constants
from veribattery.explore.exact.program import (
    ExactSource,
    as_bools,
    exact_labels,
    exact_program,
    needs_exact,
)
from veribattery.explore.exact.rational import ExactScalar, ObjectArray, tabulate
from veribattery.lang.nodes import Command, Expr, FlatModel, Model, RewardStruct, Value
from veribattery.lang.semantics import expand_formulas, expanded_modules, inline_formulas

__all__ = ["ExactDTMC", "ExactRewards", "build_exact", "exact_dtmc", "numbered_targets"]

_ONE = mpq(1)
_ZERO = mpq(0)


@dataclass(frozen=True, slots=True)
class ExactRewards:
    """One reward structure in rationals: per state, and expected per step (transition)."""

    name: str | None
    state: ObjectArray
    transition: ObjectArray

    @property
    def total(self) -> ObjectArray:
        """State plus expected transition reward per step."""
        return np.asarray(self.state + self.transition, dtype=object)


@dataclass(frozen=True, slots=True)
class ExactDTMC:
    """A built DTMC with its transition probabilities and rewards as exact rationals.

    :param dtmc: the float DTMC (states, labels, CSR structure).
    :param probabilities: ``mpq`` per entry of ``dtmc.transitions`` (CSR data order).
    :param rewards: the reward structures, in declaration order.
    :param constants: the exact values of the model's constants.
    """

    dtmc: DTMC
    probabilities: ObjectArray
    rewards: tuple[ExactRewards, ...]
    constants: Mapping[str, ExactScalar]

    def reward(self, key: str | int | None) -> ExactRewards:
        """The reward structure named *key*, at index *key*, or the first (None)."""
        return by_key(self.rewards, key)


@dataclass(frozen=True, slots=True)
class _Context:
    """What the expansion needs besides the states."""

    constants: Mapping[str, ExactScalar]
    columns: Mapping[str, tuple[int, bool]]
    updates: dict[int, tuple[Expr, ...]]  # id(flat command) -> exact update probabilities
    ranges: Mapping[str, tuple[int, int]]  # each variable's range


@dataclass(frozen=True, slots=True)
class _Branches:
    source: IntArray
    targets: IntArray
    probability: ObjectArray


def build_exact(
    model: Model,
    flat: FlatModel,
    constants: Mapping[str, Value | str] | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> ExactDTMC:
    """Build *flat*'s DTMC with rounding-prone guards, assignments and labels decided
    exactly (:mod:`~veribattery.explore.exact.program`), then its exact probabilities.

    :param model: the parsed model; *flat* is ``flatten_model(model, constants)``.
    :param constants: the values given for undefined constants (decimals are exact).
    :raises ModelError: as :func:`exact_dtmc`, and as the float builder.
    """
    source = _source(model, flat, constants)
    program = exact_program(compile_program(flat), flat, source)
    states, initial, layers = explore(flat, program, progress)
    dtmc = exact_labels(assemble(flat, states, initial, layers), flat, source)
    return exact_dtmc(model, flat, dtmc, constants, program=program, source=source)


def exact_dtmc(
    model: Model,
    flat: FlatModel,
    dtmc: DTMC,
    constants: Mapping[str, Value | str] | None = None,
    *,
    program: Program | None = None,
    source: ExactSource | None = None,
) -> ExactDTMC:
    """Exact probabilities and rewards for *dtmc*, built from *flat* (flattened *model*).

    :param model: the parsed model (its unfolded expressions are evaluated).
    :param flat: ``flatten_model(model, constants)``.
    :param dtmc: ``build_dtmc(flat)``, or the DTMC :func:`build_exact` explored.
    :param constants: the values given for undefined constants (decimals are exact).
    :param program: the program *dtmc* was explored with (default: ``compile_program(flat)``).
    :param source: the exact constants and source expressions (computed if not given).
    :raises ModelError: for an expression without an exact rational value, or a
        state whose probabilities do not sum to exactly 1.
    """
    source = source or _source(model, flat, constants)
    program = program or compile_program(flat)
    updates = {k: tuple(u.probability for u in c.updates) for k, c in source.commands.items()}
    context = _Context(source.constants, source.columns, updates, source.ranges)
    states = dtmc.states
    counts: dict[str | None, IntArray] = {}
    parts: list[_Branches] = []
    for group in program.groups:
        found = _group_branches(group, states, context)
        if found is not None:
            branches, choices = found
            parts.append(branches)
            counts[group.action] = counts.get(group.action, 0) + choices
    total = sum(counts.values(), np.zeros(dtmc.num_states, dtype=np.int64))
    probabilities = _aligned(program.lows, program.highs, dtmc, parts, total)
    _check_sums(dtmc, probabilities, flat.variable_names)
    formulas = expand_formulas(model.formulas)
    sources = [inline_formulas(r, formulas) for r in model.rewards]
    rewards = tuple(
        _rewards(f, s, dtmc, context, counts, total)
        for f, s in zip(flat.rewards, sources, strict=True)
    )
    return ExactDTMC(dtmc, probabilities, rewards, source.constants)


def _source(
    model: Model, flat: FlatModel, constants: Mapping[str, Value | str] | None
) -> ExactSource:
    exact = exact_constants(model.constants, dict(constants or {}))
    formulas = expand_formulas(model.formulas)
    labels = {lab.name: inline_formulas(lab.expr, formulas) for lab in model.labels}
    ranges = {v.name: (v.low, v.high) for v in flat.variables}
    return ExactSource(exact, _columns(flat), _source_commands(model, flat, formulas), labels,
                       ranges)


def _columns(flat: FlatModel) -> dict[str, tuple[int, bool]]:
    return {v.name: (i, v.is_bool) for i, v in enumerate(flat.variables)}


def _source_commands(
    model: Model, flat: FlatModel, formulas: Mapping[str, Expr]
) -> dict[int, Command]:
    """Each flat command (by ``id``) and the command as written (formulas inlined, renamed).

    Flattening keeps modules, commands and updates in source order, so the
    unfolded modules line up with the flat ones position by position.
    """
    found: dict[int, Command] = {}
    for flat_module, module in zip(flat.modules, expanded_modules(model, formulas), strict=True):
        for flat_command, command in zip(flat_module.commands, module.commands, strict=True):
            found[id(flat_command)] = command
    return found


# ---------------------------------------------------------------------------
# Branches of one choice group over all states
# ---------------------------------------------------------------------------


def _group_branches(
    group: ChoiceGroup, states: IntArray, context: _Context
) -> tuple[_Branches, IntArray] | None:
    """Every branch of *group* in every state, and each state's number of choices."""
    enumerated = _choices(group, states)
    if enumerated is None:
        return None
    source, picks = enumerated
    choice, updates = _branch_updates(group, picks)
    sources = states[source[choice]]
    targets = sources.copy()
    probability = np.full(choice.size, _ONE, dtype=object)
    for first, (part, pick, update) in enumerate(zip(group.parts, picks, updates, strict=True)):
        chosen = pick[choice]
        for j, command in enumerate(part):
            here = chosen == j
            if here.any():
                _apply_command(command, here, update, sources, targets, probability, context,
                               first == 0)
    counts = np.bincount(source, minlength=states.shape[0])
    return _Branches(source[choice], targets, probability), counts


def _apply_command(
    command: CompiledCommand,
    here: BoolArray,
    update: IntArray,
    sources: IntArray,
    targets: IntArray,
    probability: ObjectArray,
    context: _Context,
    first: bool,
) -> None:
    """Multiply in the exact probability and write the assignments of *command*'s updates.

    :param first: the first part of the group (its probability is set, not multiplied).
    """
    expressions = context.updates[id(command.command)]
    for u, (compiled, expr) in enumerate(zip(command.updates, expressions, strict=True)):
        at = np.flatnonzero(here & (update == u))
        if at.size == 0:
            continue
        rows = sources[at]
        exact = tabulate(expr, context.constants, context.columns, rows)
        probability[at] = exact if first else probability[at] * exact
        for column, rhs in compiled.assignments:
            targets[at, column] = rhs(rows)


def _choices(group: ChoiceGroup, states: IntArray) -> tuple[IntArray, list[IntArray]] | None:
    """Joint choices: the state of each, and per part the index of the command picked."""
    source = np.arange(states.shape[0])
    picks: list[IntArray] = []
    for part in group.parts:
        if not part:
            return None
        enabled = np.empty((source.size, len(part)), dtype=bool)
        # once per part (every command's guard reads the same rows); no copy for the first
        here = states if source.size == states.shape[0] else states[source]
        for j, command in enumerate(part):
            enabled[:, j] = np.broadcast_to(command.guard(here), source.shape)
        rows, columns = np.nonzero(enabled)
        source = source[rows]
        picks = [p[rows] for p in picks] + [columns.astype(np.int64)]
        if source.size == 0:
            return None
    return source, picks


def _branch_updates(
    group: ChoiceGroup, picks: Sequence[IntArray]
) -> tuple[IntArray, list[IntArray]]:
    """Branch-to-choice map and, per part, each branch's update index (product order)."""
    choice = np.arange(picks[0].size)
    updates: list[IntArray] = []
    for part, pick in zip(group.parts, picks, strict=True):
        sizes = np.array([len(c.updates) for c in part], dtype=np.int64)
        repeats = sizes[pick[choice]]
        starts = np.cumsum(repeats) - repeats
        choice = np.repeat(choice, repeats)
        updates = [np.repeat(u, repeats) for u in updates]
        updates.append(np.arange(choice.size) - np.repeat(starts, repeats))
    return choice, updates


# ---------------------------------------------------------------------------
# Assembling and checking
# ---------------------------------------------------------------------------


def numbered_targets(store: StateStore, targets: list[IntArray], keep: BoolArray) -> IntArray:
    """The numbers of the *targets* (blocks, in order) where *keep* holds, a block at a
    time: the blocks are not copied into one table first."""
    ends = np.cumsum([block.shape[0] for block in targets])
    found = [store.add(block[keep[end - block.shape[0]:end]])
             for block, end in zip(targets, ends, strict=True)]
    return np.concatenate(found) if found else np.empty(0, dtype=np.int64)


def _aligned(
    lows: Sequence[int],
    highs: Sequence[int],
    dtmc: DTMC,
    parts: list[_Branches],
    choices: IntArray,
) -> ObjectArray:
    """Exact branch probabilities summed per (source, target), in the float CSR's order."""
    n = dtmc.num_states
    store = StateStore(lows, highs)
    store.add(dtmc.states)
    dead = np.flatnonzero(choices == 0)
    source = np.concatenate([p.source for p in parts] + [dead])
    probability = np.concatenate([p.probability for p in parts] + [_ones(dead.size)])
    shared = np.flatnonzero(choices[source] > 1)  # nondeterministic states: uniform choice
    if shared.size:
        probability[shared] = probability[shared] / choices[source[shared]].astype(object)
    keep = probability != _ZERO  # no transition, and its target no state (as built)
    targets = [p.targets for p in parts] + [dtmc.states[dead]]
    key = source[keep].astype(np.int64) * n + numbered_targets(store, targets, keep)
    order = np.argsort(key, kind="stable")
    key, values = key[order], probability[keep][order]
    starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    summed = values if starts.size == key.size else np.add.reduceat(values, starts)
    P = dtmc.transitions
    rows = np.repeat(np.arange(n, dtype=np.int64), np.diff(P.indptr))
    expected = rows * n + P.indices
    if store.count != n or not np.array_equal(key[starts], expected):
        raise ModelError(
            "the exact re-expansion of the model does not match its float state space "
            "(a guard or assignment evaluates differently in rational arithmetic)"
        )
    return np.asarray(summed, dtype=object)


def _ones(size: int) -> ObjectArray:
    return np.full(size, _ONE, dtype=object)


def _check_sums(dtmc: DTMC, probabilities: ObjectArray, names: Sequence[str]) -> None:
    """Every row of the exact matrix must sum to exactly 1 (the float check allows 1e-6)."""
    indptr = dtmc.transitions.indptr
    sums = np.add.reduceat(probabilities, indptr[:-1]) if probabilities.size else probabilities
    wrong = np.flatnonzero(sums != _ONE)
    if wrong.size:
        state = int(wrong[0])
        where = format_state(names, dtmc.states[state])
        raise ModelError(
            f"in exact arithmetic the probabilities leaving state ({where}) sum to "
            f"{sums[state]}, not 1 (--exact takes each literal as written, e.g. 0.333 is "
            "333/1000: write 1/3)"
        )


def _rewards(
    flat: RewardStruct,
    source: RewardStruct,
    dtmc: DTMC,
    context: _Context,
    counts: Mapping[str | None, IntArray],
    choices: IntArray,
) -> ExactRewards:
    """State rewards, and transition rewards weighted by each action's share of the choices."""
    states = dtmc.states
    state = np.full(dtmc.num_states, _ZERO, dtype=object)
    transition = np.full(dtmc.num_states, _ZERO, dtype=object)
    for item, exact in zip(flat.items, source.items, strict=True):
        at = np.flatnonzero(_guard(item.guard, exact.guard, dtmc, context))
        share = counts.get(item.action) if item.is_transition else None
        if share is not None:
            at = at[share[at] > 0]  # only where the action is among the choices
        if at.size == 0 or (item.is_transition and share is None):
            continue
        value = tabulate(exact.value, context.constants, context.columns, states[at])
        if share is None:
            _accumulate(state, at, value)
            continue
        whole = share[at] == choices[at]  # the only action: weight 1, no product needed
        if not whole.all():
            value[~whole] = value[~whole] * _shares(share[at][~whole], choices[at][~whole])
        _accumulate(transition, at, value)
    return ExactRewards(source.name, state, transition)


def _guard(flat: Expr, written: Expr, dtmc: DTMC, context: _Context) -> np.ndarray:
    """A reward guard in every state: exactly from *written* where doubles may round."""
    if needs_exact(flat, context.ranges):
        return tabulate(written, context.constants, context.columns, dtmc.states, as_bools)
    value = compile_expr(flat, dtmc.variable_names)(dtmc.states)
    return np.broadcast_to(value, (dtmc.num_states,)).astype(bool)


def _accumulate(total: ObjectArray, at: IntArray, value: ObjectArray) -> None:
    """``total[at] += value``, adding only where *total* is not still exactly zero."""
    fresh = total[at] == _ZERO
    total[at[fresh]] = value[fresh]
    if not fresh.all():
        total[at[~fresh]] = total[at[~fresh]] + value[~fresh]


def _shares(count: IntArray, choices: IntArray) -> ObjectArray:
    """``count / choices`` as rationals (0 where a state has no choice)."""
    key = count.astype(np.int64) * (int(choices.max(initial=0)) + 1) + choices
    _, first, inverse = np.unique(key, return_index=True, return_inverse=True)
    table = [mpq(int(count[i]), max(int(choices[i]), 1)) for i in first]
    return np.asarray(_as_objects(table)[inverse.reshape(-1)], dtype=object)


def _as_objects(items: Sequence[mpq]) -> ObjectArray:
    array = np.empty(len(items), dtype=object)
    array[:] = items
    return array
