"""The flows of a multi-objective witness: how often each choice of the product is
taken, and where runs stop, under a strategy that attains a ``multi(...)`` answer.

The linear programme of :mod:`~veribattery.checker.mdp.multi` gives, per choice it
keeps (one that leaves its class or pays a reward), its expected number of uses
*y*, and per collapsed zero-reward end component (a *resting* class) the
probability *z* of staying there forever. A strategy needs more: how to move
*inside* a resting class, and at which of its states to stop. Both come from a
second, small programme on the resting states alone ("uncollapsing"): per state
*s* of a resting class,

    uses of the inside choices out of s - uses of inside choices into s + stay(s)
        = start(s) + uses of kept choices into s - uses of kept choices out of s,

with the inside choices' uses *w* >= 0 and ``stay(s)`` >= 0, minimising the sum of
*w* (so that no flow circulates for nothing). When that leaves a paying choice
inside a class unreached (the programme's uses of it circulate within the class
while the runs stop where they enter), the programme is solved again with a small
use of every inside choice of each entered class (:func:`uncollapsed`): a
circulation at reward 0 that changes no objective and makes every state of the
class reachable from its entries. Summed over a class, the right-hand
side is the class's *z* (the first programme's flow row), and the inside choices
make a class strongly connected, so the programme is feasible (up to the first
one's tolerance, which is absorbed at the class's largest entry).

Per product state the flows out of it -- *y* and *w* of its choices, and its
stay -- are then the expected numbers of times each is done, and the strategy
that does each with probability proportional to its flow realises them
(Etessami, Kwiatkowska, Vardi & Yannakakis, LMCS 2008, Thm. 3.2; Puterman 1994,
Thm. 6.9.1). Whatever this module computes is checked on the induced chain
(:mod:`~veribattery.checker.mdp.multi_strategy_check`) before it is shown.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any, Literal

import numpy as np
import scipy.sparse as sp

from veribattery._types import BoolArray, FloatArray, IntArray
from veribattery.checker.mdp.components import end_components
from veribattery.checker.mdp.graph import ChoiceGraph
from veribattery.checker.mdp.model import MDP
from veribattery.checker.mdp.multi import (
    Constraint,
    Quantity,
    Reach,
    Total,
    _margin_rows,
    _method,
    _Product,
    _Programme,
)

__all__ = ["Flows", "WitnessFailed", "uncollapsed", "witness_flows"]


class WitnessFailed(Exception):
    """No witness flows could be found (the message says why)."""


@dataclass(frozen=True, slots=True)
class Flows:
    """Expected uses of each choice of the product, and where runs stop.

    :param product: the MDP times the visited bits (:class:`~.multi._Product`).
    :param uses: per product choice, its expected number of uses (>= 0).
    :param stays: per product state, the probability of stopping there (staying in
        its resting class forever); 0 outside the resting classes.
    :param resting: per product state, its resting class, or -1.
    :param inside: per product choice, whether it moves inside its resting class (free,
        all its mass staying there): the choices of the uncollapsing programme.
    :param stop_choice: per product state, a choice that keeps a run inside its resting
        class (the one taken once stopped), or -1 outside the resting classes.
    :param targets: the number of visited bits (reachability quantities).
    :param optimum: the programme's optimum of the optimised quantity (None for
        achievability).
    """

    product: _Product
    uses: FloatArray
    stays: FloatArray
    resting: IntArray
    inside: BoolArray
    stop_choice: IntArray
    targets: int
    optimum: float | None = None

    @property
    def out_of(self) -> FloatArray:
        """Per product state, the flow out of it: its choices' uses and its stay."""
        pm = self.product.mdp
        return np.bincount(pm.choice_owner, weights=self.uses,
                           minlength=pm.num_states) + self.stays


