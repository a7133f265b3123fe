"""The check of a multi-objective witness strategy on the chain it induces.

Each objective of the ``multi(...)`` query is solved on the induced DTMC by the DTMC
engine, with certified bounds: ``P [ F T ]`` as the probability of reaching a node
whose MDP state is in *T* (``G`` as one minus that of its complement), ``R [ C ]``
as the expected total reward with, per node, the expected reward of its step. A
bounded objective must be met, and the optimised one must equal the reported
optimum, each within :data:`~veribattery.checker.mdp.multi.LP_TOLERANCE` (relative,
absolute below 1) -- by the certified bounds, not just the point value. Otherwise
:class:`~veribattery.checker.mdp.witness.NoStrategyError` says which objective
failed, by how much: a wrong strategy is never written.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from veribattery._types import CsrMatrix, FloatArray, IntArray
from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.kernels.steady import total_rewards
from veribattery.checker.kernels.until import until_probs
from veribattery.checker.mdp.multi import LP_TOLERANCE, Reach
from veribattery.checker.mdp.multi_formula import _Goal
from veribattery.checker.mdp.witness import NoStrategyError
from veribattery.checker.workspace import Workspace
from veribattery.lang.evaluate import evaluate
from veribattery.lang.nodes import ProbOp, RewardOp
from veribattery.lang.printing import expression_text, path_text, reward_path_text

__all__ = ["ObjectiveValue", "Reported", "objective_text", "verified_values"]


@dataclass(frozen=True, slots=True)
class Reported:
    """The checked answer a strategy must attain.

    :param value: True (achievability) or the optimum of the ``=?`` objective.
    :param enclosure: a certified interval of the optimum, if the check has one (the
        two-objective front's); a strategy whose value lies in it and equals the
        programme's optimum passes even where the point *value* is less precise.
    :param programme: the linear programme's optimum of the ``=?`` objective (the
        strategy is built from it), or None.
    """

    value: object
    enclosure: tuple[float, float] | None = None
    programme: float | None = None


@dataclass(frozen=True, slots=True)
class ObjectiveValue:
    """One objective's value under the strategy, at the initial state.

    :param text: the objective as written (``P>=0.5 [ F "a" ]``).
    :param value: its point value on the induced chain.
    :param lower: a certified lower bound.
    :param upper: a certified upper bound.
    :param requirement: what it had to be: ``>= 0.5``, ``= 0.75 (the optimum)``.
    """

    text: str
    value: float
    lower: float
    upper: float
    requirement: str


def verified_values(chain: CsrMatrix, initial: int, node_state: IntArray,
                    expected_rewards: Callable[[FloatArray], FloatArray],
                    goals: Sequence[_Goal], reported: Reported) -> tuple[ObjectiveValue, ...]:
    """Each goal's value on *chain* from node *initial*, checked (module description).

    :param node_state: per node of *chain*, its MDP state (where targets are read).
    :param expected_rewards: per node, the expected reward of a per-choice vector.
    :param reported: the query's answer (:class:`Reported`).
    :raises NoStrategyError: an objective misses its bound or the optimum.
    """
    workspace = Workspace()
    values = []
    for goal in goals:
        found = _quantity(chain, initial, node_state, expected_rewards, goal, workspace)
        low, high = sorted((goal.offset + goal.sign * float(found.lower[0]),
                            goal.offset + goal.sign * float(found.upper[0])))
        point = goal.offset + goal.sign * float(found.value[0])
        values.append(_judged(goal, point, low, high, reported))
    return tuple(values)


def _quantity(chain: CsrMatrix, initial: int, node_state: IntArray,
              expected_rewards: Callable[[FloatArray], FloatArray], goal: _Goal,
              workspace: Workspace) -> Bounds:
    """The goal's quantity (before offset and sign) at node *initial*, certified."""
    focus = np.array([initial])
    if isinstance(goal.quantity, Reach):
        target = np.asarray(goal.quantity.target, dtype=bool)[node_state]
        everywhere = np.ones(chain.shape[0], dtype=bool)
        return until_probs(chain, everywhere, target, focus, workspace=workspace).at(focus)
    rewards = expected_rewards(np.asarray(goal.quantity.rewards, dtype=np.float64))
    return total_rewards(chain, rewards, workspace=workspace).at(focus)


def _judged(goal: _Goal, point: float, low: float, high: float,
            reported: Reported) -> ObjectiveValue:
    """The goal's value if it passes its check, else the refusal naming it."""
    text = objective_text(goal.op)
    if goal.op.op == "=?":
        requirement, passed = _optimal(goal, point, low, high, reported)
    else:
        assert goal.op.bound is not None
        bound = float(evaluate(goal.op.bound, {}))
        slack = LP_TOLERANCE * max(1.0, abs(bound))
        at_least = goal.op.op in (">=", ">")
        requirement = f"{'>=' if at_least else '<='} {bound!r}"
        passed = low >= bound - slack if at_least else high <= bound + slack
    if not passed:
        raise NoStrategyError(
            f"no strategy exported: the randomised strategy built from the linear programme "
            f"gives {text} the value {point!r} (certified in [{low!r}, {high!r}]) on its "
            f"induced chain, not {requirement} within {LP_TOLERANCE:g}", goal.op.span)
    return ObjectiveValue(text, point, low, high, requirement)


def _optimal(goal: _Goal, point: float, low: float, high: float,
             reported: Reported) -> tuple[str, bool]:
    """What the optimised goal had to be, and whether it is: the reported optimum
    within the tolerance, or (where the check has a certified enclosure) inside it and
    equal to the programme's optimum it was built from."""
    assert isinstance(reported.value, float | int)
    target = float(reported.value)
    slack = LP_TOLERANCE * max(1.0, abs(target))
    if target - slack <= low and high <= target + slack:
        return f"= {target!r} (the optimum)", True
    if reported.enclosure is None or reported.programme is None:
        return f"= {target!r} (the optimum)", False
    lower, upper = reported.enclosure
    programme = goal.offset + goal.sign * reported.programme
    inside = lower - slack <= low and high <= upper + slack
    return (f"= {target!r} (the optimum, certified in [{lower!r}, {upper!r}]; the "
            f"programme's {programme!r})", inside and abs(point - programme) <= slack)


def objective_text(op: ProbOp | RewardOp) -> str:
    """An objective of ``multi(...)`` as PRISM writes it: ``Pmax=? [ F "a" ]``."""
    direction = op.direction or ""
    bound = "" if op.bound is None else expression_text(op.bound)
    if isinstance(op, ProbOp):
        return f"P{direction}{op.op}{bound} [ {path_text(op.path)} ]"
    reward = "" if op.reward is None else (
        f'{{"{op.reward}"}}' if isinstance(op.reward, str) else f"{{{op.reward + 1}}}")
    return f"R{reward}{direction}{op.op}{bound} [ {reward_path_text(op.path)} ]"
