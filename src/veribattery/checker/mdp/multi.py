"""Multi-objective queries over reachability probabilities and expected total rewards.

``multi(P>=0.9 [ F a ], R{"r"}<=5 [ C ])`` asks whether one strategy meets every
bound at once; ``multi(R{"r"}min=? [ C ], P>=0.99 [ F a ])`` for the best value of
one objective among the strategies that meet the others. Optimal strategies may
need memory and randomisation (Etessami, Kwiatkowska, Vardi & Yannakakis, LMCS
2008; Forejt, Kwiatkowska, Norman, Parker & Qu, TACAS 2011). The method is
theirs:

1. the product of the MDP with one bit per reachability target, set once the
   target has been visited (so that "visited T" becomes a property of states);
2. the end components of the product that use only choices of reward 0 in every
   reward objective are collapsed; each gets a *stay* option (remain there forever);
3. a linear programme over occupation measures: ``y_a >= 0`` the expected number of
   times choice *a* is taken, ``z_c >= 0`` the probability of staying in class *c*
   forever, with flow conservation per class. Then
   ``P(F T_i) = sum of z_c over the classes with bit i`` and
   ``E[total reward] = sum_a y_a r(a)``.

Supported: reachability and total-reward objectives, each with a lower or an
upper bound, or minimised or maximised (a maximised reward that an end component
can make as large as wished is ``inf``). As in Storm, only strategies whose total
rewards are finite are considered (with reward objectives present, runs end in the
collapsed zero-reward end components). Strict bounds are read as non-strict, as
PRISM does. The LP is solved in floating point by HiGHS (``scipy.optimize.linprog``):
these results are *not* certified (HiGHS's feasibility tolerance is 1e-7).
Pareto queries are not supported.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
import scipy.sparse as sp

from veribattery._types import BoolArray, FloatArray, IntArray
from veribattery._unique import distinct
from veribattery.checker.mdp.components import end_components
from veribattery.checker.mdp.graph import ChoiceGraph
from veribattery.checker.mdp.model import MDP
from veribattery.checker.mdp.multi_exact import exact_witness
from veribattery.checker.mdp.system import Objective

__all__ = [
    "LP_TOLERANCE", "Constraint", "Margin", "MultiResult", "Quantity", "Reach", "Total",
    "multi_achievable", "multi_margin", "multi_optimum",
]


@dataclass(frozen=True, slots=True)
class Reach:
    """The probability of eventually visiting *target*."""

    target: BoolArray


@dataclass(frozen=True, slots=True)
class Total:
    """The expected total reward, *rewards* per choice (nonnegative)."""

    rewards: FloatArray


Quantity = Reach | Total


@dataclass(frozen=True, slots=True)
class Constraint:
    """``quantity relation bound``, e.g. ``Constraint(Reach(goal), ">=", 0.9)``."""

    quantity: Quantity
    relation: Literal[">=", "<=", ">", "<"]
    bound: float


@dataclass(frozen=True, slots=True)
class MultiResult:
    """The answer of a multi-objective query at the initial state.

    :param achievable: whether some strategy meets every constraint.
    :param value: the optimum of a numerical query (None for achievability, or when
        no strategy meets the constraints).
    :param occupation: per choice of the product kept in the programme, its expected
        number of uses under a witness strategy (empty when none).
    """

    achievable: bool
    value: float | None
    occupation: FloatArray


def multi_achievable(mdp: MDP, constraints: Sequence[Constraint]) -> MultiResult:
    """Whether one strategy meets every constraint from the (single) initial state."""
    programme = _Programme.of(mdp, [c.quantity for c in constraints])
    return programme.solve(constraints, None, "max")


@dataclass(frozen=True, slots=True)
class Margin:
    """How far inside its constraints the best strategy can be (:func:`multi_margin`).

    :param value: the largest *d* (at most 1) such that some strategy meets every
        constraint with ``d * max(1, |bound|)`` to spare; negative when no strategy
        meets them all (by that much, scaled alike); ``-inf`` when no strategy has
        finite total rewards. In floating point: decisive only beyond
        :data:`LP_TOLERANCE`.
    :param witnessed: whether the programme's vertex, solved again in exact arithmetic,
        meets every constraint (:mod:`~veribattery.checker.mdp.multi_exact`): then a
        strategy provably does. Tried for every *value* not below ``-LP_TOLERANCE``.
    """

    value: float
    witnessed: bool = False


#: Relative error assumed of a value read off the linear programme (HiGHS's primal
#: and dual feasibility tolerances are 1e-7; a factor of ten for the scaling).
LP_TOLERANCE = 1e-6


def multi_margin(mdp: MDP, constraints: Sequence[Constraint]) -> Margin:
    """How far inside its constraints the best strategy can be (:class:`Margin`).

    Achievability is ``margin >= 0``; a margin within :data:`LP_TOLERANCE` of 0
    decides it only when an exact witness is found.
    """
    programme = _Programme.of(mdp, [c.quantity for c in constraints])
    return programme.margin(constraints)


def multi_optimum(mdp: MDP, quantity: Quantity, objective: Objective,
                  constraints: Sequence[Constraint]) -> MultiResult:
    """The minimum or maximum of *quantity* over the strategies that meet *constraints*."""
    programme = _Programme.of(mdp, [quantity, *(c.quantity for c in constraints)])
    return programme.solve(constraints, quantity, objective)


@dataclass(frozen=True, slots=True)
class _Product:
    """The MDP times one visited bit per target: state ``s * 2**k + bits``."""

    mdp: MDP
    codes: IntArray  # per product state, its code (sorted)
    initial: int

    @classmethod
    def of(cls, mdp: MDP, targets: Sequence[BoolArray]) -> _Product:
        width = 1 << len(targets)
        flags = _flags(mdp.num_states, targets)
        if mdp.initial.size != 1:
            raise ValueError("multi-objective queries need a single initial state")
        start = np.array([int(mdp.initial[0]) * width + int(flags[mdp.initial[0]])])
        codes = _reachable_codes(mdp, start, flags, width)
        product = _product_mdp(mdp, codes, flags, width)
        return cls(product, codes, int(np.searchsorted(codes, start[0])))

    def bits(self, index: int) -> BoolArray:
        """Per product state, whether target *index* has been visited."""
        return np.asarray(self.codes & (1 << index) != 0, dtype=bool)


def _flags(n: int, targets: Sequence[BoolArray]) -> IntArray:
    flags = np.zeros(n, dtype=np.int64)
    for i, target in enumerate(targets):
        flags |= target.astype(np.int64) << i
    return flags


#: Largest code space searched with a visited mask (one byte per code).
_DENSE_CODES = 50_000_000


def _reachable_codes(mdp: MDP, start: IntArray, flags: IntArray, width: int) -> IntArray:
    """The product states reachable from *start*, sorted: breadth first, with a
    visited mask over all codes when it fits (each layer then costs its own size,
    not the size of everything found so far)."""
    if mdp.num_states * width > _DENSE_CODES:
        codes, frontier = start, start
        while frontier.size:
            found = _successor_codes(mdp, frontier, flags, width)
            frontier = np.setdiff1d(found, codes)
            codes = np.union1d(codes, frontier)
        return codes
    seen = np.zeros(mdp.num_states * width, dtype=bool)
    seen[start] = True
    frontier = start
    while frontier.size:
        found = _successor_codes(mdp, frontier, flags, width)
        frontier = found[~seen[found]]
        seen[frontier] = True
    return np.flatnonzero(seen).astype(np.int64)


def _successor_codes(mdp: MDP, codes: IntArray, flags: IntArray, width: int) -> IntArray:
    states, bits = codes // width, codes % width
    rows = mdp.transitions[_choices_of(mdp, states)]
    owner = np.repeat(np.arange(states.size), np.diff(mdp.row_groups)[states])
    entry_owner = np.repeat(owner, np.diff(rows.indptr))
    successors = rows.indices.astype(np.int64)
    return distinct(successors * width + (bits[entry_owner] | flags[successors]))


def _choices_of(mdp: MDP, states: IntArray) -> IntArray:
    starts = mdp.row_groups[states]
    sizes = np.diff(mdp.row_groups)[states]
    offsets = np.arange(int(sizes.sum())) - np.repeat(np.cumsum(sizes) - sizes, sizes)
    return np.asarray(np.repeat(starts, sizes) + offsets, dtype=np.int64)


def _product_mdp(mdp: MDP, codes: IntArray, flags: IntArray, width: int) -> MDP:
    states, bits = codes // width, codes % width
    choices = _choices_of(mdp, states)
    rows = sp.csr_matrix(mdp.transitions[choices])
    owner = np.repeat(np.arange(states.size), np.diff(mdp.row_groups)[states])
    entry_owner = np.repeat(owner, np.diff(rows.indptr))
    successors = rows.indices.astype(np.int64)
    columns = np.searchsorted(codes, successors * width + (bits[entry_owner] | flags[successors]))
    transitions = sp.csr_matrix((rows.data, columns, rows.indptr),
                                shape=(choices.size, codes.size))
    groups = np.concatenate([[0], np.cumsum(np.diff(mdp.row_groups)[states])])
    assert mdp.choice_actions is not None
    return MDP(transitions, groups, np.array([0]), choice_actions=mdp.choice_actions[choices],
               actions=mdp.actions, rewards=(), states=choices[:, None])


@dataclass(frozen=True, slots=True)
class _Programme:
    """The flow constraints of the collapsed product and each quantity as a linear form."""

    product: _Product
    flow: sp.csr_matrix  # classes x (kept choices + stay options)
    initial: FloatArray
    forms: dict[int, FloatArray]  # id(quantity) -> coefficients over the variables
    kept: IntArray  # product choices that are variables

    @classmethod
    def of(cls, mdp: MDP, quantities: Sequence[Quantity]) -> _Programme:
        targets = [q.target for q in quantities if isinstance(q, Reach)]
        product = _Product.of(mdp, targets)
        pm = product.mdp
        original = pm.states[:, 0] if pm.states is not None else np.arange(pm.num_choices)
        graph = ChoiceGraph.of(pm.transitions, pm.choice_owner)
        rewards = [np.asarray(q.rewards, dtype=np.float64)[original]
                   for q in quantities if isinstance(q, Total)]
        free = np.ones(pm.num_choices, dtype=bool)
        for reward in rewards:
            free &= reward == 0
        resting = end_components(graph, np.ones(pm.num_states, dtype=bool), free)
        return _assembled(product, graph, resting.component, quantities, rewards)

    def solve(self, constraints: Sequence[Constraint], quantity: Quantity | None,
              objective: Objective) -> MultiResult:
        rows, bounds = [], []
        for constraint in constraints:
            form = self.forms[id(constraint.quantity)]
            sign = -1.0 if constraint.relation in (">=", ">") else 1.0
            rows.append(sign * form)
            bounds.append(sign * constraint.bound)
        cost = np.zeros(self.flow.shape[1])
        if quantity is not None:
            cost = self.forms[id(quantity)] * (-1.0 if objective == "max" else 1.0)
        from scipy.optimize import linprog  # HiGHS: only for multi-objective queries

        found = linprog(cost, A_ub=np.array(rows) if rows else None,
                        b_ub=np.array(bounds) if rows else None, A_eq=self.flow,
                        b_eq=self.initial, bounds=(0, None), method=_method(cost.size))
        if found.status == 2:
            return MultiResult(False, None, np.zeros(0))
        if found.status == 3 and quantity is not None:  # unbounded: a reward made as
            return MultiResult(True, np.inf, np.zeros(0))  # large as wished
        if found.status != 0:
            raise ValueError(f"the linear programme failed: {found.message}")
        value = None if quantity is None else float(self.forms[id(quantity)] @ found.x)
        return MultiResult(True, value, np.asarray(found.x[: self.kept.size]))

    def margin(self, constraints: Sequence[Constraint]) -> Margin:
        """The programme of :func:`multi_margin`: maximise the margin, a free variable
        capped at 1, next to the flow variables."""
        from scipy.optimize import linprog  # HiGHS: only for multi-objective queries

        size = self.flow.shape[1]
        rows, bounds = _margin_rows(self, constraints)
        cost = np.zeros(size + 1)
        cost[-1] = -1.0
        flow = sp.csr_matrix(sp.hstack([self.flow, sp.csr_matrix((self.flow.shape[0], 1))]))
        found = linprog(cost, A_ub=rows if len(constraints) else None,
                        b_ub=bounds if len(constraints) else None, A_eq=flow,
                        b_eq=self.initial, bounds=[(0, None)] * size + [(None, 1.0)],
                        method=_method(size + 1))
        if found.status == 2:  # no strategy with finite total rewards at all
            return Margin(-np.inf)
        if found.status != 0:
            raise ValueError(f"the linear programme failed: {found.message}")
        value = float(found.x[-1])
        if value < -LP_TOLERANCE:  # a witness of "no" would be a dual certificate
            return Margin(value)
        # The vertex of this programme, margin included (capped at 1: one row more),
        # solved again exactly; a margin that comes out >= 0 proves achievability.
        cap = np.zeros((1, size + 1))
        cap[0, -1] = 1.0
        return Margin(value, exact_witness(flow, self.initial, np.vstack([rows, cap]),
                                           np.append(bounds, 1.0), found.x, LP_TOLERANCE))


#: Programmes with more variables than this go to HiGHS's interior-point method
#: (with crossover to a vertex): PRISM's consensus_multi5 (382k variables) takes it
#: about 35 s of CPU, where the dual simplex had not finished after 10 minutes.
INTERIOR_POINT_SIZE = 20_000


def _method(size: int) -> str:
    """HiGHS's simplex for small programmes, its interior-point method for large ones."""
    return "highs-ipm" if size > INTERIOR_POINT_SIZE else "highs"


