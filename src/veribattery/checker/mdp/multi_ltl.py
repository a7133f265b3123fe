"""``multi(...)`` with LTL objectives, reduced to reachability (Etessami, Kwiatkowska,
Vardi & Yannakakis, LMCS 2008, Sec. 4).

When a ``P`` objective of a query is LTL, every ``P`` objective is read as LTL (``F a``,
``G a`` and a state formula are LTL too) and the MDP runs in the product with all their
parity automata at once. A strategy meets a set *S* of them by ending in an end
component of that product which is accepting for each objective of *S* at once (for
each, within its states of priority at least some even *p_i*, with one of priority
*p_i*) and staying there. So every state of such a component gets one more choice,
*stop in S*, leading to an absorbing state ``S``; objective *i* becomes "reach a stop
state of a set holding *i*", and the multi-objective programme of
:mod:`~veribattery.checker.mdp.multi` answers the query on that MDP. With reward
objectives, only components of zero-reward choices may be stayed in (only strategies
whose total rewards are finite count, as in the programme).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace
from functools import partial
from itertools import combinations
from itertools import product as every

import numpy as np
import scipy.sparse as sp

from veribattery._types import BoolArray, IntArray
from veribattery.checker.automata.parity import ParityAutomaton
from veribattery.checker.ltl.automaton import parity_of
from veribattery.checker.ltl.product import product
from veribattery.checker.mdp.components import end_components
from veribattery.checker.mdp.graph import ChoiceGraph
from veribattery.checker.mdp.model import MDP, MdpRewards
from veribattery.checker.mdp.operators import reward_structure
from veribattery.errors import CheckError
from veribattery.lang.nodes import (
    BoolLit,
    Eventually,
    Expr,
    Globally,
    LabelRef,
    LtlNode,
    LtlPath,
    LtlTemporal,
    Multi,
    Next,
    ProbOp,
    RewardOp,
    Until,
)

__all__ = ["has_ltl", "stopped_query"]

StateMask = Callable[[Expr], BoolArray]
#: The label of objective *i*'s stop states in the reduced MDP (no PRISM name has a NUL).
_STOPPED = "\0stopped {}"


def has_ltl(query: Multi) -> bool:
    """Whether some ``P`` objective of *query* is LTL."""
    return any(isinstance(op, ProbOp) and isinstance(op.path, LtlPath)
               for op in query.objectives)


def stopped_query(mdp: MDP, query: Multi, mask: StateMask) -> tuple[MDP, Multi, StateMask]:
    """The MDP with stop states, *query* with each ``P`` objective ``F`` of its stop
    states, and the mask of those labels (:mod:`this module <.multi_ltl>`)."""
    probabilities = [op for op in query.objectives if isinstance(op, ProbOp)]
    joint = _joint_product(mdp, [_as_ltl(op) for op in probabilities], mask)
    zero = _zero_reward_choices(mdp, query, joint.choices)
    reduced = _with_stops(mdp, joint, _stop_states(joint.graph, joint.priorities, zero))
    labels = dict(reduced.labels)
    rewritten: list[Expr] = []
    for op in query.objectives:
        if isinstance(op, ProbOp):
            name = _STOPPED.format(probabilities.index(op))
            rewritten.append(replace(op, path=Eventually(LabelRef(name, op.span), None,
                                                         op.span)))
        else:
            rewritten.append(op)
    return reduced, replace(query, objectives=tuple(rewritten)), partial(_stopped, labels)


def _stopped(labels: dict[str, BoolArray], expr: Expr) -> BoolArray:
    """The mask of a stop label (the only state formulas the rewritten query holds)."""
    assert isinstance(expr, LabelRef)
    return labels[expr.name]


class _Joint:
    """The product of the MDP with every objective's automaton."""

    def __init__(self, transitions: sp.csr_matrix, row_groups: IntArray, model_state: IntArray,
                 choices: IntArray, start: int, priorities: list[IntArray]) -> None:
        self.transitions, self.row_groups = transitions, row_groups
        self.model_state, self.choices, self.start = model_state, choices, start
        self.priorities = priorities
        owner = np.repeat(np.arange(model_state.size, dtype=np.int64), np.diff(row_groups))
        self.graph = ChoiceGraph.of(transitions, owner)


def _joint_product(mdp: MDP, formulas: Sequence[LtlNode], mask: StateMask) -> _Joint:
    transitions, groups = mdp.transitions, mdp.row_groups
    model_state = np.arange(mdp.num_states, dtype=np.int64)
    choices = np.arange(mdp.num_choices, dtype=np.int64)
    start = int(mdp.initial[0])
    automata: list[ParityAutomaton] = []
    states: list[IntArray] = []
    for formula in formulas:
        automaton, column = parity_of(formula, mask, mdp.num_states, formula.span)
        step = product(transitions, groups, automaton, column[model_state])
        transitions, groups = step.transitions, step.row_groups
        states = [s[step.model_state] for s in states] + [step.automaton_state]
        model_state, choices = model_state[step.model_state], choices[step.choices]
        start = int(step.start[start])
        automata.append(automaton)
    priorities = [a.priority[s].astype(np.int64) for a, s in zip(automata, states, strict=True)]
    return _Joint(transitions, groups, model_state, choices, start, priorities)


