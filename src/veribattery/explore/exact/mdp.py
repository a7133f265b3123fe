"""An ``mdp`` model built with exact rational probabilities and rewards (``--exact``).

The MDP is explored by the float builder (:func:`~veribattery.explore.build.mdp.build_mdp`)
with the guards, assignments and labels that doubles may round decided exactly
(:mod:`~veribattery.explore.exact.program`), so its states and choices are those
of the numbers as written. Each choice's probabilities are then re-derived as
rationals: every atomic group (one command, or one combination of synchronising
commands) is re-expanded over all states by the DTMC's exact expansion, a branch
lands in the row of its state and group (a state's rows follow the group order),
branches with the same row and target are summed, and the result is aligned with
the float matrix entry by entry -- a mismatch is reported, never papered over.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace

import numpy as np
from gmpy2 import mpq

from veribattery._named import by_key
from veribattery._types import BoolArray, IntArray
from veribattery.errors import ModelError
from veribattery.explore.build.atoms import AtomicGroups
from veribattery.explore.build.mdp import BuiltMdp, build_mdp
from veribattery.explore.build.store import StateStore
from veribattery.explore.build.successors import format_state
from veribattery.explore.compile.expr import compile_expr
from veribattery.explore.compile.program import Program, compile_program
from veribattery.explore.exact.dtmc import (
    _Branches,
    _Context,
    _group_branches,
    _source,
    numbered_targets,
)
from veribattery.explore.exact.program import ExactSource, as_bools, exact_program, needs_exact
from veribattery.explore.exact.rational import ExactScalar, ObjectArray, tabulate
from veribattery.lang.nodes import Expr, FlatModel, Model, RewardStruct, Value
from veribattery.lang.semantics import expand_formulas, inline_formulas

__all__ = ["ExactMdp", "ExactMdpRewards", "build_exact_mdp"]

_ONE = mpq(1)
_ZERO = mpq(0)


@dataclass(frozen=True, slots=True)
class ExactMdpRewards:
    """One reward structure in rationals: per state, and per choice (its action's reward)."""

    name: str | None
    state: ObjectArray
    choice: ObjectArray

    def per_choice(self, owner: IntArray) -> ObjectArray:
        """The reward of one step taken by each choice (*owner*: each choice's state)."""
        return np.asarray(self.state[owner] + self.choice, dtype=object)


@dataclass(frozen=True, slots=True)
class ExactMdp:
    """A built MDP with its probabilities and rewards as exact rationals.

    :param built: the MDP as explored (states, choices, labels, CSR structure).
    :param probabilities: ``mpq`` per stored entry of ``built.transitions`` (CSR order).
    :param rewards: the reward structures, in declaration order.
    :param constants: the exact values of the model's constants.
    """

    built: BuiltMdp
    probabilities: ObjectArray
    rewards: tuple[ExactMdpRewards, ...]
    constants: Mapping[str, ExactScalar]

    def reward(self, key: str | int | None) -> ExactMdpRewards:
        """The reward structure named *key*, at index *key*, or the first (None)."""
        return by_key(self.rewards, key)


def build_exact_mdp(
    model: Model,
    flat: FlatModel,
    constants: Mapping[str, Value | str] | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> ExactMdp:
    """Build *flat*'s MDP with rounding-prone guards decided exactly, then its exact
    probabilities and rewards.

    :param model: the parsed model; *flat* is ``flatten_model(model, constants)``.
    :param constants: the values given for undefined constants (decimals are exact).
    :raises ModelError: for an expression without an exact rational value, a choice
        whose probabilities do not sum to exactly 1, and as the float builder.
    """
    source = _source(model, flat, constants)
    program = exact_program(compile_program(flat), flat, source)
    built = _exact_labels(build_mdp(flat, progress=progress, program=program).wide(), flat,
                          source)
    updates = {k: tuple(u.probability for u in c.updates) for k, c in source.commands.items()}
    context = _Context(source.constants, source.columns, updates, source.ranges)
    atoms = AtomicGroups.of(program)
    probabilities, kind = _probabilities(built, atoms, program, context)
    _check_sums(built, probabilities)
    formulas = expand_formulas(model.formulas)
    written = [inline_formulas(r, formulas) for r in model.rewards]
    owner = np.repeat(np.arange(built.states.shape[0]), np.diff(built.row_groups))
    groups = [g.action for g in atoms.groups] + [_NO_ACTION]
    actions = [groups[g] for g in atoms.group_of(kind).tolist()]
    rewards = tuple(_rewards(f, w, built, context, owner, actions)
                    for f, w in zip(flat.rewards, written, strict=True))
    return ExactMdp(built, probabilities, rewards, source.constants)


#: The action of the self-loop added to a deadlock: no reward item matches it.
_NO_ACTION = object()


def _exact_labels(built: BuiltMdp, flat: FlatModel, source: ExactSource) -> BuiltMdp:
    """*built* with each rounding-prone label recomputed exactly over its states."""
    labels = dict(built.labels)
    for label in flat.labels:
        if source.rounds(label.expr):
            exact = source.function(source.labels[label.name], as_bools)
            labels[label.name] = np.asarray(exact(built.states), dtype=bool)
    return replace(built, labels=labels)


def _probabilities(built: BuiltMdp, atoms: AtomicGroups, program: Program,
                   context: _Context) -> tuple[ObjectArray, IntArray]:
    """The exact value of every stored entry, and each row's atomic group
    (``len(atoms)``: the self-loop of a deadlock).

    A state's rows follow the group order, so a group's row in a state is the number
    of groups before it enabled there: counted group by group (a states-by-groups table
    of them took 150 MB on csma.3-2's 36,850 states and 500 groups)."""
    states = built.states
    start = built.row_groups[:-1]
    taken = np.zeros(states.shape[0], dtype=np.int64)  # per state, its rows placed so far
    parts: list[_Branches] = []
    rows: list[IntArray] = []
    placed: list[tuple[IntArray, int]] = []  # (rows, atomic group)
    for index in atoms.enabled_somewhere(states):
        branches = _group_branches(atoms[index], states, context)
        if branches is None:
            continue
        part, counts = branches
        parts.append(part)
        rows.append(start[part.source] + taken[part.source])
        enabled = np.flatnonzero(counts > 0)
        placed.append((start[enabled] + taken[enabled], index))
        taken[enabled] += 1
    dead = np.flatnonzero(taken == 0)
    parts.append(_Branches(dead, states[dead], _ones(dead.size)))
    rows.append(start[dead])
    placed.append((start[dead], len(atoms)))
    if int(taken.sum()) + dead.size != built.transitions.shape[0]:
        raise _mismatch()
    kind = np.empty(built.transitions.shape[0], dtype=np.int64)
    for at, index in placed:
        kind[at] = index
    return _aligned(built, program, parts, np.concatenate(rows)), kind


def _aligned(built: BuiltMdp, program: Program, parts: list[_Branches],
             row: IntArray) -> ObjectArray:
    """Exact branch probabilities summed per (row, target), in the float CSR's order."""
    n = built.states.shape[0]
    store = StateStore(program.lows, program.highs)
    store.add(built.states)
    probability = np.concatenate([p.probability for p in parts])
    keep = probability != _ZERO  # no transition, and its target no state (as built)
    target = numbered_targets(store, [p.targets for p in parts], keep)
    key = row[keep].astype(np.int64) * n + target
    order = np.argsort(key, kind="stable")
    key, values = key[order], probability[keep][order]
    starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    summed = values if starts.size == key.size else np.add.reduceat(values, starts)
    P = built.transitions
    expected = np.repeat(np.arange(P.shape[0], dtype=np.int64), np.diff(P.indptr)) * n
    expected += P.indices
    placed = np.argsort(expected, kind="stable")
    if store.count != n or not np.array_equal(key[starts], expected[placed]):
        raise _mismatch()
    result = np.empty(expected.size, dtype=object)
    result[placed] = summed
    return result


def _mismatch() -> ModelError:
    return ModelError(
        "the exact re-expansion of the MDP does not match its float state space "
        "(a guard or assignment evaluates differently in rational arithmetic)"
    )


def _ones(size: int) -> ObjectArray:
    return np.full(size, _ONE, dtype=object)


def _check_sums(built: BuiltMdp, probabilities: ObjectArray) -> None:
    """Every choice's probabilities must sum to exactly 1 (the float check allows 1e-6)."""
    indptr = built.transitions.indptr
    sums = np.add.reduceat(probabilities, indptr[:-1]) if probabilities.size else probabilities
    wrong = np.flatnonzero(sums != _ONE)
    if wrong.size:
        state = int(np.searchsorted(built.row_groups, wrong[0], side="right") - 1)
        where = format_state(built.variable_names, built.states[state])
        raise ModelError(
            f"in exact arithmetic the probabilities of a choice in state ({where}) sum to "
            f"{sums[wrong[0]]}, not 1 (--exact takes each literal as written, e.g. 0.333 "
            "is 333/1000: write 1/3)"
        )


def _rewards(flat: RewardStruct, written: RewardStruct, built: BuiltMdp, context: _Context,
             owner: IntArray, actions: list[object]) -> ExactMdpRewards:
    """State rewards per state; transition rewards per choice, by the choice's action."""
    states = built.states
    state = np.full(states.shape[0], _ZERO, dtype=object)
    choice = np.full(owner.size, _ZERO, dtype=object)
    row_action = np.empty(len(actions), dtype=object)
    row_action[:] = actions
    for item, exact in zip(flat.items, written.items, strict=True):
        holds = _guard(item.guard, exact.guard, built, context)
        at = np.flatnonzero(holds)
        if at.size == 0:
            continue
        value = np.full(states.shape[0], _ZERO, dtype=object)
        value[at] = tabulate(exact.value, context.constants, context.columns, states[at])
        if not item.is_transition:
            state = np.asarray(state + value, dtype=object)
            continue
        matching = np.array([a == item.action for a in row_action], dtype=bool) & holds[owner]
        choice[matching] = choice[matching] + value[owner[matching]]
    return ExactMdpRewards(written.name, state, choice)


def _guard(flat: Expr, written: Expr, built: BuiltMdp, context: _Context) -> BoolArray:
    """A reward guard in every state: exactly from *written* where doubles may round."""
    if needs_exact(flat, context.ranges):
        table = tabulate(written, context.constants, context.columns, built.states, as_bools)
        return np.asarray(table, dtype=bool)
    value = compile_expr(flat, built.variable_names)(built.states)
    return np.broadcast_to(value, (built.states.shape[0],)).astype(bool)