def _margin_rows(programme: _Programme,
                 constraints: Sequence[Constraint]) -> tuple[FloatArray, FloatArray]:
    """``form <= bound`` per constraint (``>=`` negated), plus the margin's column:
    each row asks for ``max(1, |bound|)`` times the margin to spare."""
    rows, bounds = [], []
    for constraint in constraints:
        sign = -1.0 if constraint.relation in (">=", ">") else 1.0
        scale = max(1.0, abs(constraint.bound))
        rows.append(np.append(sign * programme.forms[id(constraint.quantity)], scale))
        bounds.append(sign * constraint.bound)
    return np.array(rows), np.array(bounds)


def _assembled(product: _Product, graph: ChoiceGraph, component: IntArray,
               quantities: Sequence[Quantity], rewards: Sequence[FloatArray]) -> _Programme:
    """Variables: the choices kept (:func:`_kept`), then one stay option per resting
    class; one flow row per class: uses out of it + staying - uses into it = start."""
    pm = product.mdp
    count = int(component.max(initial=-1)) + 1
    class_of = component.copy()
    class_of[component < 0] = count + np.arange(int(np.sum(component < 0)))
    classes = int(class_of.max(initial=-1)) + 1
    owner_class = class_of[pm.choice_owner]
    kept = _kept(graph, class_of, owner_class, rewards)
    entering = sp.csr_matrix((pm.transitions.data, class_of[pm.transitions.indices],
                              pm.transitions.indptr), shape=(pm.num_choices, classes))
    out = sp.csr_matrix((np.ones(kept.size), (owner_class[kept], np.arange(kept.size))),
                        shape=(classes, kept.size))
    stay = sp.csr_matrix((np.ones(count), (np.arange(count), np.arange(count))),
                         shape=(classes, count))
    flow = sp.csr_matrix(sp.hstack([out - sp.csr_matrix(entering[kept].T), stay]))
    initial = np.zeros(classes)
    initial[class_of[product.initial]] = 1.0
    return _Programme(product, flow, initial,
                      _forms(product, component, quantities, rewards, kept), kept)


