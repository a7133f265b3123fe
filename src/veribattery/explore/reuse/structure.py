"""Structure reuse: re-evaluate transition probabilities on a state space already built.

Two flat models *share a structure* when they have the same variables (names,
ranges, initial values), the same ``init`` block and the same commands -- guards,
actions and assignments -- and differ at most in their update probabilities
(rewards and labels may differ too: they are evaluated afresh on the states).
That is decided from the models themselves: a constant that reaches a guard, an
assignment or a variable's range appears in :func:`structure_key` through its
value after flattening, so changing it changes the key, while a constant that
reaches only probability expressions does not.

Sharing a key is necessary but not sufficient: a probability that becomes 0
drops a branch, and so can remove states (a probability of 1 makes its siblings
0). :func:`reevaluate` accepts a re-evaluation only if exactly the same branches
survive; otherwise it returns None and the caller builds afresh. An accepted
re-evaluation yields the very DTMC a fresh build would (same numbering, same
matrix entries summed in the same order).

It takes one of two ways. When the program has a fused plan (``fused``), the
build records the *branch kind* of every branch (which commands and updates it
combines); equal keys mean equal guards and assignments, hence the same enabled
choices and the same successors, so only the probabilities are computed again --
one gather per constant factor, one evaluation over the states per probability
expression -- and weighted as the builder does (:func:`.reprice.reprice`). The
recorded kinds are checked once at build time (they must reproduce the built
probabilities bit for bit), else this way is off for that structure. Otherwise
every known state is expanded again in one vectorised pass per chunk -- no
breadth-first search, no state lookup -- and the successors compared too.
"""

from __future__ import annotations

import dataclasses
import hashlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from veribattery._types import FloatArray, IntArray
from veribattery._unique import distinct_first
from veribattery.errors import ModelError
from veribattery.explore.build.builder import (
    Layer,
    assemble,
    expand_frontier,
    explore,
    initial_states,
    rewarded_actions,
)
from veribattery.explore.build.plan import plan_layers
from veribattery.explore.build.reprice import branch_kinds, reprice
from veribattery.explore.compile.program import Program, compile_program, with_probabilities
from veribattery.explore.dtmc import DTMC
from veribattery.lang.nodes import Command, FlatModel, LabelDecl, RewardStruct

__all__ = ["Structure", "build_reusable", "reevaluate", "structure_key"]

#: Known states expanded at once during a re-evaluation.
_CHUNK = 1 << 14


@dataclass(frozen=True, slots=True)
class Structure:
    """What a build leaves behind so that later models of the same key can reuse it.

    :param key: the :func:`structure_key` of the model built.
    :param program: its compiled commands (guards and assignments are re-used).
    :param initial_rows: the initial states as the model defined them (before numbering).
    :param rows: source state of every kept branch, in build order.
    :param columns: target state of every kept branch, in build order.
    :param dropped: positions of the zero-probability branches among all branches.
    :param labels: the model's labels and rewards, whose vectors a model that
        declares them alike can take over.
    :param kinds: the fused plan's branch kind of every branch (dropped ones
        included), or None when there is no plan or it did not reproduce the build.
    :param sources: the source state of every branch (dropped ones included).
    :param choices: the number of enabled choices per state.
    :param action_choices: per rewarded action, its number of choices per state.
    """

    key: str
    program: Program
    initial_rows: IntArray
    rows: IntArray
    columns: IntArray
    dropped: IntArray
    labels: tuple[LabelDecl, ...]
    rewards: tuple[RewardStruct, ...]
    kinds: IntArray | None = None
    sources: IntArray | None = None
    choices: IntArray | None = None
    action_choices: dict[str | None, IntArray] | None = None


def structure_key(model: FlatModel) -> str:
    """A digest equal for flat models that may share one state space.

    It covers the variables, the ``init`` block and every command with its
    probabilities left out; rewards and labels are left out too.
    """
    parts = (
        model.variables,
        model.init,
        tuple((m.name, m.variables, tuple(map(_skeleton, m.commands))) for m in model.modules),
    )
    return hashlib.sha256(_canonical(parts, {}).encode()).hexdigest()