def witness_flows(mdp: MDP, quantities: Sequence[Quantity],
                  constraints: Sequence[Constraint], optimised: Quantity | None,
                  objective: Literal["min", "max"]) -> Flows:
    """The flows of a strategy that meets *constraints* (and optimises *optimised*
    in direction *objective*, if given): the check's programme, solved for its
    solution, then uncollapsed (see the module's description).

    :param quantities: every quantity of the query, in the order the check gave them
        (the visited bits are numbered by the reachability quantities' order).
    :raises WitnessFailed: the programme has no solution (no strategy meets the
        constraints, or the optimum is unbounded).
    """
    programme = _Programme.of(mdp, quantities)
    x = _solution(programme, constraints, optimised, objective)
    pm = programme.product.mdp
    resting, inside = _resting(programme, quantities)
    uses = np.zeros(pm.num_choices)
    uses[programme.kept] = np.maximum(x[: programme.kept.size], 0.0)
    stop = np.full(pm.num_states, -1, dtype=np.int64)
    marked = np.where(inside, np.arange(pm.num_choices), pm.num_choices)
    first = np.minimum.reduceat(marked, pm.row_groups[:-1])
    stop[resting >= 0] = first[resting >= 0]
    targets = sum(isinstance(q, Reach) for q in quantities)
    optimum = None if optimised is None else float(programme.forms[id(optimised)] @ x)
    kept_only = Flows(programme.product, uses, np.zeros(pm.num_states), resting, inside,
                      stop, targets, optimum)
    return uncollapsed(kept_only, spread=False)


def uncollapsed(flows: Flows, *, spread: bool) -> Flows:
    """*flows* with the uses of the inside choices and the stays solved anew.

    :param spread: give every inside choice of a class that runs enter a use of at
        least a thousandth of the class's entries over its number of inside choices.
        Such uses circulate at reward 0 inside the class and change no objective,
        but make every state of the class reachable from where runs enter it -- which
        a paying choice the programme uses inside the class needs, when the plain
        solution stays at the entry (a circulation no run feeds).
    """
    pm = flows.product.mdp
    uses = np.where(flows.inside, 0.0, flows.uses)
    inflow = np.asarray(pm.transitions.T @ uses, dtype=np.float64)
    inflow[flows.product.initial] += 1.0
    floor = _floors(flows, inflow) if spread else np.zeros(int(flows.inside.sum()))
    w, stays = _inside_flows(pm, flows.resting, flows.inside, inflow, uses, floor)
    uses[flows.inside] = w
    return replace(flows, uses=uses, stays=stays)


def _floors(flows: Flows, inflow: FloatArray) -> FloatArray:
    """Per inside choice, the least use :func:`uncollapsed` gives it when spreading."""
    pm = flows.product.mdp
    count = int(flows.resting.max(initial=-1)) + 1
    members = flows.resting >= 0
    entries = np.bincount(flows.resting[members], weights=inflow[members], minlength=count)
    owner_class = flows.resting[pm.choice_owner[flows.inside]]
    choices = np.bincount(owner_class, minlength=count)
    return np.asarray(1e-3 * entries[owner_class] / choices[owner_class], dtype=np.float64)


def _solution(programme: _Programme, constraints: Sequence[Constraint],
              optimised: Quantity | None, objective: Literal["min", "max"]) -> FloatArray:
    """The programme's solution: the optimum of *optimised*, or, for achievability,
    the strategy with the largest margin (as :func:`~.multi.multi_margin` finds it:
    the one furthest inside its bounds)."""
    if optimised is None:
        found = _margin_solution(programme, constraints)
    else:
        found = _optimum_solution(programme, constraints, optimised, objective)
    if found.status == 3:
        raise WitnessFailed("the optimum is unbounded: no strategy attains it")
    if found.status != 0:
        raise WitnessFailed(f"the linear programme found no strategy ({found.message})")
    return np.asarray(found.x[: programme.flow.shape[1]], dtype=np.float64)


def _margin_solution(programme: _Programme, constraints: Sequence[Constraint]) -> Any:
    """HiGHS's answer to :meth:`~.multi._Programme.margin`'s programme."""
    from scipy.optimize import linprog  # HiGHS: only for multi-objective queries

    size = programme.flow.shape[1]
    rows, bounds = _margin_rows(programme, constraints)
    cost = np.zeros(size + 1)
    cost[-1] = -1.0
    flow = sp.hstack([programme.flow, sp.csr_matrix((programme.flow.shape[0], 1))])
    return linprog(cost, A_ub=rows if len(constraints) else None,
                   b_ub=bounds if len(constraints) else None, A_eq=sp.csr_matrix(flow),
                   b_eq=programme.initial, bounds=[(0, None)] * size + [(None, 1.0)],
                   method=_method(size + 1))