def _kept(graph: ChoiceGraph, class_of: IntArray, owner_class: IntArray,
          rewards: Sequence[FloatArray]) -> IntArray:
    """The choices that are variables. A free choice that keeps all its mass in its
    class only moves inside it (what the stay option stands for): dropped. A paying one
    is kept: looping on it collects as much reward as wished before leaving."""
    sizes = np.diff(graph.successor_ptr)
    outside = class_of[graph.successors] != np.repeat(owner_class, sizes)
    leaving = np.logical_or.reduceat(outside, graph.successor_ptr[:-1])
    for reward in rewards:
        leaving |= reward > 0
    return np.flatnonzero(leaving)


def _forms(product: _Product, component: IntArray, quantities: Sequence[Quantity],
           rewards: Sequence[FloatArray], kept: IntArray) -> dict[int, FloatArray]:
    """Each quantity as coefficients over the variables (keyed by the quantity's id):
    a reward on the uses, a probability on staying where its target has been visited."""
    count = int(component.max(initial=-1)) + 1
    forms: dict[int, FloatArray] = {}
    totals = iter(rewards)
    targets = 0
    for quantity in quantities:
        if isinstance(quantity, Total):
            forms[id(quantity)] = np.concatenate([next(totals)[kept], np.zeros(count)])
            continue
        visited = product.bits(targets) & (component >= 0)
        targets += 1
        reached = np.zeros(count)
        reached[component[visited]] = 1.0
        forms[id(quantity)] = np.concatenate([np.zeros(kept.size), reached])
    return forms