def build_reusable(
    model: FlatModel, *, progress: Callable[[int, int], None] | None = None
) -> tuple[DTMC, Structure]:
    """Build the DTMC of *model* as :func:`build_dtmc` does, and keep its :class:`Structure`."""
    program = compile_program(model)
    states, initial, layers = explore(model, program, progress)
    structure = Structure(
        key=structure_key(model),
        program=program,
        initial_rows=states[_first_occurrences(initial)],
        rows=np.concatenate([layer.rows for layer in layers]),
        columns=np.concatenate([layer.columns for layer in layers]),
        dropped=_global_dropped(layers),
        labels=model.labels,
        rewards=model.rewards,
    )
    structure = _with_kinds(structure, states, layers)
    return assemble(model, states, initial, layers), structure


def _with_kinds(structure: Structure, states: IntArray, layers: list[Layer]) -> Structure:
    """*structure* with the branch kinds of the fused plan, if they reproduce *layers*."""
    plan = plan_layers(structure.program)
    if plan is None:
        return structure
    found = [branch_kinds(plan, states[start : start + _CHUNK])
             for start in range(0, states.shape[0], _CHUNK)]
    kinds = np.concatenate([k for k, _ in found]) if found else np.empty(0, dtype=np.int64)
    sources = np.concatenate([s + i * _CHUNK for i, (_, s) in enumerate(found)]
                             ) if found else np.empty(0, dtype=np.int64)
    choices = np.concatenate([layer.choices for layer in layers])
    actions = {a for layer in layers for a in layer.action_choices}
    action_choices = {a: np.concatenate([_counts(layer, a) for layer in layers])
                      for a in actions}
    small = np.int32 if states.shape[0] < 2**31 else np.int64
    candidate = dataclasses.replace(
        structure, kinds=kinds.astype(np.int32), sources=sources.astype(small),
        choices=choices, action_choices=action_choices)
    built = np.concatenate([layer.probabilities for layer in layers])
    again = _repriced(plan, states, candidate)
    return candidate if again is not None and np.array_equal(again[0], built) else structure


def _counts(layer: Layer, action: str | None) -> IntArray:
    found = layer.action_choices.get(action)
    return np.zeros(layer.choices.size, dtype=layer.choices.dtype) if found is None else found


def _repriced(plan: Any, states: IntArray,
              structure: Structure) -> tuple[FloatArray, IntArray] | None:
    """The kept branches' probabilities under *plan*, and the dropped positions; None
    when they cannot be computed this way or other branches are dropped."""
    kinds, sources, choices = structure.kinds, structure.sources, structure.choices
    if kinds is None or sources is None or choices is None:
        return None
    probability = reprice(plan, states, kinds, sources)
    if probability is None:
        return None
    probability /= np.maximum(choices, 1)[sources]
    keep = probability > 0
    dropped = np.flatnonzero(~keep)
    if not np.array_equal(dropped, structure.dropped):
        return None
    return probability[keep], dropped


def reevaluate(base: DTMC, structure: Structure, model: FlatModel) -> DTMC | None:
    """The DTMC of *model* on the state space of *base*, or None if it does not share it.

    :param base: a DTMC built by :func:`build_reusable` (any model of the same key).
    :param structure: the structure returned with it.
    :param model: the model whose probabilities, rewards and labels to evaluate.
    """
    if structure_key(model) != structure.key:
        return None
    rows = initial_states(model)
    if not np.array_equal(rows, structure.initial_rows):
        return None
    try:
        layers = _fast_layers(model, base.states, structure)
        if layers is None:
            layers = _relayers(model, base.states, structure)
    except ModelError:  # let a fresh build report it, located as it always is
        return None
    if layers is None:
        return None
    known = (
        dict(base.labels) if model.labels == structure.labels else None,
        base.rewards if model.rewards == structure.rewards else None,
    )
    dtmc = assemble(model, base.states, np.arange(rows.shape[0]), layers, known)
    _share_indices(dtmc.transitions, base.transitions)
    return dtmc


def _share_indices(P: Any, base: Any) -> None:
    """Give *P* the index arrays of *base* when they are equal (as they are when the
    structure is re-used): the checker's memos by sparsity pattern then
    recognise the pattern by the arrays' identity instead of hashing them at every
    point (:func:`veribattery.checker.linalg.restriction.index_digest`). Neither is modified
    in place afterwards."""
    if (P.shape == base.shape and np.array_equal(P.indptr, base.indptr)
            and np.array_equal(P.indices, base.indices)):
        P.indptr, P.indices = base.indptr, base.indices


