"""Observers of simulated runs: each decides one ``P=?`` or ``R=?`` property run by run.

An observer is shown the state of every run at each step (``see``) and keeps,
per run, whether the property is decided yet and its value on that run. State
formulas inside the path formula are evaluated exactly by the checker first.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from veribattery._types import BoolArray, FloatArray, IntArray
from veribattery.checker import Workspace, state_set
from veribattery.checker.kernels import prob0
from veribattery.errors import CheckError
from veribattery.explore.dtmc import DTMC
from veribattery.lang.nodes import (
    Cumulative,
    DoubleLit,
    Eventually,
    Expr,
    Globally,
    Instantaneous,
    IntLit,
    Next,
    ProbOp,
    Reach,
    RewardOp,
    TimeBound,
    TimeInterval,
    Until,
)

__all__ = ["Observer", "observer_for"]

NO_BOUND = np.iinfo(np.int64).max


@dataclass(slots=True)
class Observer:
    """Per-run decision of one property.

    Runs are decided by *target* (value 1, or the accumulated reward), by
    *stop* (value 0, or an infinite reward when *stop_infinite*), or at step
    *horizon* (value 0 for probabilities, the reward so far for ``C<=k``; for
    ``I=k`` the state reward at step k).
    """

    runs: int
    target: BoolArray
    stop: BoolArray
    horizon: int = int(NO_BOUND)
    start: int = 0
    reward: FloatArray | None = None
    instantaneous: bool = False
    stop_infinite: bool = False
    negate: bool = False
    decided: BoolArray = field(init=False)
    values: FloatArray = field(init=False)

    def __post_init__(self) -> None:
        self.decided = np.zeros(self.runs, dtype=bool)
        self.values = np.zeros(self.runs)

    @property
    def is_probability(self) -> bool:
        """The values are 0/1 hits."""
        return self.reward is None

    def see(self, step: int, current: IntArray) -> None:
        """Decide the runs whose state at *step* settles the property."""
        open_ = ~self.decided
        if self.instantaneous:
            self._settle(open_ if step >= self.horizon else None, current)
            return
        hit = open_ & self.target[current] & (self.start <= step <= self.horizon)
        if self.reward is None:
            self.values[hit] = 0.0 if self.negate else 1.0
        self.decided |= hit
        open_ &= ~hit
        stopped = open_ & self.stop[current]
        self.values[stopped] = self._stop_value()
        self.decided |= stopped
        open_ &= ~stopped
        if self.reward is not None and step < self.horizon:
            self.values[open_] += self.reward[current[open_]]
        if step >= self.horizon:
            self.values[open_] = 1.0 if self.negate else self.values[open_]
            self.decided |= open_

    def _stop_value(self) -> float:
        if self.reward is not None:
            return np.inf if self.stop_infinite else 0.0
        return 1.0 if self.negate else 0.0

    def _settle(self, runs: BoolArray | None, current: IntArray) -> None:
        if runs is not None and self.reward is not None:
            self.values[runs] = self.reward[current[runs]]
            self.decided |= runs


def observer_for(dtmc: DTMC, formula: Expr, runs: int) -> Observer:
    """The observer of ``P=? [...]`` or ``R=? [...]``.

    :raises CheckError: for anything else (bounded queries, ``F>=k``, booleans).
    """
    workspace = Workspace()  # the graph searches of this observer's sets
    if isinstance(formula, ProbOp) and formula.op == "=?":
        return _path_observer(dtmc, formula, runs, workspace=workspace)
    if isinstance(formula, RewardOp) and formula.op == "=?":
        return _reward_observer(dtmc, formula, runs, workspace=workspace)
    raise CheckError("only P=? and R=? queries are simulated")


def _path_observer(dtmc: DTMC, op: ProbOp, runs: int, *, workspace: Workspace) -> Observer:
    everywhere = np.ones(dtmc.num_states, dtype=bool)
    match op.path:
        case Next(operand=operand):
            target = state_set(dtmc, operand, workspace=workspace)
            return Observer(runs, target, ~everywhere, horizon=1, start=1)
        case Until(left=left, right=right, bound=bound):
            a = state_set(dtmc, left, workspace=workspace)
            b = state_set(dtmc, right, workspace=workspace)
            return _until(dtmc, a, b, bound, runs, workspace=workspace)
        case Eventually(operand=operand, bound=bound):
            target = state_set(dtmc, operand, workspace=workspace)
            return _until(dtmc, everywhere, target, bound, runs, workspace=workspace)
        case Globally(operand=operand, bound=bound):
            avoid = ~state_set(dtmc, operand, workspace=workspace)
            escape = _until(dtmc, everywhere, avoid, bound, runs, workspace=workspace)
            escape.negate = True
            return escape
    raise _not_simulated(op.path)


def _until(dtmc: DTMC, remain: BoolArray, target: BoolArray,
           bound: TimeBound | TimeInterval | None, runs: int, *,
           workspace: Workspace) -> Observer:
    never = prob0(dtmc.transitions, remain, target, workspace=workspace)
    horizon = _upper(bound)
    # A run at step `horizon` may still hit the target; after it, it cannot.
    return Observer(runs, target, never | (~remain & ~target), horizon=horizon)


def _upper(bound: TimeBound | TimeInterval | None) -> int:
    if bound is None:
        return int(NO_BOUND)
    if isinstance(bound, TimeInterval):
        raise CheckError("step intervals U[a,b] are not simulated")
    if bound.op == "<=":
        return _steps(bound.value)
    if bound.op == "<":
        return _steps(bound.value) - 1
    raise CheckError(f"step bound '{bound.op}' is not simulated")


def _steps(expr: Expr) -> int:
    if isinstance(expr, IntLit | DoubleLit) and float(expr.value) == int(expr.value) >= 0:
        return int(expr.value)
    raise CheckError("a step bound must be a non-negative integer")


def _reward_observer(dtmc: DTMC, op: RewardOp, runs: int, *,
                     workspace: Workspace) -> Observer:
    try:
        structure = dtmc.reward(op.reward)
    except (KeyError, IndexError):
        raise CheckError(f"the model has no reward structure {op.reward!r}") from None
    nothing = np.zeros(dtmc.num_states, dtype=bool)
    match op.path:
        case Reach(target=target):
            goal = state_set(dtmc, target, workspace=workspace)
            lost = prob0(dtmc.transitions, ~nothing, goal, workspace=workspace)
            return Observer(runs, goal, lost, reward=structure.total, stop_infinite=True)
        case Cumulative(bound=bound):
            return Observer(runs, nothing, nothing, horizon=_steps(bound),
                            reward=structure.total)
        case Instantaneous(time=time):
            return Observer(runs, nothing, nothing, horizon=_steps(time),
                            reward=structure.state, instantaneous=True)
    raise _not_simulated(op.path)


#: The paths a run cannot be followed through, in the property language's words.
_PATH_WORDS = {
    "WeakUntil": "weak until (W)", "Release": "release (R)",
    "RewardBounded": "a reward-bounded F or U", "Conditional": "a conditional probability (||)",
    "Total": "a total reward (C)", "LongRun": "a long-run average reward (S)",
    "ReachUntil": "a reward until (a U b)", "ReachNext": "a reward of the next step (X)",
    "ConditionalReach": "a conditional expectation (F a || F b)",
    "LtlPath": "an LTL formula (a finite run cannot settle most)",
    "CosafeReach": "a reward until a co-safe LTL formula holds",
}


def _not_simulated(path: object) -> CheckError:
    kind = _PATH_WORDS.get(type(path).__name__, "this path formula")
    return CheckError(f"{kind} is not simulated")
