"""Weighted sums of one reachability probability and one expected total reward.

The two-objective queries of :mod:`~veribattery.checker.mdp.multi_front` are answered
by optimising ``E[R] + lam * (1 - P(F T))`` for weights ``lam >= 0`` (Forejt,
Kwiatkowska & Parker, ATVA 2012; Storm's ``pcaa`` engine). For a fixed *lam* this is
an ordinary expected-reward minimisation, solved and certified by the MDP engine.

The MDP it is solved on is the one of :mod:`~veribattery.checker.mdp.multi`'s
linear programme, made explicit: the product with the visited bit of *T*, where
every state of a zero-reward end component (a *resting* state: the strategies
counted end their runs in one) gets one more choice, *stop*, that moves to one of
two absorbing sinks -- *reached* if the bit is set, *missed* if not. Then, over
the strategies that reach a sink almost surely (those whose total reward is finite),
``P(F T)`` is the probability of the *reached* sink, and
``E[R] + lam (1 - P)`` is ``Rmin [ F sinks ]`` with reward *lam* on every stop into
*missed*. The zero-reward end components are what the reward pre-pass collapses, so
"staying forever" costs exactly the stop that ends the run there.

Each optimum comes with a memoryless deterministic strategy (the policy iteration's,
deterministic: ties between rows go to the first row of a state that attains the
optimum, :mod:`~veribattery.checker.mdp.solve`); its own point (P, E[R]) is then
evaluated, certified, on the MDP of its choices alone.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction

import numpy as np
import scipy.sparse as sp

from veribattery._types import BoolArray, FloatArray, IntArray
from veribattery.checker.mdp.attain import may_attain
from veribattery.checker.mdp.components import end_components
from veribattery.checker.mdp.graph import ChoiceGraph, reached_from
from veribattery.checker.mdp.model import MDP
from veribattery.checker.mdp.multi import Reach, Total, _Product
from veribattery.checker.mdp.optimum import Equations, Problem, solve_from
from veribattery.checker.mdp.reach import reach_probability
from veribattery.checker.mdp.rewards import reach_reward, reach_reward_problem
from veribattery.checker.mdp.strategy import Strategy

__all__ = ["Interval", "Point", "StoppingMdp", "WeightedOptimum", "down", "up"]


@dataclass(frozen=True, slots=True)
class Interval:
    """A certified enclosure ``lower <= exact <= upper`` and a point value inside."""

    value: float
    lower: float
    upper: float

    @property
    def error(self) -> float:
        """The largest distance from the value to an end of the interval."""
        return max(self.value - self.lower, self.upper - self.value)


@dataclass(frozen=True, slots=True)
class Point:
    """A deterministic strategy's own values at the initial state.

    :param p: its probability of reaching the target (and stopping there).
    :param total: its expected total reward (``inf``: it does not end almost surely).
    :param extras: its expected totals of the extra rewards, in the order given.
    :param strategy: per state of the stopping MDP, its choice.
    """

    p: Interval
    total: Interval
    extras: tuple[Interval, ...]
    strategy: Strategy


@dataclass(frozen=True, slots=True)
class WeightedOptimum:
    """``min E[R] + lam (1 - P)`` at the initial state, and the point of its strategy."""

    lam: float
    value: Interval
    point: Point
    rows: IntArray | None = None  # the strategy as rows of the problem's system


@dataclass(frozen=True, slots=True)
class StoppingMdp:
    """The product with the target's bit, a *stop* choice in every resting state, and
    the two sinks (the last two states: *reached*, then *missed*).

    :param mdp: that MDP (its initial state the product's).
    :param rewards: per choice, the total reward (0 on stops and sinks).
    :param missing: per choice, whether it is a stop into *missed* (it pays *lam*).
    :param extras: per choice, each extra total reward (0 on stops and sinks).
    """

    mdp: MDP
    graph: ChoiceGraph
    rewards: FloatArray
    missing: BoolArray
    extras: tuple[FloatArray, ...]

    @classmethod
    def of(cls, mdp: MDP, reach: Reach, total: Total,
           extras: Sequence[Total] = ()) -> StoppingMdp:
        """The stopping MDP of *mdp* for ``P(F reach.target)`` and ``E[total]``."""
        product = _Product.of(mdp, [reach.target])
        pm = product.mdp
        assert pm.states is not None  # the original choice of each product choice
        original = pm.states[:, 0]
        graph = ChoiceGraph.of(pm.transitions, pm.choice_owner)
        reward = np.asarray(total.rewards, dtype=np.float64)[original]
        resting = end_components(graph, np.ones(pm.num_states, dtype=bool), reward == 0)
        stopping, position, missing = _with_stops(pm, resting.component >= 0,
                                                  product.bits(0))
        choices = stopping.num_choices

        def lifted(values: FloatArray) -> FloatArray:
            out = np.zeros(choices)
            out[position] = np.asarray(values, dtype=np.float64)[original]
            return out

        return cls(stopping, ChoiceGraph.of(stopping.transitions, stopping.choice_owner),
                   lifted(total.rewards), missing, tuple(lifted(e.rewards) for e in extras))

    @property
    def sinks(self) -> BoolArray:
        """The two sinks."""
        mask = np.zeros(self.mdp.num_states, dtype=bool)
        mask[-2:] = True
        return mask

    @property
    def reached(self) -> BoolArray:
        """The sink of the runs that visited the target."""
        mask = np.zeros(self.mdp.num_states, dtype=bool)
        mask[-2] = True
        return mask

    def problem(self, lam: float) -> Problem:
        """The pre-pass of ``Rmin [ F sinks ]`` with weight *lam* (it depends only on
        which rewards are 0)."""
        return reach_reward_problem(self.mdp, self.graph, self.weighted(lam), self.sinks, "min")

    def weighted(self, lam: float) -> FloatArray:
        """Per choice, its reward plus *lam* on the stops into *missed*."""
        return np.asarray(self.rewards + lam * self.missing, dtype=np.float64)

    def optimum(self, lam: float, problem: Problem | None = None,
                start: IntArray | Strategy | None = None,
                equations: Equations | None = None) -> WeightedOptimum:
        """``min E[R] + lam (1 - P)``, certified, and the point of its strategy.

        :param start: where policy iteration starts: the rows of another weight's
            strategy on the same *problem* (the strategies of close weights are close),
            or a strategy over the states (:func:`~veribattery.checker.mdp.optimum.approximate`).
        :param equations: *problem*'s equations, if the caller keeps them.
        """
        rewards = self.weighted(lam)
        solved = solve_from(self.mdp, self.graph, problem or self.problem(lam), rewards, start,
                            equations=equations)
        found = solved.result
        first = int(self.mdp.initial[0])
        value = Interval(float(found.values[first]), float(found.lower[first]),
                         float(found.upper[first]))
        assert isinstance(found.strategy, Strategy)
        return WeightedOptimum(lam, value, self.point(found.strategy), solved.rows)

    def safest(self) -> tuple[Interval, Point]:
        """``Pmax`` of the *reached* sink (certified), and the lexicographic optimum of
        ``lam = inf``: among the choices that may attain ``Pmax`` (certified value not
        below the state's lower bound), the strategy of least ``E[R]``."""
        pmax = reach_probability(self.mdp, self.reached, objective="max")
        start = int(self.mdp.initial[0])
        best = Interval(float(pmax.values[start]), float(pmax.lower[start]),
                        float(pmax.upper[start]))
        keep = may_attain(self.mdp, pmax.upper, pmax.lower)
        assert isinstance(pmax.strategy, Strategy)
        keep[pmax.strategy.choices] = True
        restricted, rows = _restricted(self.mdp, keep)
        fastest = reach_reward(restricted, self.rewards[rows], self.sinks, objective="min")
        assert isinstance(fastest.strategy, Strategy)
        return best, self.point(Strategy(rows[fastest.strategy.choices]))

    def point(self, strategy: Strategy) -> Point:
        """The strategy's own P, E[R] and extras at the initial state, certified (on
        the chain of its choices over the states it reaches)."""
        chosen = sp.csr_matrix(self.mdp.transitions[strategy.choices])
        first = int(self.mdp.initial[0])
        reached = reached_from(chosen, first)
        size = reached.size
        own = MDP(sp.csr_matrix(chosen[reached][:, reached]), np.arange(size + 1),
                  np.searchsorted(reached, [first]))
        rows = strategy.choices[reached]
        start = int(own.initial[0])
        p = reach_probability(own, self.reached[reached], objective="max")

        def total(rewards: FloatArray) -> Interval:
            found = reach_reward(own, rewards[rows], self.sinks[reached], objective="min")
            return Interval(float(found.values[start]), float(found.lower[start]),
                            float(found.upper[start]))

        return Point(Interval(float(p.values[start]), float(p.lower[start]),
                              float(p.upper[start])),
                     total(self.rewards), tuple(total(e) for e in self.extras), strategy)


def _with_stops(pm: MDP, resting: BoolArray,
                visited: BoolArray) -> tuple[MDP, IntArray, BoolArray]:
    """*pm* with a stop choice last in every *resting* state (into the sink *reached*
    where *visited*, else *missed*) and the two sinks; per choice of *pm*, its row; per
    choice of the result, whether it is a stop into *missed*."""
    n = pm.num_states
    stops = np.flatnonzero(resting)
    counts = np.append(np.diff(pm.row_groups), [1, 1])
    counts[stops] += 1
    groups = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    owner = pm.choice_owner
    position = groups[owner] + (np.arange(pm.num_choices) - pm.row_groups[owner])
    lengths = np.diff(pm.transitions.indptr)
    rows = np.concatenate([np.repeat(position, lengths), groups[stops + 1] - 1,
                           groups[n:n + 2]])
    columns = np.concatenate([pm.transitions.indices,
                              np.where(visited[stops], n, n + 1), [n, n + 1]])
    data = np.concatenate([pm.transitions.data, np.ones(stops.size + 2)])
    transitions = sp.csr_matrix((data, (rows, columns)), shape=(int(groups[-1]), n + 2))
    missing = np.zeros(int(groups[-1]), dtype=bool)
    missing[groups[stops + 1] - 1] = ~visited[stops]
    return MDP(transitions, groups, pm.initial), position, missing


def _restricted(mdp: MDP, keep: BoolArray) -> tuple[MDP, IntArray]:
    """*mdp* with only the choices *keep* (each state keeps one at least), and per
    choice of the result, its row in *mdp*."""
    rows = np.flatnonzero(keep)
    counts = np.add.reduceat(keep.astype(np.int64), mdp.row_groups[:-1])
    groups = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    return MDP(sp.csr_matrix(mdp.transitions[rows]), groups, mdp.initial), rows


def down(q: Fraction) -> float:
    """The largest float not above *q*."""
    f = float(q)
    return float(np.nextafter(f, -np.inf)) if Fraction(f) > q else f


def up(q: Fraction) -> float:
    """The smallest float not below *q*."""
    f = float(q)
    return float(np.nextafter(f, np.inf)) if Fraction(f) < q else f
