"""Path probabilities and step-bounded values of an MDP in rationals: ``U`` within any
step interval, ``X``, and the exact Bellman rounds under ``C<=k`` and ``I=k``.

The rounds are those of the float engine (:mod:`~veribattery.checker.mdp.stepped`):
``x(s) = opt_a (o_a + P_a x)`` on the states that move, the others held at fixed
values -- each round exact, so *k* rounds give the exact finite-horizon optimum.
Unbounded ``U`` is exact policy iteration (:mod:`~veribattery.checker.mdp.exact`).
"""

from __future__ import annotations

import numpy as np
from gmpy2 import mpq

from veribattery._types import BoolArray
from veribattery.checker.formula.leaves import exact_step_bound
from veribattery.checker.mdp.exact import exact_reach_probability
from veribattery.checker.mdp.model import MDP
from veribattery.checker.mdp.rational import ObjectArray
from veribattery.checker.mdp.system import Objective
from veribattery.lang.nodes import TimeBound, TimeInterval

__all__ = ["exact_next", "exact_rounds", "exact_until"]

_ZERO = mpq(0)
_ONE = mpq(1)


def exact_until(mdp: MDP, probabilities: ObjectArray, remain: BoolArray | None,
                target: BoolArray, bound: TimeBound | TimeInterval | None,
                objective: Objective) -> ObjectArray:
    """Pmin or Pmax of ``remain U target`` within its step interval, per state.

    :param probabilities: the exact value of each stored entry of ``mdp.transitions``.
    :param remain: the states that may be passed through (None: all).
    """
    n = mdp.num_states
    remain = np.ones(n, dtype=bool) if remain is None else remain
    if bound is None:
        return _reach(mdp, probabilities, remain, target, objective)
    if isinstance(bound, TimeInterval):
        low, high = exact_step_bound(bound.low), exact_step_bound(bound.high)
    elif bound.op in ("<=", "<"):
        low, high = 0, exact_step_bound(bound.value) - (bound.op == "<")
    elif bound.op == "=":
        low = high = exact_step_bound(bound.value)
    else:  # >= k, > k: remain for k steps, then remain U target
        steps = exact_step_bound(bound.value) + (bound.op == ">")
        later = _reach(mdp, probabilities, remain, target, objective)
        return exact_rounds(mdp, probabilities, later, remain, _zeros(n), objective, steps)
    if high < low:
        return _zeros(n)
    start = _indicator(target)
    window = exact_rounds(mdp, probabilities, start, remain & ~target, start, objective,
                          high - low)
    return exact_rounds(mdp, probabilities, window, remain, _zeros(n), objective, low)


def exact_next(mdp: MDP, probabilities: ObjectArray, target: BoolArray,
               objective: Objective) -> ObjectArray:
    """Pmin or Pmax of ``X target``, per state."""
    return _image(mdp, probabilities, _indicator(target), objective, None)


def exact_rounds(mdp: MDP, probabilities: ObjectArray, start: ObjectArray, moving: BoolArray,
                 fixed: ObjectArray, objective: Objective, steps: int,
                 offset: ObjectArray | None = None) -> ObjectArray:
    """*steps* rounds of ``x(s) = opt_a (o_a + P_a x)`` from *start* on the *moving*
    states, the others held at *fixed* (*offset*: per choice, its reward; None: 0)."""
    x = start
    for _ in range(steps):
        x = np.where(moving, _image(mdp, probabilities, x, objective, offset), fixed)
    return np.asarray(x, dtype=object)


def _image(mdp: MDP, probabilities: ObjectArray, x: ObjectArray, objective: Objective,
           offset: ObjectArray | None) -> ObjectArray:
    """One exact Bellman image: per state, the best choice's ``o_a + P_a x``."""
    P = mdp.transitions
    rows = np.add.reduceat(probabilities * x[P.indices], P.indptr[:-1])  # no empty row
    if offset is not None:
        rows = rows + offset
    reduce = np.maximum if objective == "max" else np.minimum
    return np.asarray(reduce.reduceat(rows, mdp.row_groups[:-1]), dtype=object)


def _reach(mdp: MDP, probabilities: ObjectArray, remain: BoolArray, target: BoolArray,
           objective: Objective) -> ObjectArray:
    """Unbounded ``remain U target`` by exact policy iteration."""
    found = exact_reach_probability(mdp, target, objective=objective, remain=remain,
                                    probabilities=probabilities)
    return found.values


def _indicator(mask: BoolArray) -> ObjectArray:
    return np.asarray(np.where(mask, _ONE, _ZERO), dtype=object)


def _zeros(n: int) -> ObjectArray:
    return np.full(n, _ZERO, dtype=object)
