"""Breadth-first construction of the DTMC of a flat model, one whole frontier at a time.

States are numbered in discovery order: the initial states first, then each BFS
layer's new successors in order of (source state, choice, update). Each layer is
expanded group by group with numpy over all its states (see ``successors``), and
the successors are deduplicated against the known states in one batch (see
``store``). PRISM's DTMC rules apply: a state with several enabled choices takes
each with probability 1/n, and a state with none gets a self-loop.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.sparse as sp

from veribattery._collector import collections_spaced
from veribattery._memory import trim_heap
from veribattery._text import count_of
from veribattery._types import BoolArray, FloatArray, IntArray
from veribattery.errors import ModelError
from veribattery.explore.build.fused import Expansion, LayerPlan
from veribattery.explore.build.guard import Footprint, MemoryGuard
from veribattery.explore.build.halting import halted, with_self_loops
from veribattery.explore.build.initial import initial_states
from veribattery.explore.build.layers import Layer, Layers
from veribattery.explore.build.plan import plan_layers
from veribattery.explore.build.sample import BranchSample, sampled_branches
from veribattery.explore.build.store import StateStore, radix_words
from veribattery.explore.compile.expr import CompileCache, CompiledExpr, compile_expr, may_fail
from veribattery.explore.compile.program import Program, compile_program
from veribattery.explore.dtmc import DTMC, RewardVectors, require_dtmc
from veribattery.lang.nodes import Expr, FlatModel, RewardItem, RewardStruct

if TYPE_CHECKING:
    from veribattery.explore.build.successors import GroupSuccessors

__all__ = ["Expansion", "Layer", "assemble", "build_dtmc", "build_warnings",
           "check_finite_reward", "expand_frontier", "explore", "initial_states", "layer_plan",
           "memory_footprint", "rewarded_actions"]

#: Frontier states expanded at once, at most.
_CHUNK = 1 << 14
#: The first chunk of a search: its branches per state are not known yet.
_FIRST_CHUNK = 1 << 8
#: Words (int64) of successor rows a chunk may produce, estimated from the chunk before:
#: a heavily synchronised model (Herman's ring: ~440 branches of 15 variables per state)
#: would otherwise hold gigabytes of successor rows for one chunk of _CHUNK states.
_BRANCH_WORDS = 1 << 22
_NONE = np.empty(0, dtype=np.int64)
_NO_FLOATS = np.empty(0, dtype=np.float64)


@collections_spaced
def build_dtmc(model: FlatModel, *, progress: Callable[[int, int], None] | None = None) -> DTMC:
    """Explore the reachable states of *model* and return its DTMC.

    :param model: a flat model (constants substituted, formulas inlined).
    :param progress: called once per BFS layer with (states found so far, frontier size).
    :raises ModelError: an update leaves a variable's range, a probability is
        negative, or a choice's probabilities do not sum to 1.
    :raises ModelTooLarge: the state space would not fit in the memory available.
    :raises ArgumentError: for a model not flattened (a parsed :class:`Model`).
    """
    states, initial, layers = explore(model, compile_program(model), progress)
    return assemble(model, states, initial, layers)


def explore(
    model: FlatModel,
    program: Program,
    progress: Callable[[int, int], None] | None = None,
    guard: MemoryGuard | None = None, *, compact: bool = False,
    halt: CompiledExpr | None = None,
) -> tuple[IntArray, IntArray, list[Layer]]:
    """Breadth-first search: the states in numbering order, the initial ones, the layers.

    Consecutive small layers are merged (:class:`Layers`): their number stays small at any depth.

    :param progress: called once per BFS layer with (states found so far, frontier size).
    :param guard: checked once per BFS layer (default: against the memory available).
    :param compact: the states in the narrowest type of the ranges, else in int64.
    :param halt: where it holds, a state is not expanded but given a self-loop
        (:mod:`~veribattery.explore.build.halting`).
    :raises ModelTooLarge: when the search would outgrow the memory available.
    """
    require_dtmc(model.model_type)
    store = StateStore(program.lows, program.highs)
    initial = store.add(initial_states(model))
    rewarded = rewarded_actions(model.rewards)
    layers = Layers(_count_dtype(program))
    if guard is None:
        guard = MemoryGuard(memory_footprint(program))
    low, size, transitions = 0, _FIRST_CHUNK, 0
    while low < store.count:
        high = store.count
        # Chunks bound the memory of wide layers; sources stay in order, so the
        # numbering is the same as for the whole layer at once.
        start = low
        if low == 0 and high > _CHUNK:  # a wide first layer: no branching known yet
            guard.wide_layer(store.count, high, _sampler(program, store, rewarded, high))
        while start < high:
            stop = min(start + size, high)
            branches = _explore_chunk(program, store, (start, stop), (rewarded, halt), layers)
            size = _next_chunk(size, branches, stop - start, len(program.lows))
            transitions += branches
            start = stop
            if start < high:  # a wide layer (herman's first: every state) reports as it goes
                if progress is not None:
                    progress(store.count, high - start)
                guard.chunk_done(store.count, transitions, start - low, high - low)
        if progress is not None:
            progress(store.count, high - low)
        guard.layer_done(store.count, high, high - low, transitions)
        low = high
    return store.compact_states if compact else store.states, initial, layers.done(store.count)


def memory_footprint(program: Program) -> Footprint:
    """The builder's bytes per state and transition for *program*'s states."""
    return Footprint(len(program.lows), radix_words(program.lows, program.highs).shape[1])


def _explore_chunk(
    program: Program, store: StateStore, chunk: tuple[int, int],
    how: tuple[set[str | None], CompiledExpr | None], layers: Layers,
) -> int:
    """Expand the frontier states *chunk* (low, high) into *layers*; return its branches
    (*how*: the rewarded actions, and where a state is left unexpanded).

    (A function of its own so that the successor rows, up to ``_BRANCH_WORDS`` words,
    are freed before the next chunk is expanded.)
    """
    rewarded, halt = how
    rows = store.rows(*chunk)
    stopped = halted(halt, rows)
    if stopped is None:
        found = expand_frontier(program, rows, rewarded)
    else:
        live = rows[~stopped]
        found = with_self_loops(expand_frontier(program, live, rewarded) if live.shape[0]
                                else _no_branches(live), stopped, rows)
    layers.add(found, chunk[0], store.add(found.targets), store.count)
    return found.branches


def _no_branches(rows: IntArray) -> Expansion:
    """The expansion of no state (*rows*: none, of the frontier's width)."""
    none = np.zeros(0, dtype=np.int64)
    return Expansion(none, rows, np.zeros(0), np.zeros(0, dtype=np.uint8), {}, none, 0)


def _sampler(program: Program, store: StateStore, rewarded: set[str | None],
             high: int) -> Callable[[], BranchSample | None]:
    """The branches of a uniform sample of the states ``0..high-1``."""
    def branches_of(rows: IntArray) -> IntArray:
        found = expand_frontier(program, rows, rewarded)
        return np.bincount(found.source, minlength=rows.shape[0])
    return lambda: sampled_branches(store.rows_at, branches_of, 0, high)


def _next_chunk(size: int, branches: int, states: int, width: int) -> int:
    """The next chunk's size: at most four times this one's (the branching may grow),
    at most ``_CHUNK``, and about ``_BRANCH_WORDS`` words of successor rows at this
    chunk's branches per state."""
    words = max(branches, 1) * (width + 2) / states  # rows, plus source and probability
    return max(1, min(_CHUNK, 4 * size, int(_BRANCH_WORDS / words)))


# ---------------------------------------------------------------------------
# One BFS layer
# ---------------------------------------------------------------------------


def _count_dtype(program: Program) -> np.dtype[Any]:
    """The smallest unsigned dtype that holds any state's number of choices (usually
    one byte): the layers keep a count per state and per rewarded action until the
    DTMC is assembled, and at int64 those arrays would outweigh the transitions.
    """
    bound = sum(math.prod(len(part) for part in group.parts) for group in program.groups)
    return np.min_scalar_type(bound)


def expand_frontier(program: Program, frontier: IntArray, rewarded: set[str | None]) -> Expansion:
    """Every branch out of *frontier*, ordered by source state (see :class:`Expansion`).

    The layer is expanded in one pass over all groups (see ``fused``) when the
    program allows it; otherwise, or when that pass finds anything unusual, group
    by group. Update ranges are checked once over all the layer's targets (two
    numpy calls instead of two per assignment); only if one is out of range is
    the frontier expanded again with per-update checks, which raise the located
    error.
    """
    plan = layer_plan(program)
    if plan is not None:
        fused = plan.expand(frontier, rewarded)
        if fused is not None:
            return fused
    # Layers the fused plan does not cover (and error locations) only: imported then.
    from veribattery.explore.build.successors import expand_groups

    try:
        found = expand_groups(program, frontier, bounds=False)
        expansion = _combine(program, found, frontier, rewarded)
    except (ModelError, _OutOfRange):
        # Expand again checking each update as it is made, so that the first error
        # in command order is the one reported, located at its command.
        expand_groups(program, frontier, bounds=True)
        raise
    return expansion


#: Plans of the programs explored last, by identity (a program holds no weak references).
_PLANS: list[tuple[Program, LayerPlan | None]] = []


def layer_plan(program: Program) -> LayerPlan | None:
    """*program*'s fused layer plan (None: too many kinds), made once per program."""
    for known, plan in _PLANS:
        if known is program:
            return plan
    plan = plan_layers(program)
    _PLANS[:] = [*_PLANS[-3:], (program, plan)]
    return plan


class _OutOfRange(Exception):
    """Some branch of a layer leaves its variable's range (located by a re-expansion)."""


def _check_in_range(program: Program, targets: IntArray) -> None:
    lows, highs = _bounds(program.lows, program.highs)
    if (targets < lows).any() or (targets > highs).any():
        raise _OutOfRange


@functools.lru_cache(maxsize=64)
def _bounds(lows: tuple[int, ...], highs: tuple[int, ...]) -> tuple[IntArray, IntArray]:
    return np.array(lows, dtype=np.int64), np.array(highs, dtype=np.int64)


def _combine(
    program: Program,
    found: list[tuple[str | None, GroupSuccessors]],
    frontier: IntArray,
    rewarded: set[str | None],
) -> Expansion:
    n = frontier.shape[0]
    choices = np.zeros(n, dtype=np.int64)
    action_choices: dict[str | None, IntArray] = {}
    for action, successors in found:
        choices += successors.choices
        if action in rewarded:
            action_choices[action] = action_choices.get(action, 0) + successors.choices
    source, targets, probability, dropped, branches = _merge(program, found, choices, frontier)
    return Expansion(source, targets, probability, choices, action_choices, dropped, branches)


def _merge(
    program: Program,
    found: list[tuple[str | None, GroupSuccessors]],
    choices: IntArray,
    frontier: IntArray,
) -> tuple[IntArray, IntArray, FloatArray, IntArray, int]:
    """All branches of a layer ordered by source, weighted 1/n, deadlocks self-looped;
    zero-probability branches dropped (their positions returned), and the branch count.

    :raises _OutOfRange: a branch (even of probability 0) leaves a variable's range.
    """
    dead = np.flatnonzero(choices == 0)
    source = np.concatenate([s.source for _, s in found] + [dead])
    targets = np.concatenate([s.targets for _, s in found] + [frontier[dead]])
    _check_in_range(program, targets)
    probability = np.concatenate([s.probability for _, s in found] + [np.ones(dead.size)])
    probability /= np.maximum(choices, 1)[source]
    keep = probability > 0
    if np.all(source[1:] >= source[:-1]):  # one group, already in source order
        if keep.all():
            return source, targets, probability, _NONE, source.size
        return (source[keep], targets[keep], probability[keep], np.flatnonzero(~keep),
                source.size)
    # Chunks have < 2**15 states: an int16 key lets numpy use its O(n) radix sort.
    key = source.astype(np.int16) if choices.size < 1 << 15 else source
    order = np.argsort(key, kind="stable")
    kept = keep[order]
    dropped = _NONE if keep.all() else np.flatnonzero(~kept)
    order = order[kept] if dropped.size else order
    return source[order], targets[order], probability[order], dropped, source.size


# ---------------------------------------------------------------------------
# Assembling the DTMC
# ---------------------------------------------------------------------------


def assemble(
    model: FlatModel,
    states: IntArray,
    initial: IntArray,
    layers: list[Layer],
    known: tuple[dict[str, BoolArray] | None, tuple[RewardVectors, ...] | None] = (None, None),
) -> DTMC:
    """The DTMC of *model* from its explored layers (which are emptied as they are used).

    :param known: labels and rewards already evaluated on these states and choices
        (see ``reuse.structure``), or None to evaluate them.
    """
    n = states.shape[0]
    choices = np.concatenate([layer.choices for layer in layers])
    matrix = _transition_matrix(n, layers)
    labels, rewards = known
    # The labels' and rewards' common sub-expressions and tables, compiled once; no
    # memo: it would keep a result per node and chunk alive until the end.
    cache = CompileCache(memoise=False)
    if labels is None:
        labels = _labels(model, (states, cache), initial, choices == 0)
    if rewards is None:
        rewards = tuple(_reward_vectors(model, r, (states, cache), choices, layers)
                        for r in model.rewards)
    deadlocks = int(np.count_nonzero(choices == 0))
    nondeterministic = int(np.count_nonzero(choices > 1))
    return DTMC(
        transitions=matrix,
        states=states,
        variable_names=model.variable_names,
        initial=np.flatnonzero(np.bincount(initial, minlength=n)),  # np.unique imports numpy.ma
        labels=labels,
        rewards=rewards,
        deadlocks=deadlocks,
        nondeterministic=nondeterministic,
        warnings=build_warnings(deadlocks, nondeterministic),
    )


def _transition_matrix(n: int, layers: list[Layer]) -> sp.csr_matrix:
    """CSR straight from the layers: their rows are already sorted by source state.

    Each field is moved out of the layers layer by layer into its concatenation
    (see ``_drain``), so the peak holds about one copy of the transitions, not two.
    """
    counts = np.zeros(n, dtype=np.int64)
    for layer in layers:
        if layer.rows.size:
            first = int(layer.rows[0])
            found = np.bincount(layer.rows - first)
            counts[first : first + found.size] += found
    for i, layer in enumerate(layers):
        layers[i] = replace(layer, rows=_NONE)
    columns = _drain(layers, "columns", _NONE)
    data = _drain(layers, "probabilities", _NO_FLOATS)
    indptr = np.zeros(n + 1, dtype=columns.dtype)
    np.cumsum(counts, out=indptr[1:])
    matrix = sp.csr_matrix((data, columns, indptr), shape=(n, n))
    matrix.sum_duplicates()  # sorts each row's columns and adds repeated successors
    return matrix


def _drain(layers: list[Layer], name: str, empty: np.ndarray) -> np.ndarray:
    """The concatenation of field *name* over *layers*, each layer's array released as
    soon as it is copied: the output's pages are touched as the inputs are freed.
    """
    parts = [getattr(layer, name) for layer in layers]
    dtype = np.result_type(*parts) if parts else empty.dtype
    out = np.empty(sum(p.size for p in parts), dtype=dtype)
    del parts
    start = freed = 0
    for i, layer in enumerate(layers):
        part = getattr(layer, name)
        out[start : start + part.size] = part
        start += part.size
        freed += part.nbytes
        released: dict[str, Any] = {name: empty}
        layers[i] = replace(layer, **released)
        if freed >= _TRIM_BYTES:
            # Freed layers of a few MB stay in the C heap (glibc raises its mmap
            # threshold after the first frees), so the copy would add to the peak
            # instead of replacing them: hand the memory back as it is freed.
            del part
            trim_heap()
            freed = 0
    return out


#: Bytes of layers released between two returns of free heap memory to the system.
_TRIM_BYTES = 32 << 20


def build_warnings(deadlocks: int, nondeterministic: int) -> tuple[str, ...]:
    """What a build fixed (deadlocks) or drew uniformly (a DTMC's nondeterminism), as
    PRISM reports it."""
    loops = "self-loop" if deadlocks == 1 else "self-loops"
    found = [f"{count_of(deadlocks, 'deadlock state')} ({loops} added)"] if deadlocks else []
    if nondeterministic:
        found.append(f"{nondeterministic} states with several enabled choices "
                     "(each taken with equal probability)")
    return tuple(found)


def _labels(
    model: FlatModel, over: tuple[IntArray, CompileCache], initial: IntArray, dead: BoolArray
) -> dict[str, BoolArray]:
    labels = {label.name: _over_states(model, label.expr, over, bool) for label in model.labels}
    init = np.zeros(over[0].shape[0], dtype=bool)
    init[initial] = True
    labels["init"] = init
    labels["deadlock"] = dead
    return labels


#: States evaluated at once by labels and rewards: bounds the temporaries (a
#: ``? :`` with a risky branch copies the rows it selects) to a few MB.
_EVAL_CHUNK = 1 << 16


def _over_states(
    model: FlatModel, expr: Expr, over: tuple[IntArray, CompileCache], dtype: Any,
    where: BoolArray | None = None,
) -> np.ndarray:
    """*expr* in every state, as *dtype*, evaluated chunk by chunk; sub-expressions
    over small domains are tabulated (as for the commands), each table built once per
    cache (the ``mt`` reward's ``T_CELL*dist`` of three actions, a label's formula).
    With *where*, 0 elsewhere: an expression that may fail is evaluated only there."""
    states, cache = over
    ranges = {v.name: (v.low, v.high) for v in model.variables}
    evaluate = compile_expr(expr, model.variable_names, ranges=ranges, cache=cache)
    if where is None or not may_fail(evaluate):
        out = _chunked(evaluate, states, dtype)
        return out if where is None else np.where(where, out, 0)
    out = np.zeros(states.shape[0], dtype=dtype)
    out[where] = _chunked(evaluate, states[where], dtype)
    return out


def _chunked(evaluate: CompiledExpr, states: IntArray, dtype: Any) -> np.ndarray:
    out = np.empty(states.shape[0], dtype=dtype)
    for start in range(0, states.shape[0], _EVAL_CHUNK):
        # int64, as compiled expressions take (a no-op unless the table is compact)
        block = np.asarray(states[start : start + _EVAL_CHUNK], dtype=np.int64)
        out[start : start + _EVAL_CHUNK] = evaluate(block)
    return out


def rewarded_actions(rewards: tuple[RewardStruct, ...]) -> set[str | None]:
    return {item.action for r in rewards for item in r.items if item.is_transition}


def _reward_vectors(
    model: FlatModel,
    struct: RewardStruct,
    over: tuple[IntArray, CompileCache],
    choices: IntArray,
    layers: list[Layer],
) -> RewardVectors:
    """State rewards, and transition rewards weighted by each action's share of the choices."""
    states = over[0]
    state = np.zeros(states.shape[0], dtype=np.float64)
    transition = np.zeros(states.shape[0], dtype=np.float64)
    share: dict[str | None, FloatArray] = {}
    for item in struct.items:
        guard = _over_states(model, item.guard, over, bool)
        value = _over_states(model, item.value, over, np.float64, where=guard)
        check_finite_reward(struct, item, value, model, states)
        if not item.is_transition:
            state += value
            continue
        if item.action not in share:
            share[item.action] = _action_share(item.action, choices, layers)
        transition += share[item.action] * value
    return RewardVectors(struct.name, state, transition)


def check_finite_reward(struct: RewardStruct, item: RewardItem, value: FloatArray,
                        model: FlatModel, states: IntArray) -> None:
    """A reward that is infinite or NaN in a state is an error, as in PRISM."""
    bad = np.flatnonzero(~np.isfinite(value))
    if bad.size:
        name = f'"{struct.name}"' if struct.name is not None else "(unnamed)"
        from veribattery.explore.build.successors import format_state  # an error only

        where = format_state(model.variable_names, states[bad[0]])
        raise ModelError(f"reward structure {name} is not finite at state ({where}): "
                         f"{value[bad[0]]}", item.value.span)


def _action_share(action: str | None, choices: IntArray, layers: list[Layer]) -> FloatArray:
    """Fraction of each state's choices that carry *action* (0 in deadlock states)."""
    counts = np.concatenate(
        [
            np.asarray(layer.action_choices.get(action, np.zeros(layer.choices.size)))
            for layer in layers
        ]
    )
    return counts / np.maximum(choices, 1)
