"""Breadth-first construction of the MDP of a flat ``mdp`` model.

PRISM's MDP semantics: in each state, every enabled command of a module, and every
enabled combination of commands synchronising on an action (one per participating
module), is a choice of its own, labelled by its action. The DTMC builder merges a
state's choices into one uniform distribution; here each *atomic* group -- one
command, or one combination of synchronising commands -- yields at most one choice
per state, expanded by the same vectorised successor code (``successors``), and the
choices stay separate rows of a choice matrix grouped by state. A state with no
enabled choice gets a self-loop (reported, as PRISM fixes deadlocks).
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp

from veribattery._collector import collections_spaced
from veribattery._types import BoolArray, FloatArray, IntArray
from veribattery._unique import distinct
from veribattery.explore.build.atoms import AtomicGroups
from veribattery.explore.build.builder import (
    _FIRST_CHUNK,
    _labels,
    _next_chunk,
    _over_states,
    build_warnings,
    check_finite_reward,
    initial_states,
    layer_plan,
    memory_footprint,
)
from veribattery.explore.build.guard import MemoryGuard
from veribattery.explore.build.halting import compile_halt, halted, mdp_with_loops
from veribattery.explore.build.store import StateStore
from veribattery.explore.build.successors import expand_group
from veribattery.explore.compile.expr import CompileCache, CompiledExpr
from veribattery.explore.compile.program import (
    Program,
    compile_program,
)
from veribattery.lang.nodes import Expr, FlatModel, RewardStruct

__all__ = ["BuiltMdp", "MdpRewardVectors", "build_mdp"]

@dataclass(frozen=True, slots=True)
class MdpRewardVectors:
    """One reward structure: per state (state rewards), per choice (transition rewards)."""

    name: str | None
    state: FloatArray
    choice: FloatArray


@dataclass(frozen=True, slots=True)
class BuiltMdp:
    """The parts of an MDP as explored (the checker's ``MDP`` is made from them).

    :param transitions: ``choices x states`` CSR matrix, one row per choice.
    :param row_groups: ``states + 1`` offsets of each state's choices.
    :param choice_actions: per choice, its index in *actions* (``""``: unlabelled).
    :param states: one row of variable values per state, in the narrowest integer type
        of the variables' ranges (:attr:`StateStore.compact_states`): read it through
        int64 copies of the columns an expression needs, or :meth:`wide` for arithmetic
        on whole rows.
    """

    transitions: sp.csr_matrix
    row_groups: IntArray
    initial: IntArray
    labels: dict[str, BoolArray]
    choice_actions: IntArray
    actions: tuple[str, ...]
    rewards: tuple[MdpRewardVectors, ...]
    states: IntArray
    variable_names: tuple[str, ...]
    deadlocks: int
    #: States not expanded, where the build's *stop* formula held (each has a self-loop).
    stopped: int = 0

    def wide(self) -> BuiltMdp:
        """This MDP with its state table in int64 (exact exploration re-expands and
        evaluates whole rows)."""
        return replace(self, states=np.asarray(self.states, dtype=np.int64))

    @property
    def warnings(self) -> tuple[str, ...]:
        """What the build fixed, as PRISM reports it."""
        return build_warnings(self.deadlocks, 0)


@collections_spaced
def build_mdp(model: FlatModel, *,
              progress: Callable[[int, int], None] | None = None,
              program: Program | None = None, guard: MemoryGuard | None = None,
              stop: Expr | None = None) -> BuiltMdp:
    """Explore the reachable states of the ``mdp`` *model*, one choice per enabled
    command or synchronised combination of commands.

    :param stop: a state formula over the model's variables: a state where it holds is
        not expanded but given a self-loop (no action, not a deadlock), as Storm's
        builder treats its terminal states (see ``pipeline.stopping``).
    :param program: the compiled program to explore with (default:
        ``compile_program(model)``; ``--exact`` gives one with guards decided exactly).
    :param guard: checked after each chunk (default: against the memory available).
    :raises ModelError: an update leaves a variable's range, a probability is
        negative, or a choice's probabilities do not sum to 1.
    :raises ModelTooLarge: when what is found would not fit in the memory available.
    """
    program = program or compile_program(model)
    guard = guard or MemoryGuard(memory_footprint(program))
    atoms = AtomicGroups.of(program)
    halt = compile_halt(model, stop)
    store = StateStore(program.lows, program.highs)
    initial = store.add(initial_states(model))
    rows: list[sp.csr_matrix] = []
    counts: list[IntArray] = []
    kinds: list[IntArray] = []
    low = found = 0
    size = _FIRST_CHUNK
    while low < store.count:
        # (chunks grow as the DTMC builder's do, within its words of successor rows: a
        # step of Python per group and chunk, eajs.4's 178 groups over 4,096 states at a
        # time, was most of its build)
        high = min(store.count, low + size)
        matrix, per_state, kind = _expand(program, atoms, store, (low, high), halt)
        size = _next_chunk(size, matrix.nnz, high - low, len(program.lows))
        rows.append(matrix)
        counts.append(per_state)
        kinds.append(kind)
        if progress is not None:
            progress(store.count, high - low)
        found += matrix.nnz
        guard.chunk_done(store.count, found, high)
        low = high
    n = store.count
    transitions = sp.vstack([_widen(m, n) for m in rows], format="csr")
    per_state = np.concatenate(counts)
    kind = np.concatenate(kinds)
    # Narrow: int64 rows of zeroconf (N=20, K=4) took 76 MB, half of Storm's whole process.
    states = store.compact_states
    dead = _dead_states(per_state, kind, len(atoms))
    cache = CompileCache(memoise=False)
    labels = _labels(model, (states, cache), initial, dead)
    row_groups = np.concatenate([[0], np.cumsum(per_state)]).astype(np.int64)
    owner = np.repeat(np.arange(n), per_state)
    group = atoms.group_of(kind)
    rewards = tuple(_reward_vectors(model, r, (states, cache), owner, group, atoms)
                    for r in model.rewards)
    return BuiltMdp(transitions, row_groups, distinct(initial), labels,
                    atoms.action_indices(group), atoms.actions, rewards, states,
                    model.variable_names, int(dead.sum()),
                    int(np.count_nonzero(kind == len(atoms) + 1)))


def _expand(program: Program, atoms: AtomicGroups, store: StateStore, chunk: tuple[int, int],
            halt: CompiledExpr | None) -> tuple[sp.csr_matrix, IntArray, IntArray]:
    """The choices of states ``low..high-1`` (in state, then group order): their rows,
    the number per state, and each one's atomic group (``len(atoms)``: a deadlock loop;
    ``len(atoms) + 1``: the self-loop of a state where *halt* holds, not expanded).

    Expanded in one pass over all groups where the program's layer plan allows
    (``fused``: its kinds are :class:`AtomicGroups`' numbers), else group by
    group. Either way the targets are numbered group by group (see :func:`_fused`),
    so that the states are numbered alike whichever path a chunk takes; a branch of
    probability 0 is dropped before (as the DTMC builder, PRISM and Storm do)."""
    low, high = chunk
    frontier = store.rows(low, high)
    stopped = halted(halt, frontier)
    live = frontier if stopped is None else frontier[~stopped]
    found = _fused(program, live, len(atoms)) if live.shape[0] else _nothing(live)
    if found is None:
        found = _grouped(program, atoms, live)
    source, group, row, targets, p, numbering = found
    keep = p > 0  # a branch of probability 0 is no transition: its target no state
    order = np.flatnonzero(keep) if numbering is None else numbering[keep[numbering]]
    row, p, targets = row[order], p[order], targets[order]
    entries = (p, row, store.add(targets))
    if stopped is not None:
        source, group, entries = mdp_with_loops(stopped, low, len(atoms) + 1, (source, group),
                                                entries)
    matrix = sp.csr_matrix((entries[0], (entries[1], entries[2])),
                           shape=(source.size, store.count))
    matrix.sum_duplicates()
    per_state = np.bincount(source, minlength=high - low)
    return matrix, per_state.astype(np.int64), group


def _nothing(frontier: IntArray) -> _Choices:
    """No choice and no branch: every state of the chunk halted."""
    none = np.zeros(0, dtype=np.int64)
    return none, none, none, frontier[:0], np.zeros(0), None


#: Per choice its source and atomic group; per branch its choice, target and probability;
#: and the order in which the targets are numbered (None: as they are).
_Choices = tuple[IntArray, IntArray, IntArray, IntArray, FloatArray, IntArray | None]


def _fused(program: Program, frontier: IntArray, groups: int) -> _Choices | None:
    """The chunk's choices by the program's layer plan, or None where it gives up.

    Its branches come by state, then group; they are numbered in :func:`_grouped`'s
    order: group by group, a lone command's update by update (each over the states),
    a synchronised combination's state by state (each with its branches)."""
    plan = layer_plan(program)
    if plan is None or plan.kinds != groups:  # (the same enumeration, or none)
        return None
    found = plan.branches(frontier)
    if found is None:
        return None
    widths = found.widths
    row = np.repeat(np.arange(found.kind.size), widths)
    kind = found.kind[row]
    update = np.arange(row.size) - np.repeat(np.cumsum(widths) - widths, widths)
    lone = (plan.kind_commands[:, 1:] == plan.commands).all(axis=1)[kind]
    numbering = np.lexsort((np.where(lone, found.source, update),
                            np.where(lone, update, found.source), kind))
    return found.choice_source, found.kind, row, found.targets, found.probability, numbering


def _grouped(program: Program, atoms: AtomicGroups, frontier: IntArray) -> _Choices:
    """The chunk's choices group by group (errors raised where they are, located); the
    branches atomic group by atomic group, each one's as its expansion gives them (see
    :func:`_fused`), the deadlocks' last.

    A group expands the atomic groups the chunk enables one by one (found by
    :meth:`AtomicGroups.enabled_in`, which dismisses whole subtrees of combinations at
    once: firewire's ~5,000 per chunk, a few dozen enabled), unless they outnumber its
    commands: then it is expanded whole, all its combinations at once, at a cost per
    command (a guard and a table of updates over the chunk) where one by one costs a
    Python step per combination (eajs.5's 1.9 million, some 500 enabled per chunk over
    125 commands: 16 s of its build one by one; firewire.true's build 9.7 s whole past
    16 combinations, 8.4 s one by one). Either way the branches come atomic group by
    atomic group, so that the states are numbered alike."""
    sources: list[IntArray] = []
    groups: list[IntArray] = []
    targets: list[IntArray] = []
    probability: list[FloatArray] = []
    guards: dict[int, BoolArray | None] = {}
    for index, choices in enumerate(program.groups):
        commands = sum(len(part) for part in choices.parts)
        few = list(itertools.islice(atoms.enabled_in(index, frontier, guards), commands + 1))
        if len(few) > commands:
            found = expand_group(program, choices, frontier, True)
            parts = [] if found is None else [(found, atoms.starts[index])]
        else:
            parts = []
            for number in few:
                found = expand_group(program, atoms[number], frontier, True)
                if found is not None:
                    parts.append((found, number))
        for found, first in parts:
            # by atomic group (a stable sort keeps each one's branches in the order of
            # its own expansion)
            combination = found.combination
            order = (slice(None) if combination is None
                     else np.argsort(combination, kind="stable"))
            sources.append(found.source[order])
            groups.append(np.full(found.source.size, first, dtype=np.int64)
                          if combination is None else first + combination[order])
            targets.append(found.targets[order])
            probability.append(found.probability[order])
    enabled = np.zeros(frontier.shape[0], dtype=bool)
    for source in sources:
        enabled[source] = True
    dead = np.flatnonzero(~enabled)
    sources.append(dead)
    groups.append(np.full(dead.size, len(atoms), dtype=np.int64))
    targets.append(frontier[dead])
    probability.append(np.ones(dead.size))
    source, group = np.concatenate(sources), np.concatenate(groups)
    order = np.lexsort((group, source))  # stable: a choice's updates keep their order
    by_state, group = source[order], group[order]
    new_row = np.r_[True, (by_state[1:] != by_state[:-1]) | (group[1:] != group[:-1])]
    starts = np.flatnonzero(new_row)
    row = np.empty(order.size, dtype=np.int64)
    row[order] = np.cumsum(new_row) - 1
    return (by_state[starts], group[starts], row, np.concatenate(targets),
            np.concatenate(probability), None)


def _widen(matrix: sp.csr_matrix, n: int) -> sp.csr_matrix:
    """*matrix* with *n* columns (states found after its chunk was expanded)."""
    return sp.csr_matrix((matrix.data, matrix.indices, matrix.indptr),
                         shape=(matrix.shape[0], n))


def _dead_states(per_state: IntArray, kind: IntArray, loop: int) -> BoolArray:
    """States whose only choice is the self-loop added for a deadlock (group *loop*)."""
    first = np.concatenate([[0], np.cumsum(per_state)[:-1]]).astype(np.int64)
    return np.asarray(kind[first] == loop, dtype=bool)


def _reward_vectors(model: FlatModel, struct: RewardStruct,
                    over: tuple[IntArray, CompileCache], owner: IntArray, group: IntArray,
                    atoms: AtomicGroups) -> MdpRewardVectors:
    """State rewards per state; transition rewards per choice, by the action of its
    *group* (:meth:`AtomicGroups.group_of`; none on the self-loops added to deadlocks
    and to the states left unexpanded)."""
    states = over[0]
    state = np.zeros(states.shape[0], dtype=np.float64)
    choice = np.zeros(owner.size, dtype=np.float64)
    for item in struct.items:
        guard = _over_states(model, item.guard, over, bool)
        value = _over_states(model, item.value, over, np.float64, where=guard)
        check_finite_reward(struct, item, value, model, states)
        if not item.is_transition:
            state += value
            continue
        choice += np.where(atoms.with_action(group, item.action), value[owner], 0.0)
    return MdpRewardVectors(struct.name, state, choice)
