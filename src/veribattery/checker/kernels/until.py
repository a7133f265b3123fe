"""Unbounded until and reachability rewards: the pre-pass, then a certified linear system.

:func:`until_probs` and :func:`reach_rewards` solve the system on the unknown states
with :mod:`~veribattery.checker.linalg` (sparse LU with extended-precision iterative
refinement, or an iterative method), then certify it with
:func:`~veribattery.checker.certify.fixpoint.certify_fixpoint`; when that interval is
too wide, small systems are solved exactly (:mod:`~veribattery.checker.linalg.rational`)
and larger ones tightened by interval iteration.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from veribattery._types import BoolArray, CsrMatrix, FloatArray, IntArray
from veribattery.checker import certify, linalg
from veribattery.checker.certify.bounds import Bounds, escalated
from veribattery.checker.kernels import systems
from veribattery.checker.kernels.prepass import prob0, prob1, reach_unknowns
from veribattery.checker.kernels.systems import (
    _mask_key,
    _restrict,
    _system,
)
from veribattery.errors import CheckError

if TYPE_CHECKING:
    from veribattery.checker.certify import focus
    from veribattery.checker.kernels.systems import _System
    from veribattery.checker.workspace import Workspace


#: Results of ``until_probs`` kept per matrix: ``P=? [ F "success" ]`` and the
#: condition ``F "success"`` of the conditional properties are one computation.
RESULTS_KEPT = 2
# ---------------------------------------------------------------------------
# Unbounded properties: pre-pass, then a certified linear system (see certify)
# ---------------------------------------------------------------------------


def until_probs(P: CsrMatrix, remain: BoolArray, target: BoolArray,
                focus_states: IntArray | None = None, *, workspace: Workspace) -> Bounds:
    """Probability of ``remain U target`` in every state, with certified bounds.

    prob0/prob1 fix the states with value 0 and 1; the rest solve
    ``(I - P_mm) x = P_my 1`` under the residual rule of
    :mod:`~veribattery.checker.linalg.factorization`, and the answer is
    certified (then refined if needed) by :func:`_certified`.

    :param P: row-stochastic CSR transition matrix.
    :param remain: states that may be passed through before *target*.
    :param target: states to reach.
    :param focus_states: the only states whose bounds the caller reads (the initial
        ones), or None; elsewhere the bounds may be the trivial ones (:mod:`focus`).
    :param workspace: where the pre-pass, the linear system and the result are kept
        for later queries on *P*.
    :return: probabilities in [0, 1] and their certified enclosures.
    """
    kept = workspace.kernels.of(P)
    memo = kept.results
    operands = (_mask_key(remain), _mask_key(target))
    if operands in kept.whole:
        focus_states = None  # computed once, for both
    key = (*operands, escalated(), b"")
    found = memo.get(key)  # a whole vector serves a focused query too
    if found is None and focus_states is not None:
        key = (*operands, escalated(), focus_states.tobytes())
        found = memo.get(key)
    if found is None:
        found = memo[key] = _until_probs(P, remain, target, focus_states, workspace)
        while len(memo) > RESULTS_KEPT:
            memo.popitem(last=False)
    else:
        memo.move_to_end(key)
    return found


def need_whole(P: CsrMatrix, remain: BoolArray, target: BoolArray, *,
               workspace: Workspace) -> None:
    """Mark ``remain U target`` as needed in every state (a conditional property's
    condition), so that a query of it asked at the initial states only computes that
    once, not a focused copy first."""
    workspace.kernels.of(P).whole.add((_mask_key(remain), _mask_key(target)))


def _until_probs(P: CsrMatrix, remain: BoolArray, target: BoolArray,
                 focus_states: IntArray | None, workspace: Workspace) -> Bounds:
    no = prob0(P, remain, target, workspace=workspace)
    yes = prob1(P, remain, target, no, workspace=workspace)
    result = yes.astype(np.float64)
    maybe = ~(no | yes)
    if not maybe.any():
        return Bounds.exact(result)
    pinned = _pinned_until(P, maybe, remain & ~target, result, focus_states, workspace)
    if pinned is not None:
        return pinned
    # Every state of remain & !target satisfies x = P x, its yes and no states included.
    system = _system(P, maybe, remain & ~target, workspace=workspace)
    known = np.where(system.unknowns, 0.0, result)
    F = system.affine(known, known, None)
    found = _certified(F, system, known, None, (0.0, 1.0), focus_states)
    del F, known  # full-length: not alive beside the answer's three (8 MB each per 10^6 states)
    return _spread(result, maybe, _restrict(found, system.unknowns, maybe))


def _pinned_until(P: CsrMatrix, maybe: BoolArray, allowed: BoolArray, result: FloatArray,
                  focus_states: IntArray | None, workspace: Workspace) -> Bounds | None:
    """The until's values solved on a kept system that holds *maybe* and also states
    outside *allowed* (the target states inside ``R=? [ F "done" ]``'s system, for the
    recharge cap's ``P=? [ F rc=RC_MAX ]``), those rows pinned to their known values
    *result* (docs/numerics.md, "Shared systems"); None when there is no such system
    or the quick certificate does not succeed on it (the caller builds its own).
    """
    system = _pinnable(workspace.kernels.of(P).systems.values(), maybe, allowed)
    if system is None:
        return None
    unknowns = system.unknowns
    local = ~allowed[unknowns]  # the pinned states, among the system's
    solver = system.factorization.pinned(local)
    if solver is None:
        return None
    where = np.flatnonzero(local)
    values = result[unknowns][where]
    known = np.where(unknowns, 0.0, result)
    F = certify.PinnedMap.around(system.affine(known, known, None), where, values)
    b = _right_side(system, known, None, np.float64)
    b[where] = values
    # The system's rows of (I - B)^-1 bound the pinned map's from above (docs/numerics.md).
    rows = focus_rows(system, F, focus_states)
    found = quick_bounds(F, solver, b, np.full((), 0.0), np.full((), 1.0),
                         None if rows is None else tuple(row.above_only() for row in rows))
    if found is None:
        return None
    return _spread(result, maybe, _restrict(found, unknowns, maybe))


def _pinnable(candidates: Iterable[_System], maybe: BoolArray,
              allowed: BoolArray) -> _System | None:
    """A kept system (of at least ``QUICK_MIN_STATES`` unknowns) whose unknowns hold
    *maybe* and some states outside *allowed*, with *maybe* its ``SUPERSET_SHARE``."""
    wanted = int(np.count_nonzero(maybe))
    for system in candidates:
        unknowns = system.unknowns
        size = int(np.count_nonzero(unknowns))
        if (unknowns.size == maybe.size and size >= systems.QUICK_MIN_STATES
                and wanted >= systems.SUPERSET_SHARE * size
                and not np.any(maybe & ~unknowns) and np.any(unknowns & ~allowed)):
            return system
    return None


def reach_rewards(P: CsrMatrix, rewards: FloatArray, target: BoolArray,
                  focus_states: IntArray | None = None, *, workspace: Workspace) -> Bounds:
    """Expected reward accumulated until *target* is first reached (``R=? [F target]``).

    PRISM semantics: 0 in *target* states; infinity in states that reach
    *target* with probability below 1, even where the reward is 0. The reward
    of the step leaving a state is counted; that of the target state is not.

    :param P: row-stochastic CSR transition matrix.
    :param rewards: reward earned per step taken from each state (state + transition).
    :param target: states to reach.
    :param focus_states: as for :func:`until_probs`.
    :param workspace: as for :func:`until_probs`.
    :return: expected rewards, ``inf`` where *target* is not almost sure, with bounds.
    """
    maybe = reach_unknowns(P, target, workspace=workspace)
    result = np.where(maybe | target, 0.0, np.inf)
    if not maybe.any():
        return Bounds.exact(result)
    # Successors of almost-sure states are almost sure, so the system is closed
    # and every known value it reads is a target's 0.
    system = _system(P, maybe, workspace=workspace)
    offset = np.asarray(rewards[maybe], dtype=np.float64)
    zeros = np.zeros(P.shape[0])
    F = system.affine(zeros, zeros, offset)
    floor = 0.0 if np.all(offset >= 0) else -np.inf
    return _spread(result, maybe,
                   _certified(F, system, None, offset, (floor, np.inf), focus_states))


def _point(system: _System, b: npt.NDArray[np.longdouble]) -> FloatArray | None:
    """The fast path's approximate solution (None when no solver was accepted)."""
    try:
        return system.factorization.solve(b)
    except CheckError:
        return None


def _right_side(system: _System, known: FloatArray | None, offset: FloatArray | None,
                dtype: type[np.floating]) -> npt.NDArray[np.floating]:
    """``offset + P_m,known known`` (the system's right-hand side) in *dtype*."""
    b = np.zeros(system.rows.shape[0], dtype=dtype)
    if known is not None and dtype == np.longdouble:  # no extended copy of the rows
        b += linalg.extended_product(system.rows, known)
    elif known is not None:
        b += system.rows @ known.astype(dtype)
    if offset is not None:
        b += offset.astype(dtype)
    return b


def _quick(F: certify.AffineMap, system: _System, known: FloatArray | None,
           offset: FloatArray | None, trivial: tuple[float, float],
           focus_states: IntArray | None) -> Bounds | None:
    """One substitution with the direct solver, certified by two products -- or None.

    No extended-precision refinement: when the certified interval already meets
    the precision it is the answer; otherwise :func:`_certified` goes the long way.
    Systems below ``QUICK_MIN_STATES`` unknowns always go that way: there the
    refinement costs next to nothing and makes the point value correct to the last
    bit wherever ``cond(A) * 1e-16 < 1`` (the interval is certified either way).
    """
    if F.states.size < systems.QUICK_MIN_STATES:
        return None
    floor, ceiling = trivial
    # The trivial bounds as 0-d arrays: they broadcast (two fewer vectors at the peak).
    return quick_bounds(F, system.factorization, _right_side(system, known, offset, np.float64),
                        np.full((), floor), np.full((), ceiling),
                        focus_rows(system, F, focus_states))


def quick_bounds(F: certify.AffineMap, solver: linalg.QuickSolver,
                 b: npt.NDArray[np.floating], floor: FloatArray, ceiling: FloatArray,
                 rows: Sequence[focus.FocusRow] | None = None) -> Bounds | None:
    """The fixed point of *F* (system ``solver.A x = b``) from one unrefined substitution,
    certified by :func:`certify.quick_certificate` -- or None when the system is
    below ``QUICK_MIN_STATES``, the pair fails its test or is not precise enough.

    With *rows* (:func:`focus_rows`), bounds tight at their focus states only are tried
    first: from the rows alone where they are bounded on both sides
    (:func:`focus.answered_bounds`, no solve), else from the approximate solution's
    defect (:func:`focus.focused_bounds`). For the kernels here and in
    :mod:`~veribattery.checker.kernels.conditional`.
    """
    if F.states.size < systems.QUICK_MIN_STATES:
        return None
    b64 = np.asarray(b, dtype=np.float64)
    if rows is not None:  # answers at a few states only: focus is imported then
        from veribattery.checker.certify import focus
    if rows and all(row.lower is not None for row in rows):
        answered = focus.answered_bounds(F, rows, b64, floor, ceiling)
        if answered is not None:
            return answered
    x = solver.approximate(b64)
    if x is None:
        return None
    x = np.clip(x, floor, ceiling)
    if rows is not None:
        focused = focus.focused_bounds(F, x, rows, floor, ceiling)
        if focused is not None:
            return focused
    found = None
    for margin in solver.margins_for(b, x):
        pair = certify.quick_certificate(F, x, margin, floor, ceiling)
        found = None if pair is None else Bounds.around(x, *pair)
        del pair
        if found is not None and found.precise_states().all():
            break
        found = None
    return found


def _certified(F: certify.AffineMap, system: _System, known: FloatArray | None,
               offset: FloatArray | None, trivial: tuple[float, float],
               focus_states: IntArray | None = None) -> Bounds:
    """Certified bounds of the fixed point of *F* (right-hand side ``offset + P known``),
    escalating until precise.

    0. one unrefined substitution, certified cheaply (:func:`_quick`);
    1. the refined solution, certified (:func:`certify.certify_fixpoint`);
    2. if too wide, solve the system exactly when it is small (:mod:`rational`);
    3. otherwise tighten by interval iteration, and return what it reached.
    """
    quick = _quick(F, system, known, offset, trivial, focus_states)
    if quick is not None:
        return quick
    floor, ceiling = trivial
    x = _point(system, _right_side(system, known, offset, np.longdouble))
    x = None if x is None else np.clip(x, floor, ceiling)
    n = F.states.size
    low, high = np.full(n, floor), np.full(n, ceiling)
    if x is not None:
        correct = system.factorization.correction
        low, high = certify.certify_fixpoint(F, x, correct, low, high)
    found = Bounds.around(x if x is not None else low, low, high)
    if found.precise_states().all():
        return found
    from veribattery.checker.linalg import rational  # the last resort: imported when reached

    exact = rational.solve_exact(F)
    if exact is not None:
        return Bounds(*exact)
    low, high = certify.interval_iteration(F, low, high, found.value,
                                           lambda b: b.precise_states(),
                                           system.factorization.monitor)
    if x is None:  # no float solution: the midpoint where the interval is finite
        with np.errstate(invalid="ignore", over="ignore"):
            middle = low + (high - low) / 2
        return Bounds.around(np.where(np.isfinite(middle), middle, low), low, high)
    return Bounds.around(found.value, low, high)


def focus_rows(system: _System, F: certify.AffineMap, focus_states: IntArray | None
               ) -> tuple[focus.FocusRow, ...] | None:
    """The certified rows of ``(I - B)^-1`` of *system* for the *focus_states* among its
    unknowns (made once per system; *F* any map of it), or None: no focus, more than
    ``focus.FOCUS_MAX`` of them, a solver without a transposed substitution, or a row
    that failed its test. Then whole vectors are certified."""
    if focus_states is None or F.states.size < systems.QUICK_MIN_STATES:
        return None
    from veribattery.checker.certify import focus  # answers at a few states only

    inside = focus_states[system.unknowns[focus_states]]
    if inside.size > focus.FOCUS_MAX:
        return None
    rows = []
    for position in np.searchsorted(F.states, inside).tolist():
        if position not in system.focus_rows:
            system.focus_rows[position] = focus.certified_row(
                F, system.factorization.dual, position)
        row = system.focus_rows[position]
        if row is None:
            return None
        rows.append(row)
    return tuple(rows)


def _spread(known: FloatArray, unknown: BoolArray, found: Bounds) -> Bounds:
    """Full-length bounds: *known* (exact) outside *unknown*, *found* inside. *known*
    becomes the value (every caller passes a vector of its own: one copy fewer)."""
    value, lower, upper = known, known.copy(), known.copy()
    value[unknown], lower[unknown], upper[unknown] = found.value, found.lower, found.upper
    return Bounds(value, lower, upper)
