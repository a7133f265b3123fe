"""Exact optimal values: policy iteration in rationals, optimality verified exactly.

The qualitative pre-pass and the equations are those of the float engine (graph
searches do not depend on the arithmetic); the transition probabilities and
rewards are then read as rationals (:class:`gmpy2.mpq`). Policy iteration starts
from the float engine's strategy, evaluates each strategy exactly (its induced
system solved SCC by SCC by :mod:`~veribattery.checker.exact_solve`) and switches
every class whose best row is *strictly* better, compared exactly. It stops when
no row is better: then ``B(x) = x`` holds exactly, and since the pre-pass left
``B`` with a single fixed point (``docs/mdp-numerics.md``), ``x`` is the optimal
value and the final strategy is optimal -- verified, not assumed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from gmpy2 import mpq

from veribattery._types import BoolArray, FloatArray, IntArray
from veribattery.checker.exact_solve import ExactSystem
from veribattery.checker.exact_solve import solve as solve_linear
from veribattery.checker.mdp.graph import ChoiceGraph
from veribattery.checker.mdp.model import MDP
from veribattery.checker.mdp.optimum import Problem, approximate
from veribattery.checker.mdp.reach import reach_problem
from veribattery.checker.mdp.rewards import reach_reward_problem, total_reward_problem
from veribattery.checker.mdp.strategy import Strategy, lifted
from veribattery.checker.mdp.system import ChoiceSystem, Objective

__all__ = [
    "ExactMdpResult",
    "exact_probabilities",
    "exact_reach_probability",
    "exact_reach_reward",
    "exact_total_reward",
]

#: One Python object (here :class:`gmpy2.mpq`) per entry.
ObjectArray = np.ndarray

_ZERO = mpq(0)


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


def exact_probabilities(mdp: MDP) -> ObjectArray:
    """The stored float64 probabilities as the rationals they are (CSR data order)."""
    return np.array([mpq(float(p)) for p in mdp.transitions.data], dtype=object)


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
    found = approximate(mdp, problem, None if rewards is None else _floats(rewards))
    rational = _Rational.of(found.system, exact, values, rewards)
    rows, x = _policy_iteration(rational, problem.objective, found.rows)
    class_of = problem.classes
    values[class_of >= 0] = x[class_of[class_of >= 0]]
    strategy = lifted(mdp, graph, found.system, rows, problem.components, problem.choices)
    return ExactMdpResult(values, infinite, Strategy(strategy))


@dataclass(frozen=True, slots=True)
class _Rational:
    """A :class:`ChoiceSystem` with exact entries, known values and offsets."""

    system: ChoiceSystem
    entries: ObjectArray  # per stored entry of system.off
    entry_row: IntArray
    leave: ObjectArray  # per row, the exact probability of leaving its class
    known: ObjectArray  # per known state of the system
    offset: ObjectArray  # per row

    @classmethod
    def of(cls, system: ChoiceSystem, probabilities: ObjectArray, values: ObjectArray,
           rewards: ObjectArray | None) -> _Rational:
        entries = probabilities[system.positions]
        entry_row = np.repeat(np.arange(system.off.shape[0]), np.diff(system.off.indptr))
        leave = np.add.reduceat(entries, system.off.indptr[:-1])
        offset = (np.full(system.choices.size, _ZERO, dtype=object) if rewards is None
                  else np.asarray(rewards, dtype=object)[system.choices])
        return cls(system, entries, entry_row, leave, values[system.known_states], offset)

    def images(self, x: ObjectArray) -> ObjectArray:
        """``G_a(x)`` of every row, exactly."""
        full = np.concatenate([x, self.known])
        products = self.entries * full[self.system.off.indices]
        sums = np.add.reduceat(products, self.system.off.indptr[:-1])
        return np.asarray((sums + self.offset) / self.leave, dtype=object)

    def evaluate(self, rows: IntArray) -> ObjectArray:
        """The exact values of the strategy *rows* (one row per class)."""
        size = self.system.size
        chosen = np.zeros(self.system.choices.size, dtype=bool)
        chosen[rows] = True
        local = np.full(self.system.choices.size, -1, dtype=np.int64)
        local[rows] = np.arange(size)
        picked = chosen[self.entry_row]
        columns = self.system.off.indices[picked]
        owner = local[self.entry_row[picked]]
        scaled = self.entries[picked] / self.leave[self.entry_row[picked]]
        inner = columns < size
        rhs = self.offset[rows] / self.leave[rows]
        np.add.at(rhs, owner[~inner], scaled[~inner] * self.known[columns[~inner] - size])
        linear = _merged(size, owner[inner], columns[inner], scaled[inner])
        return np.asarray(solve_linear(linear, rhs), dtype=object)


def _merged(size: int, rows: IntArray, columns: IntArray, values: ObjectArray) -> ExactSystem:
    """The entries with one (row, column) summed: a row of a collapsed class may enter
    another class through several of its states."""
    keys, inverse = np.unique(rows * size + columns, return_inverse=True)
    sums = np.full(keys.size, _ZERO, dtype=object)
    np.add.at(sums, inverse, values)
    return ExactSystem(size, keys // size, keys % size, sums)


def _policy_iteration(rational: _Rational, objective: Objective,
                      rows: IntArray) -> tuple[IntArray, ObjectArray]:
    """Exact policy iteration from *rows*: the optimal strategy and values."""
    system = rational.system
    starts = system.groups[:-1]
    reduce = np.maximum if objective == "max" else np.minimum
    while True:
        x = rational.evaluate(rows)
        images = rational.images(x)
        best = reduce.reduceat(images, starts)
        now = images[rows]
        better = (best > now) if objective == "max" else (best < now)
        better = np.asarray(better, dtype=bool)
        if not better.any():
            return rows, x
        first = _first_equal(images, best[system.row_class], starts, images.size)
        rows = np.where(better, first, rows)


def _first_equal(values: ObjectArray, best: ObjectArray, starts: IntArray, size: int) -> IntArray:
    """Per group, the first position whose value equals its group's *best*."""
    hits = np.asarray(values == best, dtype=bool)
    positions = np.where(hits, np.arange(size), size)
    return np.asarray(np.minimum.reduceat(positions, starts), dtype=np.int64)