def _fast_layers(model: FlatModel, states: IntArray,
                 structure: Structure) -> list[Layer] | None:
    """One layer over all known states with the probabilities of *model* re-priced by
    branch kind (guards and successors are those of the build), or None."""
    if structure.kinds is None or structure.choices is None:
        return None
    plan = plan_layers(with_probabilities(structure.program, model))
    found = None if plan is None else _repriced(plan, states, structure)
    if found is None:
        return None
    probability, dropped = found
    return [Layer(structure.rows, structure.columns, probability, structure.choices,
                  structure.action_choices or {}, dropped, structure.kinds.size)]


def _relayers(model: FlatModel, states: IntArray, structure: Structure) -> list[Layer] | None:
    """Layers over all known states, or None as soon as a branch differs from the build's."""
    program = with_probabilities(structure.program, model)
    rewarded = rewarded_actions(model.rewards)
    layers: list[Layer] = []
    kept = offset = 0
    dropped: list[IntArray] = []
    for start in range(0, states.shape[0], _CHUNK):
        found = expand_frontier(program, states[start : start + _CHUNK], rewarded)
        end = kept + found.source.size
        columns = structure.columns[kept:end]
        if (
            end > structure.columns.size
            or not np.array_equal(found.source + start, structure.rows[kept:end])
            or not np.array_equal(found.targets, states[columns])
        ):
            return None
        dropped.append(found.dropped + offset)
        layers.append(Layer(structure.rows[kept:end], columns, found.probability, found.choices,
                            found.action_choices, found.dropped, found.branches))
        kept, offset = end, offset + found.branches
    if kept != structure.columns.size or not np.array_equal(
        np.concatenate(dropped), structure.dropped
    ):
        return None
    return layers


def _global_dropped(layers: list[Layer]) -> IntArray:
    """The layers' dropped positions, counted over all branches of the build."""
    offsets = np.cumsum([0] + [layer.branches for layer in layers[:-1]])
    parts = [layer.dropped + offset for layer, offset in zip(layers, offsets, strict=True)]
    return np.concatenate(parts) if parts else np.empty(0, dtype=np.int64)


def _first_occurrences(indices: IntArray) -> IntArray:
    """*indices* without repeats, in order of first occurrence (the numbering order)."""
    first = distinct_first(indices)[1]
    return indices[np.sort(first)]


# ---------------------------------------------------------------------------
# The key
# ---------------------------------------------------------------------------


def _skeleton(command: Command) -> tuple[Any, ...]:
    """A command without its probabilities: action, guard, and each update's assignments."""
    return (command.action, command.guard, tuple(u.assignments for u in command.updates))


def _canonical(node: Any, memo: dict[int, str]) -> str:
    """Text that identifies *node* up to source positions (spans are left out).

    Flattening inlines formulas as shared sub-trees, so texts are memoised by identity.
    """
    known = memo.get(id(node))
    if known is not None:
        return known
    if hasattr(type(node), "__dataclass_fields__") and not isinstance(node, type):
        inner = ",".join(_canonical(v, memo) for v in _fields(node))
        text = f"{type(node).__name__}({inner})"
    elif isinstance(node, tuple | list):
        text = "(" + ",".join(_canonical(v, memo) for v in node) + ")"
    elif isinstance(node, frozenset | set):
        text = "{" + ",".join(sorted(_canonical(v, memo) for v in node)) + "}"
    else:
        text = repr(node)
    memo[id(node)] = text
    return text


def _fields(node: Any) -> Iterator[Any]:
    return map(node.__getattribute__, _field_names(type(node)))


_FIELD_NAMES: dict[type, tuple[str, ...]] = {}


def _field_names(cls: type) -> tuple[str, ...]:
    """A record class's fields but its span (``dataclasses.fields`` is slow per node)."""
    names = _FIELD_NAMES.get(cls)
    if names is None:
        names = _FIELD_NAMES[cls] = tuple(
            f.name for f in dataclasses.fields(cls) if f.name != "span")
    return names
