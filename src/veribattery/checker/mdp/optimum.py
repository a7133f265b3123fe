"""The optimal values of the unknown states: equations, policy iteration, certificate.

Every unbounded operator ends here once its pre-pass has decided which states
are known, which are unknown (and which end components among them are
collapsed) and which choices may be used -- a :class:`Problem`. :func:`solve`
builds the :class:`~veribattery.checker.mdp.system.ChoiceSystem` of the unknown
classes (:class:`Equations`). Where their class graph is acyclic, one pass over its
levels certifies the optimum (:mod:`~veribattery.checker.mdp.acyclic`); otherwise
policy iteration from the greedy strategy of topological value iteration
(:mod:`~veribattery.checker.mdp.topological`; else from a strategy that makes
progress towards the *goal* states) approximates it and the certificate bounds it.
Either way the strategy is lifted from classes back to states. The exact engine
(:mod:`~veribattery.checker.mdp.exact`) solves the same problems in rationals.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from veribattery._types import BoolArray, FloatArray, IntArray
from veribattery.checker.certify.bounds import Bounds, rational_bounds
from veribattery.checker.certify.fixpoint import Progress
from veribattery.checker.mdp.acyclic import acyclic_optimum
from veribattery.checker.mdp.certificate import certified_values
from veribattery.checker.mdp.components import EndComponents
from veribattery.checker.mdp.graph import ChoiceGraph
from veribattery.checker.mdp.model import MDP
from veribattery.checker.mdp.result import MdpResult
from veribattery.checker.mdp.solve import Evaluation, policy_iteration, progress_rows
from veribattery.checker.mdp.strategy import Strategy, lifted
from veribattery.checker.mdp.system import ChoiceSystem, Objective, equations, quotient_classes
from veribattery.checker.mdp.topological import (
    Levels,
    class_levels,
    topological_policy_iteration,
)

__all__ = ["Equations", "Problem", "Solved", "approximate", "solve", "solve_from", "spread"]

#: Systems of at most this many classes are solved exactly when their certificate
#: stays too wide (as the DTMC side's rational solve of small systems).
EXACT_LIMIT = 2_000


@dataclass(frozen=True, slots=True)
class Problem:
    """An unbounded operator after its qualitative pre-pass.

    :param objective: whether the values are minimal or maximal.
    :param unknown: the states still to solve.
    :param known: per state, the exact value of the others (0, 1 or ``inf``).
    :param choices: per state, an optimal choice where the value is known (the
        first choice where any will do); the unknown states' are replaced.
    :param goal: known states a first strategy moves towards (for minimal rewards
        they are reached almost surely from every unknown state under it).
    :param components: end components among the unknown states to collapse, if any.
    :param allowed: the choices that may be taken (None: all).
    :param ceiling: the trivial upper bound (1 for probabilities, ``inf`` for rewards).
    """

    objective: Objective
    unknown: BoolArray
    known: FloatArray
    choices: IntArray
    goal: BoolArray
    components: EndComponents | None = None
    allowed: BoolArray | None = None
    ceiling: float = 1.0

    @property
    def classes(self) -> IntArray:
        """Per state, its class among the unknowns (-1: known)."""
        component = None if self.components is None else self.components.component
        return quotient_classes(self.unknown, component)


@dataclass(frozen=True, slots=True)
class Equations:
    """A problem's equations and what every solve of them shares whatever the rewards:
    the known values, a strategy that makes progress, the class levels. Made once by a
    caller that solves one problem with many rewards (``multi(...)``'s weights).

    :param moving: per class, a row that moves towards the problem's goal.
    """

    problem: Problem
    system: ChoiceSystem
    known: FloatArray
    moving: IntArray
    levels: Levels

    @classmethod
    def of(cls, mdp: MDP, problem: Problem) -> Equations:
        """The equations of *problem*'s unknown classes (it must have some)."""
        system = equations(mdp.transitions, mdp.choice_owner, problem.classes, problem.allowed)
        known = np.asarray(problem.known[system.known_states], dtype=np.float64)
        moving = progress_rows(system, problem.goal[system.known_states])
        return cls(problem, system, known, moving, class_levels(system))


@dataclass(frozen=True, slots=True)
class Approximation:
    """A problem's equations and policy iteration's answer on them (None: none found),
    or, on an acyclic system, the certified values of its one pass (*certified*; then
    *start* is the strategy found)."""

    system: ChoiceSystem
    known: FloatArray
    offset: FloatArray | None
    evaluation: Evaluation | None
    start: IntArray
    certified: Bounds | None = None

    @property
    def rows(self) -> IntArray:
        """The strategy found (per class, a row of the system)."""
        return self.start if self.evaluation is None else self.evaluation.rows

    def settled(self) -> Approximation:
        """The same without its evaluation (its strategy kept as *start*)."""
        return replace(self, evaluation=None, start=self.rows)


def approximate(mdp: MDP, equations: Equations, rewards: FloatArray | None,
                start: IntArray | Strategy | None = None, *,
                progress: Progress | None = None) -> Approximation:
    """The approximate optimum of a problem's *equations* (or, where their class graph
    is acyclic and its one pass precise, their certified optimum).

    :param rewards: per choice, the reward of taking it (None: probabilities).
    :param start: where policy iteration starts: rows per class (a strategy found for
        the same problem with other rewards), or a strategy over the states (each class
        takes the first of its rows that one of its states chooses, else a row that
        makes progress); None, or one whose system is singular: a strategy that makes
        progress towards the goal. An acyclic system keeps its rows on ties.
    """
    system, known, moving, levels = (equations.system, equations.known, equations.moving,
                                     equations.levels)
    objective = equations.problem.objective
    offset = None if rewards is None else np.asarray(rewards[system.choices], dtype=np.float64)
    if isinstance(start, Strategy):
        start = _rows_of(mdp, system, start, moving)
    if start is not None and start.shape != (system.size,):
        start = None
    if levels.within_limit and levels.acyclic:
        bounds, rows = acyclic_optimum(system, objective, known, offset, levels,
                                       moving if start is None else start,
                                       equations.problem.ceiling, progress=progress)
        if bounds.precise_states().all():
            return Approximation(system, known, offset, None, rows, bounds)
    evaluation = None
    if start is not None:
        evaluation = policy_iteration(system, objective, known, offset, start,
                                      progress=progress)
    else:
        evaluation = topological_policy_iteration(system, objective, known, offset,
                                                  moving, levels, progress=progress)
    if evaluation is None:
        start = moving
        evaluation = policy_iteration(system, objective, known, offset, start,
                                      progress=progress)
    if start is None:
        start = moving
    return Approximation(system, known, offset, evaluation, start)


def _rows_of(mdp: MDP, system: ChoiceSystem, strategy: Strategy,
             progress: IntArray) -> IntArray:
    """Per class, the first row that the state owning it chooses, else *progress*'s."""
    chosen = strategy.choices[mdp.choice_owner[system.choices]] == system.choices
    index = np.where(chosen, np.arange(system.choices.size), system.choices.size)
    first = np.minimum.reduceat(index, system.groups[:-1])
    return np.where(first < system.choices.size, first, progress).astype(np.int64)


@dataclass(frozen=True, slots=True)
class Solved:
    """A problem's result, and the rows of the system its strategy takes (None: no
    unknown state), to start another solve of the same problem from."""

    result: MdpResult
    rows: IntArray | None


def solve(mdp: MDP, graph: ChoiceGraph, problem: Problem,
          rewards: FloatArray | None, *, progress: Progress | None = None) -> MdpResult:
    """*problem* solved: certified values in every state and an optimal strategy.

    :param progress: told ``(done, total, unit)`` as the solve goes: the levels of the
        topological start, the improvement rounds, the certificate's sweeps.
    """
    return solve_from(mdp, graph, problem, rewards, None, progress=progress).result


def solve_from(mdp: MDP, graph: ChoiceGraph, problem: Problem, rewards: FloatArray | None,
               start: IntArray | Strategy | None, *, equations: Equations | None = None,
               progress: Progress | None = None) -> Solved:
    """:func:`solve`, policy iteration started from *start* (:func:`approximate`).

    :param equations: ``Equations.of(mdp, problem)``, if the caller keeps them.
    """
    values = Bounds.exact(problem.known.copy())
    if not problem.unknown.any():
        return Solved(MdpResult(values, Strategy(problem.choices)), None)
    equations = Equations.of(mdp, problem) if equations is None else equations
    found = approximate(mdp, equations, rewards, start, progress=progress)
    bounds = found.certified
    if bounds is None:
        # The evaluation is handed to the certificate, which drops it (and its solver)
        # once it has served: no name here keeps it (zeroconf N=20 K=4: 325 -> 310 MB peak).
        handed = [found.evaluation]
        found = found.settled()
        bounds = certified_values(found.system, problem.objective, found.known, found.offset,
                                  handed.pop(), problem.ceiling, progress=progress)
    rows = found.rows
    if not bounds.precise_states().all() and found.system.size <= EXACT_LIMIT:
        rows, bounds = _exactly(mdp, problem, found, rewards)
    strategy = lifted(mdp, graph, found.system, rows, problem.components, problem.choices)
    return Solved(MdpResult(spread(values, problem.classes, bounds), Strategy(strategy)), rows)


def _exactly(mdp: MDP, problem: Problem, found: Approximation,
             rewards: FloatArray | None) -> tuple[IntArray, Bounds]:
    """The last resort of a small system whose certificate stays too wide: policy
    iteration in rationals on the same equations (the stored doubles read exactly),
    the exact values rounded to the floats either side."""
    # (imported here: the exact engine is read only when a float certificate fails)
    from gmpy2 import mpq

    from veribattery.checker.mdp.rational import RationalSystem, exact_policy_iteration

    system = found.system
    probabilities = np.full(mdp.transitions.nnz, mpq(0), dtype=object)
    probabilities[system.positions] = [mpq(float(p)) for p in mdp.transitions.data[
        system.positions]]
    known = np.array([mpq(float(v)) for v in found.known], dtype=object)
    exact_rewards = None
    if rewards is not None:
        exact_rewards = np.full(mdp.num_choices, mpq(0), dtype=object)
        exact_rewards[system.choices] = [mpq(float(r)) for r in rewards[system.choices]]
    rational = RationalSystem.of(system, probabilities, known, exact_rewards)
    rows, x = exact_policy_iteration(rational, problem.objective, found.rows)
    return rows, _rounded(x)


def _rounded(values: np.ndarray) -> Bounds:
    """Rationals as floats: the nearest one, inside the floats either side (exactly
    the value where it is a float; ``inf`` above the largest double)."""
    return rational_bounds(values.tolist())


def spread(values: Bounds, class_of: IntArray, found: Bounds) -> Bounds:
    """*values* with each classed state given its class's bounds from *found*."""
    inside = class_of >= 0
    index = class_of[inside]
    value, lower, upper = values.value.copy(), values.lower.copy(), values.upper.copy()
    value[inside], lower[inside], upper[inside] = (found.value[index], found.lower[index],
                                                   found.upper[index])
    return Bounds(value, lower, upper)
