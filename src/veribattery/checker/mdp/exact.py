"""Exact optimal values: policy iteration in rationals, optimality verified exactly.

The qualitative pre-pass and the equations are those of the float engine (graph
searches do not depend on the arithmetic); the transition probabilities and
rewards are then read as rationals (:class:`gmpy2.mpq`). Policy iteration starts
from the float engine's strategy, evaluates each strategy exactly (its induced
system solved SCC by SCC by :mod:`~veribattery.checker.exact.solve`) and switches
every class whose best row is *strictly* better, compared exactly. It stops when
no row is better: then ``B(x) = x`` holds exactly, and since the pre-pass left
``B`` with a single fixed point (``docs/mdp-numerics.md``), ``x`` is the optimal
value and the final strategy is optimal -- verified, not assumed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from gmpy2 import mpq

from veribattery._types import BoolArray, FloatArray
from veribattery.checker.mdp.cosafe import trapped_entries
from veribattery.checker.mdp.graph import ChoiceGraph
from veribattery.checker.mdp.model import MDP
from veribattery.checker.mdp.optimum import Equations, Problem, approximate
from veribattery.checker.mdp.rational import (
    ObjectArray,
    RationalSystem,
    exact_policy_iteration,
    exact_probabilities,
)
from veribattery.checker.mdp.reach import reach_problem
from veribattery.checker.mdp.rewards import reach_reward_problem, total_reward_problem
from veribattery.checker.mdp.strategy import Strategy, lifted
from veribattery.checker.mdp.system import Objective

__all__ = [
    "ExactMdpResult",
    "exact_probabilities",
    "exact_reach_probability",
    "exact_reach_reward",
    "exact_total_reward",
    "exact_until_reward",
]

_ZERO = mpq(0)
_ONE = mpq(1)


@dataclass(frozen=True, slots=True)
class ExactMdpResult:
    """Exact optimal values and a strategy verified to attain them.

    :param values: per state, the optimal value as an ``mpq`` (0 where *infinite*).
    :param infinite: the states whose optimal expected reward is infinite.
    :param strategy: a memoryless deterministic optimal strategy.
    """

    values: ObjectArray
    infinite: BoolArray
    strategy: Strategy


def exact_reach_probability(mdp: MDP, target: BoolArray, *, objective: Objective,
                            remain: BoolArray | None = None,
                            probabilities: ObjectArray | None = None) -> ExactMdpResult:
    """Pmin or Pmax of ``remain U target`` in rationals.

    :param probabilities: the exact value of each stored entry of ``mdp.transitions``
        (CSR data order; positive exactly where the float entry is), or None for the
        float entries read exactly.
    """
    graph = ChoiceGraph.of(mdp.transitions, mdp.choice_owner)
    problem = reach_problem(mdp, graph, target, objective, remain)
    return _solved(mdp, graph, problem, probabilities, None)


def exact_reach_reward(mdp: MDP, rewards: ObjectArray, target: BoolArray, *,
                       objective: Objective,
                       probabilities: ObjectArray | None = None) -> ExactMdpResult:
    """Rmin or Rmax ``[ F target ]`` in rationals.

    :param rewards: per choice, the exact reward of one step taken with it (``mpq``).
    """
    graph = ChoiceGraph.of(mdp.transitions, mdp.choice_owner)
    problem = reach_reward_problem(mdp, graph, _floats(rewards), target, objective)
    return _solved(mdp, graph, problem, probabilities, rewards)


def exact_until_reward(mdp: MDP, rewards: ObjectArray, remain: BoolArray, target: BoolArray,
                       *, objective: Objective, probabilities: ObjectArray) -> ExactMdpResult:
    """Rmin or Rmax of the co-safe ``remain U target`` in rationals: ``R [ F target ]``
    with the states of neither trapped, as the float engine solves it
    (:func:`~veribattery.checker.mdp.cosafe.trapped_entries`), the kept entries' exact
    probabilities carried over."""
    trapped, old, new = trapped_entries(mdp, ~remain & ~target)
    exact = np.full(trapped.transitions.nnz, _ONE, dtype=object)
    exact[new] = probabilities[old]
    return exact_reach_reward(trapped, rewards, target, objective=objective,
                              probabilities=exact)


def exact_total_reward(mdp: MDP, rewards: ObjectArray, *, objective: Objective,
                       probabilities: ObjectArray | None = None) -> ExactMdpResult:
    """Rmin or Rmax ``[ C ]`` in rationals (*rewards* per choice, ``mpq``)."""
    graph = ChoiceGraph.of(mdp.transitions, mdp.choice_owner)
    problem = total_reward_problem(mdp, graph, _floats(rewards), objective)
    return _solved(mdp, graph, problem, probabilities, rewards)


def _floats(rewards: ObjectArray) -> FloatArray:
    """The rewards in floating point for the pre-pass, keeping which are positive."""
    floats = np.array([float(r) for r in rewards], dtype=np.float64)
    positive = np.array([r > 0 for r in rewards], dtype=bool)
    floats[positive & (floats == 0)] = np.nextafter(0.0, 1.0)
    return floats


def _solved(mdp: MDP, graph: ChoiceGraph, problem: Problem, probabilities: ObjectArray | None,
            rewards: ObjectArray | None) -> ExactMdpResult:
    infinite = (problem.known == np.inf) & ~problem.unknown
    values = np.array([_ZERO if v == np.inf else mpq(float(v)) for v in problem.known],
                      dtype=object)
    if not problem.unknown.any():
        return ExactMdpResult(values, infinite, Strategy(problem.choices))
    exact = exact_probabilities(mdp) if probabilities is None else probabilities
    found = approximate(mdp, Equations.of(mdp, problem),
                        None if rewards is None else _floats(rewards))
    rational = RationalSystem.of(found.system, exact, values[found.system.known_states], rewards)
    rows, x = exact_policy_iteration(rational, problem.objective, found.rows)
    class_of = problem.classes
    values[class_of >= 0] = x[class_of[class_of >= 0]]
    strategy = lifted(mdp, graph, found.system, rows, problem.components, problem.choices)
    return ExactMdpResult(values, infinite, Strategy(strategy))


