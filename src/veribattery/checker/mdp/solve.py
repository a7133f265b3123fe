"""Approximate optimal values and strategies: policy iteration in floating point.

Policy iteration (Howard 1960; Puterman 1994, §6.4 and §7.2) evaluates a strategy
by one sparse LU solve of its induced system, then switches every class whose
best row beats its current one. Only the *approximation* comes from here: the
bounds returned to users are certified afterwards from the Bellman operator
itself (:mod:`~veribattery.checker.mdp.certificate`), so a rounding error or a
tie broken the wrong way here can widen an interval but never falsify it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from veribattery._types import BoolArray, FloatArray, IntArray
from veribattery.checker.mdp.graph import attractor
from veribattery.checker.mdp.system import ChoiceSystem, Objective

__all__ = ["Evaluation", "evaluate", "policy_iteration", "progress_rows"]

#: A row replaces the current one only if it is better by this much, relative.
POLICY_TOLERANCE = 1e-12
#: Improvement rounds before the last strategy is taken as it is.
POLICY_ROUNDS = 200
#: Refinement steps after each LU solve (in float64).
REFINE_STEPS = 2


@dataclass(frozen=True, slots=True)
class Evaluation:
    """A strategy's values on the classes and an approximate solver of its system.

    :param values: the strategy's value per class.
    :param rows: the strategy: one row of the system per class.
    :param correct: ``delta -> (I - B)^-1 delta`` for the strategy's map
        ``x -> G_rows(x)`` (``B`` its linear part): how far a defect *delta* of that map
        moves its fixed point.
    """

    values: FloatArray
    rows: IntArray
    correct: Callable[[FloatArray], FloatArray]


def evaluate(system: ChoiceSystem, rows: IntArray, known: FloatArray,
             offset: FloatArray | None) -> Evaluation | None:
    """The values of the strategy *rows*, or None if its system is singular (the
    strategy stays forever among the unknown states from somewhere)."""
    chosen = sp.csr_matrix(system.off[rows])
    leave = system.leave[rows]
    matrix = sp.csc_matrix(sp.diags(leave) - chosen[:, : system.size])
    rhs = chosen[:, system.size:] @ known
    if offset is not None:
        rhs = rhs + offset[rows]
    try:
        factors = splu(matrix)
    except RuntimeError:
        return None
    x = factors.solve(rhs)
    for _ in range(REFINE_STEPS):
        x = x + factors.solve(rhs - matrix @ x)
    if not np.all(np.isfinite(x)):
        return None

    def correct(delta: FloatArray) -> FloatArray:
        return np.asarray(factors.solve(leave * delta), dtype=np.float64)

    return Evaluation(np.asarray(x, dtype=np.float64), rows, correct)


def policy_iteration(system: ChoiceSystem, objective: Objective, known: FloatArray,
                     offset: FloatArray | None, start: IntArray) -> Evaluation | None:
    """Policy iteration from the strategy *start* (rows per class).

    A class switches only where its best row beats the current one by more than
    :data:`POLICY_TOLERANCE` (relative), so rounding noise cannot make it cycle.
    For minimising expected rewards *start* must reach the known states almost
    surely (a proper strategy); improvements keep that (Bertsekas & Tsitsiklis 1991).

    :return: the last strategy's evaluation, or None if even *start* is singular.
    """
    current = evaluate(system, start, known, offset)
    for _ in range(POLICY_ROUNDS):
        if current is None:
            return None
        following = _improved(system, objective, current, known, offset)
        if following is None:
            return current
        candidate = evaluate(system, following, known, offset)
        if candidate is None or _improper(candidate.values):
            return current
        current = candidate
    return current


def _improper(values: FloatArray) -> bool:
    """Whether values that must be >= 0 are clearly negative (more than rounding
    noise): the sign of a strategy that stays forever among the unknowns."""
    scale = float(np.max(np.abs(values), initial=1.0))
    return bool(np.any(values < -1e-9 * scale))


def _improved(system: ChoiceSystem, objective: Objective, current: Evaluation,
              known: FloatArray, offset: FloatArray | None) -> IntArray | None:
    """The switched strategy, or None when no class improves."""
    images = system.images(current.values, known, offset)
    best = system.best(images, objective)
    now = images[current.rows]
    tolerance = POLICY_TOLERANCE * np.maximum(np.abs(now), np.abs(best))
    with np.errstate(invalid="ignore"):
        better = best > now + tolerance if objective == "max" else best < now - tolerance
    if not better.any():
        return None
    return np.where(better, system.best_rows(images, objective), current.rows)


def progress_rows(system: ChoiceSystem, goal: BoolArray) -> IntArray:
    """A starting strategy: per class, a row that moves towards the known states
    *goal* (a mask over ``system.known_states``); the first row where none does."""
    graph = system.graph()
    nodes = system.size + system.known_states.size
    through = np.zeros(nodes, dtype=bool)
    through[: system.size] = True
    seeds = np.zeros(nodes, dtype=bool)
    seeds[system.size:] = goal
    _, via = attractor(graph, through, seeds)
    return np.where(via[: system.size] >= 0, via[: system.size], system.groups[:-1])