def _optimum_solution(programme: _Programme, constraints: Sequence[Constraint],
                      optimised: Quantity, objective: Literal["min", "max"]) -> Any:
    """HiGHS's answer to :meth:`~.multi._Programme.solve`'s programme."""
    from scipy.optimize import linprog  # HiGHS: only for multi-objective queries

    signs = [-1.0 if c.relation in (">=", ">") else 1.0 for c in constraints]
    rows = np.array([sign * programme.forms[id(c.quantity)]
                     for sign, c in zip(signs, constraints, strict=True)])
    bounds = np.array([sign * c.bound for sign, c in zip(signs, constraints, strict=True)])
    cost = programme.forms[id(optimised)] * (-1.0 if objective == "max" else 1.0)
    return linprog(cost, A_ub=rows if len(constraints) else None,
                   b_ub=bounds if len(constraints) else None, A_eq=programme.flow,
                   b_eq=programme.initial, bounds=(0, None),
                   method=_method(programme.flow.shape[1]))


def _resting(programme: _Programme,
             quantities: Sequence[Quantity]) -> tuple[IntArray, BoolArray]:
    """Per product state its resting class (as the programme collapsed them), and per
    product choice whether it moves inside a resting class (a variable of neither
    programme's first part: free, and all its mass stays in the class)."""
    pm = programme.product.mdp
    original = pm.states[:, 0] if pm.states is not None else np.arange(pm.num_choices)
    free = np.ones(pm.num_choices, dtype=bool)
    for quantity in quantities:
        if isinstance(quantity, Total):
            free &= np.asarray(quantity.rewards, dtype=np.float64)[original] == 0
    graph = ChoiceGraph.of(pm.transitions, pm.choice_owner)
    resting = end_components(graph, np.ones(pm.num_states, dtype=bool), free).component
    inside = np.ones(pm.num_choices, dtype=bool)
    inside[programme.kept] = False
    inside &= resting[pm.choice_owner] >= 0
    return resting, inside


def _inside_flows(pm: MDP, resting: IntArray, inside: BoolArray, inflow: FloatArray,
                  uses: FloatArray, floor: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The inside choices' uses (each at least its *floor*) and the stays, per state of
    the resting classes (the second programme of the module's description)."""
    from scipy.optimize import linprog  # HiGHS: only for multi-objective queries

    states = np.flatnonzero(resting >= 0)
    stays = np.zeros(pm.num_states)
    choices = np.flatnonzero(inside)
    if states.size == 0:
        return np.zeros(0), stays
    demand = inflow - np.bincount(pm.choice_owner, weights=uses, minlength=pm.num_states)
    demand = _absorbed(demand, resting)[states]
    position = np.full(pm.num_states, -1, dtype=np.int64)
    position[states] = np.arange(states.size)
    rows = sp.csr_matrix(pm.transitions[choices])
    into = sp.csr_matrix((rows.data, position[rows.indices], rows.indptr),
                         shape=(choices.size, states.size))
    out = sp.csr_matrix((np.ones(choices.size),
                         (np.arange(choices.size), position[pm.choice_owner[choices]])),
                        shape=(choices.size, states.size))
    balance = sp.hstack([(out - into).T, sp.identity(states.size)])
    cost = np.concatenate([np.ones(choices.size), np.zeros(states.size)])
    lower = np.concatenate([floor, np.zeros(states.size)])
    found = linprog(cost, A_eq=sp.csr_matrix(balance), b_eq=demand,
                    bounds=np.column_stack([lower, np.full(cost.size, np.inf)]),
                    method=_method(cost.size))
    if found.status != 0:
        raise WitnessFailed("no flow inside the zero-reward end components matches the "
                            f"programme's ({found.message})")
    x = np.maximum(np.asarray(found.x, dtype=np.float64), 0.0)
    stays[states] = x[choices.size:]
    return x[: choices.size], stays


def _absorbed(demand: FloatArray, resting: IntArray) -> FloatArray:
    """*demand* with each resting class's total made nonnegative: a class whose flows
    sum to slightly below 0 (the first programme's tolerance) gets the shortfall at
    its state of largest demand, where it changes the flows least in relative terms."""
    fixed = demand.copy()
    members = resting >= 0
    count = int(resting.max(initial=-1)) + 1
    totals = np.bincount(resting[members], weights=demand[members], minlength=count)
    for cls in np.flatnonzero(totals < 0):
        states = np.flatnonzero(resting == cls)
        fixed[states[np.argmax(demand[states])]] -= totals[cls]
    return fixed

