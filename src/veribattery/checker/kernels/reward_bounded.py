"""Reward-bounded reachability: Storm's ``F{"r"}<=T phi`` and ``psi U{"r"}<=T phi``.

**Semantics** (the same as Storm's, tested against it in
``tests/checker/test_reward_bounded_storm.py``). A path ``s0 s1 … sn`` whose first
*target* state is ``sn`` satisfies ``remain U{"r"}<=T target`` when ``s0 … s(n-1)``
satisfy *remain* and the reward of its *n* steps is at most T. The reward of a step
is that of the state it leaves: the state reward plus the transition (action)
reward, so the step that **enters** the target is counted in full and the target
state's own reward is not (as for ``R=? [ F phi ]``). ``U{"r"}<T`` is ``<=T-1``
for the integer rewards required here; a fractional T is rounded down.

**Algorithm.** A dynamic programme over accumulated reward levels ``k = 0..T``:
the value at level *k* of a state with reward ``r > 0`` is one sparse row product
with the values of level ``k - r``; states with reward 0 stay on their level, so
each level closes over them with one solve of ``(I - P_ZZ)``, factorised once.
Rewards and T are first divided by the greatest common divisor of the rewards.
Both directions are here: :func:`reward_bounded_until_probs` (backward, every
state, one T) and :func:`absorption_by_level` (forward, from the initial states,
every level up to a stopping rule: a whole distribution in one pass).

**Certification** (backward; ``docs/numerics.md``). The levels are computed once in
float64 with a rigorous forward-error radius per state
(:mod:`~veribattery.checker.kernels.reward_radius`); only where that interval misses the
required precision is every level certified on its own (:func:`_certified_programme`,
about ten times slower), and the two intervals are intersected.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

from veribattery._types import BoolArray, CsrMatrix, FloatArray, IntArray
from veribattery._unique import distinct
from veribattery.checker import certify, linalg
from veribattery.checker.certify.bounds import Bounds, round_down, round_up
from veribattery.checker.kernels import reward_radius
from veribattery.checker.kernels.prepass import prob0
from veribattery.errors import CheckError, Span
from veribattery.explore.build.successors import format_state
from veribattery.explore.dtmc import DTMC, RewardVectors

if TYPE_CHECKING:
    from veribattery.checker.workspace import Workspace

#: Largest accepted distance of a reward value from the nearest integer.
INTEGER_TOL = 1e-9


class NonIntegerReward(ValueError):
    """A reward value that is negative or not an integer, at state index *state*."""

    def __init__(self, state: int, value: float) -> None:
        super().__init__(f"state {state} has reward {value:g}")
        self.state = state
        self.value = value


def integer_levels(rewards: FloatArray) -> IntArray:
    """*rewards* as non-negative integers.

    :raises NonIntegerReward: naming the first state whose reward is negative or not
        within :data:`INTEGER_TOL` of an integer.
    """
    rounded = np.rint(rewards)
    bad = (rounded < 0) | ~(np.abs(rewards - rounded) <= INTEGER_TOL * np.maximum(1.0, rounded))
    if bad.any():
        state = int(np.flatnonzero(bad)[0])
        raise NonIntegerReward(state, float(rewards[state]))
    return rounded.astype(np.int64)


def integer_rewards(dtmc: DTMC, structure: RewardVectors, span: Span) -> IntArray:
    """The rewards per step of *structure* as integers, or an error naming a bad state.

    :raises CheckError: when a state's reward is negative or not an integer.
    """
    try:
        return integer_levels(structure.total)
    except NonIntegerReward as exc:
        state = format_state(dtmc.variable_names, dtmc.states[exc.state])
        name = f'"{structure.name}"' if structure.name else "(unnamed)"
        raise CheckError(
            f"a reward bound needs non-negative integer rewards, but reward structure {name} "
            f"gives {exc.value:g} in state ({state})", span) from None


# ---------------------------------------------------------------------------
# The level structure shared by both directions
# ---------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Levels:
    """The moving states grouped by reward (in units of *unit*), and the zero-reward closure."""

    unit: int
    #: (reward in units, the moving states with that reward) for every positive reward.
    groups: tuple[tuple[int, IntArray], ...]
    zero: IntArray
    #: ``I - P_ZZ`` over the zero-reward moving states, factorised (None if there are none).
    closure: linalg.Factorization | None
    #: Rows of P of the zero-reward moving states.
    zero_rows: CsrMatrix


def _levels(P: CsrMatrix, moving: BoolArray, rewards: IntArray, transpose: bool,
            plans: linalg.SolverPlans | None = None) -> Levels:
    """Group the *moving* states by reward; factorise the zero-reward closure once
    (its index work kept in *plans* for a closure of the same pattern).

    The closure is nonsingular because every moving state can leave the moving set
    (the caller removed the states that cannot reach the target).
    """
    positive = np.unique(rewards[moving & (rewards > 0)])
    unit = math.gcd(*(int(v) for v in positive)) if positive.size else 1
    groups = tuple(
        (int(value) // unit, np.flatnonzero(moving & (rewards == value))) for value in positive
    )
    zero_mask = moving & (rewards == 0)
    zero = np.flatnonzero(zero_mask)
    closure = None
    if zero.size:
        A, _rows = linalg.restricted_matrix(P, zero_mask, plans)
        closure = linalg.Factorization(sp.csr_matrix(A.T) if transpose else A, plans=plans)
    return Levels(unit, groups, zero, closure, sp.csr_matrix(P[zero]))


def _close(levels: Levels, b: FloatArray) -> FloatArray:
    """Solve the zero-reward closure ``(I - P_ZZ)[^T] x = b``."""
    assert levels.closure is not None
    return levels.closure.solve(np.asarray(b, dtype=np.longdouble))


# ---------------------------------------------------------------------------
# Backward: every state, one bound
# ---------------------------------------------------------------------------


def reward_bounded_until_probs(P: CsrMatrix, remain: BoolArray, target: BoolArray,
                               rewards: IntArray, bound: int, *, workspace: Workspace
                               ) -> FloatArray:
    """The point values of :func:`reward_bounded_until_bounds`."""
    return reward_bounded_until_bounds(P, remain, target, rewards, bound,
                                       workspace=workspace).value


def reward_bounded_until_bounds(P: CsrMatrix, remain: BoolArray, target: BoolArray,
                                rewards: IntArray, bound: int, *, workspace: Workspace
                                ) -> Bounds:
    """Probability of ``remain U{r}<=bound target`` in every state, with certified bounds.

    First the point values with a forward-error radius per state
    (:func:`~veribattery.checker.kernels.reward_radius.radius_programme`: per level two
    products per reward group and two substitutions for the closure); where that
    interval misses the required precision, the programme is run again with every level certified
    (:func:`_certified_programme`) and the two certified intervals are intersected.

    :param P: row-stochastic CSR transition matrix.
    :param remain: states that may be passed through before *target*.
    :param target: states to reach.
    :param rewards: non-negative integer reward of the step leaving each state
        (see :func:`integer_levels`).
    :param bound: the largest total reward allowed, the entering step included.
    :param workspace: where the graph search and the closure's plans are kept.
    :return: probabilities in [0, 1]; 0 everywhere if *bound* < 0.
    """
    n = P.shape[0]
    if bound < 0:
        return Bounds.exact(np.zeros(n))
    moving = remain & ~target & ~prob0(P, remain, target, workspace=workspace)
    order = _grouped_order(moving, rewards)
    P, moving, target, rewards = (sp.csr_matrix(P[order][:, order]), moving[order],
                                  target[order], rewards[order])
    levels = _levels(P, moving, rewards, transpose=False, plans=workspace.solvers)
    last = bound // levels.unit
    found = reward_radius.radius_programme(P, moving, target, rewards, levels, last)
    if found is None or not found.precise_states().all():
        slow = _certified_programme(P, target, levels, last)
        found = slow if found is None else Bounds.around(
            slow.value, np.maximum(found.lower, slow.lower), np.minimum(found.upper, slow.upper))
    back = np.argsort(order)
    return Bounds(found.value[back], found.lower[back], found.upper[back])


def _grouped_order(moving: BoolArray, rewards: IntArray) -> IntArray:
    """A renumbering of the states that makes each reward group one contiguous block
    (higher rewards first, the states that do not move last): the per-level copies in
    and out of the groups are then slices, not gathers."""
    return np.argsort(np.where(moving, rewards, -1), kind="stable")[::-1]


# ---------------------------------------------------------------------------
# Backward, escalation: every level certified
# ---------------------------------------------------------------------------


def _certified_programme(P: CsrMatrix, target: BoolArray, levels: Levels, last: int) -> Bounds:
    """The levels with certified intervals carried from level to level.

    The positive-reward states' values are enclosed products of the interval of the
    level they reach back to (monotone since ``P >= 0``), and the zero-reward
    closure's fixed point is certified around its LU solution
    (:func:`certify.certify_side`) with the level's other values as intervals: the
    widths are transported state by state, at the cost of two certifications per level.
    """
    n = P.shape[0]
    steps = [_BackwardGroup.of(P, r, states) for r, states in levels.groups]
    closure = _Closure.of(levels, n) if levels.closure is not None else None
    hit = target.astype(np.float64)
    found = Bounds.exact(hit)
    for k in range(last + 1):
        found = Bounds.exact(hit)
        for group in steps:
            group.fill(k, found)
        if closure is not None:
            closure.close(levels, found)
        for group in steps:
            group.remember(k, found)
    return Bounds.around(np.clip(found.value, 0.0, 1.0), np.maximum(found.lower, 0.0),
                         np.minimum(found.upper, 1.0))


@dataclass(frozen=True, slots=True)
class _BackwardGroup:
    """States with reward *r*: their value on level k is P_rows @ (successors' value on k-r).

    Only the successors' values of the last *r* levels are kept (a ring buffer), as
    point value, certified lower and upper bound.
    """

    r: int
    states: IntArray
    successors: IntArray
    block: CsrMatrix
    history: FloatArray
    #: The rounding bound of a row product is ``coefficient * magnitude + underflow``.
    coefficient: FloatArray
    underflow: FloatArray

    @classmethod
    def of(cls, P: CsrMatrix, r: int, states: IntArray) -> _BackwardGroup:
        successors, block, coefficient, underflow = reward_radius.group_rows(P, states)
        return cls(r, states, successors, block, np.zeros((3, r, successors.size)),
                   coefficient, underflow)

    def fill(self, k: int, found: Bounds) -> None:
        """Write this group's value on level *k* into *found* (0 below level r)."""
        if k < self.r:
            found.value[self.states] = found.lower[self.states] = found.upper[self.states] = 0.0
            return
        value, low, high = self.history[:, k % self.r]
        found.value[self.states] = self.block @ value
        # 0 <= low <= high, so the rounding bound of the larger product covers both.
        above = self.block @ high
        # certify.product_error for nonnegative terms, its constant parts precomputed
        # (coefficient * magnitude + underflow), rounded up once.
        error = round_up(self.coefficient * above + self.underflow)
        found.lower[self.states] = np.maximum(round_down(self.block @ low - error), 0.0)
        found.upper[self.states] = round_up(above + error)

    def remember(self, k: int, found: Bounds) -> None:
        slot = k % self.r
        for i, vector in enumerate((found.value, found.lower, found.upper)):
            self.history[i, slot] = vector[self.successors]


@dataclass(frozen=True, slots=True)
class _Closure:
    """The certified zero-reward closure of one level, over the columns its rows use."""

    used: IntArray
    template: certify.AffineMap

    @classmethod
    def of(cls, levels: Levels, n: int) -> _Closure:
        used = distinct(np.concatenate([levels.zero_rows.indices, levels.zero]))
        local = np.searchsorted(used, levels.zero)
        rows = sp.csr_matrix(levels.zero_rows[:, used])
        empty = np.zeros(used.size)
        return cls(used, certify.AffineMap.of(rows, local, empty, empty, None))

    def close(self, levels: Levels, found: Bounds) -> None:
        """Solve the closure in *found* (values of the other states already in place).

        The point value, and each bound from its own solve (the other states at their
        lower, resp. upper bounds), certified one side at a time: so the widths carry
        over from level to level as the values do, without a growing margin.
        """
        zero = levels.zero
        assert levels.closure is not None
        found.value[zero] = 0.0
        found.value[zero] = np.clip(_close(levels, levels.zero_rows @ found.value), 0.0, 1.0)
        correct = levels.closure.correction
        solved = []
        for vector in (found.lower, found.upper):
            # One substitution with the factors is enough: its accuracy only affects
            # how tight the certified side comes out.
            vector[zero] = 0.0
            guess = correct(np.asarray(levels.zero_rows @ vector, dtype=np.float64))
            solved.append(found.value[zero] if guess is None else np.clip(guess, 0.0, 1.0))
        F = replace(self.template, known_lower=found.lower[self.used],
                    known_upper=found.upper[self.used])
        found.lower[zero] = certify.certify_side(F, solved[0], correct, np.zeros(zero.size),
                                                 up=False)
        found.upper[zero] = certify.certify_side(F, solved[1], correct, np.ones(zero.size),
                                                 up=True)


# ---------------------------------------------------------------------------
# Forward: from the initial states, every level
# ---------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class LevelMasses:
    """Probability mass absorbed per reward level, from :func:`absorption_by_level`.

    *absorbed[i, k]* is the probability of first entering absorbing set *i* with a
    total reward of exactly ``k * unit``; *pending* the mass not yet absorbed after
    the last level (moving, or on its way to a higher level); *never* the mass
    that entered a state from which no absorbing set can be reached.
    """

    unit: int
    absorbed: FloatArray
    pending: float
    never: float

    @property
    def rewards(self) -> FloatArray:
        """The reward of each level."""
        return np.arange(self.absorbed.shape[1], dtype=np.float64) * self.unit


#: Stopping rule of the forward pass: (level, mass absorbed so far per set, pending) → stop?
StopRule = Callable[[int, FloatArray, float], bool]


def absorption_by_level(P: CsrMatrix, initial: FloatArray, absorbing: tuple[BoolArray, ...],
                        rewards: IntArray, stop: StopRule, max_levels: int, *,
                        workspace: Workspace) -> LevelMasses:
    """The distribution of the reward accumulated until the first absorbing state.

    One forward pass over reward levels: the mass arriving on a level is closed
    over the zero-reward states (one solve), split off where it is absorbed, and
    sent on by one sparse product per distinct positive reward to the level it
    reaches.

    :param P: row-stochastic CSR transition matrix.
    :param initial: the initial distribution.
    :param absorbing: disjoint masks of the states where the pass stops (e.g. success
        and failure).
    :param rewards: non-negative integer reward of the step leaving each state.
    :param stop: called after each level; the pass ends when it returns True.
    :param max_levels: the pass ends after this many levels in any case.
    :param workspace: where the graph search and the closure's plans are kept.
    """
    n = P.shape[0]
    stopped = np.zeros(n, dtype=bool)
    for mask in absorbing:
        stopped |= mask
    dead = prob0(P, np.ones(n, dtype=bool), stopped, workspace=workspace) & ~stopped
    moving = ~stopped & ~dead
    order = _grouped_order(moving, rewards)
    Q = sp.csr_matrix(P[order][:, order])
    levels = _levels(Q, moving[order], rewards[order], transpose=True, plans=workspace.solvers)
    return _forward(Q, levels, initial[order], tuple(m[order] for m in absorbing),
                    dead[order], stop, max_levels)


def _forward(P: CsrMatrix, levels: Levels, initial: FloatArray,
             absorbing: tuple[BoolArray, ...], dead: BoolArray, stop: StopRule,
             max_levels: int) -> LevelMasses:
    targets = [np.flatnonzero(mask) for mask in absorbing]
    dead_states = np.flatnonzero(dead)
    rings = [_Ring(r, states) for r, states in levels.groups]
    # One product per level: the mass leaving every positive-reward state, each taken
    # from the level its reward reaches back to, moved by the transposed rows at once.
    movers = np.concatenate([states for _, states in levels.groups] or [np.zeros(0, np.int64)])
    moved = linalg.TransposedProduct(P[movers])
    zero_dest, zero_moves = _columns_used(levels.zero_rows)
    leaving = np.zeros(movers.size)
    total = float(initial.sum())
    absorbed: list[FloatArray] = []
    done = np.zeros(len(absorbing))
    never = 0.0
    for k in range(max_levels):
        _gather(rings, k, leaving)
        here = moved(leaving)
        if k == 0:
            here += initial
        if levels.closure is not None:
            here[zero_dest] += zero_moves @ _close(levels, here[levels.zero])
            here[levels.zero] = 0.0
        absorbed.append(np.array([here[states].sum() for states in targets]))
        done += absorbed[-1]
        never += float(here[dead_states].sum())
        for ring in rings:
            ring.history[k % ring.r] = here[ring.block]
        if stop(k, done, max(0.0, total - float(done.sum()) - never)):
            break
    return LevelMasses(levels.unit, np.array(absorbed).T,
                       max(0.0, total - float(done.sum()) - never), never)


def _columns_used(rows: CsrMatrix) -> tuple[IntArray, CsrMatrix]:
    """The columns *rows* reach, and the transposed block over just those columns."""
    used = distinct(rows.indices)
    return used, sp.csr_matrix(rows[:, used].T)


@dataclass(frozen=True, slots=True)
class _Ring:
    """The mass that left the states with reward *r* on each of the last *r* levels."""

    r: int
    states: IntArray
    history: FloatArray
    #: The states as a slice where they are contiguous (after the renumbering).
    block: slice | IntArray

    def __init__(self, r: int, states: IntArray) -> None:
        object.__setattr__(self, "r", r)
        object.__setattr__(self, "states", states)
        object.__setattr__(self, "history", np.zeros((r, states.size)))
        contiguous = states.size > 0 and states[-1] - states[0] + 1 == states.size
        object.__setattr__(self, "block", slice(int(states[0]), int(states[-1]) + 1)
                           if contiguous else states)


def _gather(rings: list[_Ring], k: int, leaving: FloatArray) -> None:
    """The mass leaving each positive-reward state that arrives on level *k*."""
    start = 0
    for ring in rings:
        end = start + ring.states.size
        leaving[start:end] = ring.history[k % ring.r] if k >= ring.r else 0.0
        start = end