def _as_ltl(op: ProbOp) -> LtlNode:
    """A P objective's path as LTL (a state formula is one of its own)."""
    path = op.path
    span = path.span
    match path:
        case LtlPath(formula=formula):
            return formula
        case Eventually(operand=operand, bound=None):
            return LtlTemporal("F", None, operand, span)
        case Globally(operand=operand, bound=None):
            return LtlTemporal("G", None, operand, span)
        case Next(operand=operand):
            return LtlTemporal("X", None, operand, span)
        case Until(left=BoolLit(value=False), right=operand, bound=None):
            return LtlTemporal("U", BoolLit(False, span), operand, span)
        case Until(left=left, right=right, bound=None):
            return LtlTemporal("U", left, right, span)
    raise CheckError("multi(...) with LTL takes unbounded P objectives", span)


def _zero_reward_choices(mdp: MDP, query: Multi, choices: IntArray) -> BoolArray | None:
    """The product choices with no reward in any reward objective (None: no such
    objective, every choice may be stayed on)."""
    rewards = [op for op in query.objectives if isinstance(op, RewardOp)]
    if not rewards:
        return None
    zero = np.ones(mdp.num_choices, dtype=bool)
    for op in rewards:
        zero &= reward_structure(mdp, op).per_choice(mdp) == 0
    return np.asarray(zero[choices], dtype=bool)


def _stop_states(graph: ChoiceGraph, priorities: list[IntArray],
                 zero: BoolArray | None) -> dict[tuple[int, ...], BoolArray]:
    """Per set of objectives, the states of the end components accepting all of them."""
    found: dict[tuple[int, ...], BoolArray] = {}
    indices = range(len(priorities))
    for size in range(1, len(priorities) + 1):
        for chosen in combinations(indices, size):
            evens = [np.unique(priorities[i][priorities[i] % 2 == 0]) for i in chosen]
            states = np.zeros(graph.num_states, dtype=bool)
            for levels in every(*evens):
                states |= _accepting_for_all(graph, [priorities[i] for i in chosen],
                                             levels, zero)
            if states.any():
                found[chosen] = states
    return found


def _accepting_for_all(graph: ChoiceGraph, priorities: list[IntArray], levels: tuple[int, ...],
                       zero: BoolArray | None) -> BoolArray:
    """States of end components within priority >= levels[i] for every i that hold a
    state of priority levels[i] for every i."""
    inside = np.ones(graph.num_states, dtype=bool)
    for priority, level in zip(priorities, levels, strict=True):
        inside &= priority >= level
    found = end_components(graph, inside, zero)
    hits: set[int] | None = None
    for priority, level in zip(priorities, levels, strict=True):
        here = set(np.unique(found.component[(priority == level) & (found.component >= 0)]))
        hits = here if hits is None else hits & here
    if not hits:
        return np.zeros(graph.num_states, dtype=bool)
    return np.asarray(np.isin(found.component, sorted(hits)), dtype=bool)


def _with_stops(mdp: MDP, joint: _Joint, stops: dict[tuple[int, ...], BoolArray]) -> MDP:
    """The product with an absorbing state per set of objectives and a stop choice into it
    from each state of its components; labels name each objective's stop states."""
    n, sets = joint.model_state.size, list(stops)
    size = n + len(sets)
    base = sp.csr_matrix((joint.transitions.data, joint.transitions.indices,
                          joint.transitions.indptr), shape=(joint.transitions.shape[0], size))
    owner = [np.repeat(np.arange(n, dtype=np.int64), np.diff(joint.row_groups))]
    blocks, source = [base], [joint.choices]
    for k, chosen in enumerate(sets):
        rows = np.flatnonzero(stops[chosen])
        blocks.append(_jumps(rows.size, n + k, size))
        owner.append(rows)
        source.append(np.full(rows.size, -1))
    blocks.append(_jumps(len(sets), np.arange(n, size), size))  # the sinks' self-loops
    owner.append(np.arange(n, size, dtype=np.int64))
    source.append(np.full(len(sets), -1))
    all_owner = np.concatenate(owner)
    order = np.argsort(all_owner, kind="stable")
    matrix = sp.vstack(blocks, format="csr")[order]
    groups = np.concatenate([[0], np.cumsum(np.bincount(all_owner, minlength=size))])
    copied = np.concatenate(source)[order]
    labels = {}
    for i in range(len(joint.priorities)):
        mask = np.zeros(size, dtype=bool)
        mask[[n + k for k, chosen in enumerate(sets) if i in chosen]] = True
        labels[_STOPPED.format(i)] = mask
    rewards = tuple(_lifted(r, joint.model_state, copied, len(sets)) for r in mdp.rewards)
    return MDP(matrix, groups, np.array([joint.start]), labels, rewards=rewards)


def _jumps(count: int, target: int | IntArray, size: int) -> sp.csr_matrix:
    """*count* rows, each a certain step to *target* (one per row, or the same)."""
    columns = np.broadcast_to(np.asarray(target, dtype=np.int64), (count,))
    return sp.csr_matrix((np.ones(count), columns, np.arange(count + 1)), shape=(count, size))


def _lifted(rewards: MdpRewards, model_state: IntArray, copied: IntArray,
            sinks: int) -> MdpRewards:
    """A reward structure on the reduced MDP: nothing on the stops and in the sinks."""
    state = np.concatenate([rewards.state[model_state], np.zeros(sinks)])
    choice = np.where(copied >= 0, rewards.choice[np.maximum(copied, 0)], 0.0)
    return MdpRewards(rewards.name, state, choice)
