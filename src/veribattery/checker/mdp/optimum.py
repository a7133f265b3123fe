"""The optimal values of the unknown states: equations, policy iteration, certificate.

Every unbounded operator ends here once its pre-pass has decided which states
are known and which choices may be used: :func:`optimise` builds the
:class:`~veribattery.checker.mdp.system.ChoiceSystem` of the unknown classes,
approximates the optimum by policy iteration from a strategy that makes progress
towards the *goal* states, and certifies it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from veribattery._types import BoolArray, FloatArray, IntArray
from veribattery.checker.bounds import Bounds
from veribattery.checker.mdp.certificate import certified_values
from veribattery.checker.mdp.model import MDP
from veribattery.checker.mdp.solve import policy_iteration, progress_rows
from veribattery.checker.mdp.system import ChoiceSystem, Objective, equations

__all__ = ["Optimum", "optimise", "spread"]


@dataclass(frozen=True, slots=True)
class Optimum:
    """The certified optimum of the unknown classes and the strategy that attains it.

    :param system: the equations of the classes.
    :param bounds: per class, the optimal value and its enclosure.
    :param rows: per class, the row (of *system*) the strategy takes.
    """

    system: ChoiceSystem
    bounds: Bounds
    rows: IntArray


def optimise(mdp: MDP, class_of: IntArray, known: FloatArray, objective: Objective, *,
             rewards: FloatArray | None = None, allowed: BoolArray | None = None,
             goal: BoolArray, ceiling: float) -> Optimum:
    """The optimal values of the classes of *class_of* (-1: a known state).

    :param known: per state, the exact value of the known states (read there only).
    :param rewards: per choice, the reward of taking it (None: probabilities).
    :param allowed: the choices that may be taken (None: all).
    :param goal: the known states a first strategy moves towards (for minimal
        rewards it must reach them almost surely from every class).
    :param ceiling: the trivial upper bound (1 for probabilities, inf for rewards).
    """
    system = equations(mdp.transitions, mdp.choice_owner, class_of, allowed)
    fixed = np.asarray(known[system.known_states], dtype=np.float64)
    offset = None if rewards is None else np.asarray(rewards[system.choices], dtype=np.float64)
    start = progress_rows(system, goal[system.known_states])
    evaluation = policy_iteration(system, objective, fixed, offset, start)
    bounds = certified_values(system, objective, fixed, offset, evaluation, ceiling)
    return Optimum(system, bounds, start if evaluation is None else evaluation.rows)


def spread(values: Bounds, class_of: IntArray, found: Bounds) -> Bounds:
    """*values* with each classed state given its class's bounds from *found*."""
    inside = class_of >= 0
    index = class_of[inside]
    value, lower, upper = values.value.copy(), values.lower.copy(), values.upper.copy()
    value[inside], lower[inside], upper[inside] = (found.value[index], found.lower[index],
                                                   found.upper[index])
    return Bounds(value, lower, upper)
