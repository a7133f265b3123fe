"""Numeric kernels of the DTMC checker: matrices and masks in, arrays out.

Every kernel takes the row-stochastic CSR transition matrix *P* and boolean
state masks, never formulas (the recursion over formulas lives in
:mod:`veribattery.checker.pctl`). Unbounded properties run the qualitative
pre-pass first (:func:`prob0`, :func:`prob1`, both graph searches in C via
:mod:`scipy.sparse.csgraph`), so the linear systems are only solved on the
states whose value is strictly between the trivial ones, where they are
nonsingular.

Every kernel returns :class:`~veribattery.checker.bounds.Bounds`: point values
with certified enclosures (``docs/numerics.md``). The linear systems of
:func:`until_probs` and :func:`reach_rewards` are solved by
:mod:`~veribattery.checker.linsolve` (sparse LU with extended-precision iterative
refinement, or an iterative method), then certified by
:func:`~veribattery.checker.certify.certify_fixpoint`; when that interval is too
wide, small systems are solved exactly (:mod:`~veribattery.checker.rational`)
and larger ones tightened by interval iteration.

Step-bounded kernels iterate one sparse matrix-vector product per step, plus
one on the error radius, and stop early only at an exact fixpoint of the float
map (the next iterate equal to the current one in every bit).
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import weakref
from collections import OrderedDict
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
from scipy.sparse import csgraph

from veribattery._memory import trim_for
from veribattery._types import BoolArray, CsrMatrix, FloatArray, IntArray
from veribattery.checker import certify, linsolve
from veribattery.checker.bounds import (
    Bounds,
    current_precision,
    escalated,
    round_down,
    round_up,
)
from veribattery.errors import CheckError

if TYPE_CHECKING:
    from veribattery.checker import focus

# ---------------------------------------------------------------------------
# Memo per transition matrix: properties of one model share targets (``F "done"``
# under two reward structures) and hence graph searches and linear systems.
# Matrices are keyed by identity and forgotten with them; they must not be
# modified in place afterwards (a DTMC's never is).
# ---------------------------------------------------------------------------

#: Linear systems kept per matrix (each holds its matrix and direct solver).
#: One: consecutive properties on one set of states (two reward structures to
#: one target) and the conditional numerators still share it, and on the
#: 11x11 mission (1.4M states) keeping 4 cost 450 MB of peak (1,621 MB against
#: 1,168 MB) for no measurable time.
SYSTEMS_KEPT = 1
#: Systems with at least this many unknowns try one unrefined substitution first.
QUICK_MIN_STATES = 10_000
#: A kept system on a superset of a query's unknown states is re-used when the query
#: has at least this share of its states (a solve on it costs less than a new system).
SUPERSET_SHARE = 0.25
#: Results of ``until_probs`` kept per matrix: ``P=? [ F "success" ]`` and the
#: condition ``F "success"`` of the conditional properties are one computation.
RESULTS_KEPT = 2


@dataclass(slots=True)
class _System:
    """``I - P_mm``, the rows ``P[maybe, :]`` and the prepared solver.

    *template* is the first fixed-point map built on these rows: properties on the
    same unknown states (``R{"mt"}`` and ``R{"rc"}`` until ``"done"``) share its
    off-diagonal matrix and per-row constants.
    """

    rows: CsrMatrix
    factorization: linsolve.Factorization
    #: The unknown states of the system (a mask over all states).
    unknowns: BoolArray
    template: certify.AffineMap | None = None
    #: Certified rows of ``(I - B)^-1`` by focus position (None: its test failed).
    focus_rows: dict[int, focus.FocusRow | None] = field(default_factory=dict)

    def affine(self, known_lower: FloatArray, known_upper: FloatArray,
               offset: FloatArray | None) -> certify.AffineMap:
        """The fixed-point map on these rows with the given known values and offset."""
        F = certify.AffineMap.of(self.rows, np.flatnonzero(self.unknowns), known_lower,
                                 known_upper, offset, self.template)
        if self.template is None:  # kept without this query's vectors (every use replaces them)
            empty = np.zeros(0)
            self.template = dataclasses.replace(F, known_lower=empty, known_upper=empty,
                                                offset=None)
            # From now on the rows are the map's: the same rows without their own
            # state's entry. Every right-hand side reads known values that are 0 on
            # the unknowns, so the products are the same (one copy of the rows kept).
            self.rows = F.rows
        return F


_MaskMemo = dict[tuple[str, bytes, bytes], BoolArray]


@dataclass(slots=True)
class _Memo:
    matrix: weakref.ref[CsrMatrix]
    masks: _MaskMemo | None = None
    systems: OrderedDict[bytes, _System] = field(default_factory=OrderedDict)
    #: Keyed by the operands, escalation and the focus states (b"": every state).
    results: OrderedDict[tuple[bytes, bytes, bool, bytes], Bounds] = field(
        default_factory=OrderedDict)
    reversed: tuple[npt.NDArray[np.int64], npt.NDArray[np.integer]] | None = None
    #: Untils (keys of ``remain``, ``target``) that some query needs in every state.
    whole: set[tuple[bytes, bytes]] = field(default_factory=set)


_MEMOS: dict[int, _Memo] = {}

#: Graph-search results per sparsity pattern: the 0/1 pre-pass depends only on
#: which transitions exist, so matrices that differ only in their probabilities
#: (a sweep re-using one state space) share them. A few patterns are kept.
PATTERNS_KEPT = 4
_PATTERN_MASKS: OrderedDict[bytes, _MaskMemo] = OrderedDict()


def _pattern_key(P: CsrMatrix) -> bytes:
    """A digest of the positive entries' positions (not their values)."""
    digest = hashlib.blake2b(digest_size=20)
    digest.update(np.asarray(P.shape, dtype=np.int64).tobytes())
    digest.update(linsolve.index_digest(P.indptr, P.indices))
    digest.update(np.packbits(P.data > 0).data)
    return digest.digest()


def _pattern_masks(P: CsrMatrix) -> _MaskMemo:
    """The pre-pass memo shared by every matrix with *P*'s pattern."""
    memo = _memo(P)
    if memo.masks is None:
        key = _pattern_key(P)
        masks = _PATTERN_MASKS.get(key)
        if masks is None:
            masks = _PATTERN_MASKS[key] = {}
            while len(_PATTERN_MASKS) > PATTERNS_KEPT:
                _PATTERN_MASKS.popitem(last=False)
        else:
            _PATTERN_MASKS.move_to_end(key)
        memo.masks = masks
    return memo.masks


def _memo(P: CsrMatrix) -> _Memo:
    key = id(P)
    memo = _MEMOS.get(key)
    if memo is None or memo.matrix() is not P:
        memo = _Memo(weakref.ref(P))
        _MEMOS[key] = memo
        weakref.finalize(P, _forget, key, memo)
    return memo


def _forget(key: int, memo: _Memo) -> None:
    if _MEMOS.get(key) is memo:
        del _MEMOS[key]


def _mask_key(mask: BoolArray) -> bytes:
    return np.packbits(mask).tobytes() + mask.size.to_bytes(8, "little")


def _memoised_mask(P: CsrMatrix, kind: str, a: BoolArray, b: BoolArray,
                   compute: Callable[[], BoolArray]) -> BoolArray:
    masks = _pattern_masks(P)
    key = (kind, _mask_key(a), _mask_key(b))
    if key not in masks:
        masks[key] = compute()
    return masks[key].copy()


def _system(P: CsrMatrix, maybe: BoolArray, allowed: BoolArray | None = None) -> _System:
    """The restricted system on *maybe*, built (and its solver prepared) once per matrix.

    With *allowed*, a kept system whose unknowns *M* satisfy ``maybe <= M <= allowed``
    (and hold not many more states, :data:`SUPERSET_SHARE`) is returned instead: the
    caller guarantees that the exact values satisfy the system's equations on every
    state of *allowed* (docs/numerics.md, "Shared systems"), so solving on *M* with the
    values outside *M* known gives the same fixed point on *maybe*.
    """
    systems = _memo(P).systems
    key = _mask_key(maybe)
    found = systems.get(key)
    if found is None and allowed is not None:
        found = _superset(systems.values(), maybe, allowed)
    if found is None:
        # Make room first: the old system is freed before the new one is built, not
        # after (on the 11x11 mission each takes ~250 MB).
        while systems and len(systems) >= SYSTEMS_KEPT:
            systems.popitem(last=False)
        A64, residue, rows = linsolve.restricted_parts(P, maybe)
        unknowns = maybe.copy()
        solver = linsolve.Factorization(A64, residue, _rebuilder(P, unknowns))
        del A64, residue
        found = _System(rows, solver, unknowns)
        trim_for(maybe.size)  # the restriction's per-entry temporaries
        systems[key] = found
    else:
        systems.move_to_end(_mask_key(found.unknowns))
    return found


def _rebuilder(P: CsrMatrix, unknowns: BoolArray
               ) -> Callable[[], tuple[sp.csr_matrix, sp.csr_matrix]]:
    """Makes ``I - P_mm`` (float64 part and residue) again, for a solver that released it.

    *P* is held weakly, as by the memo (a system does not outlive its matrix); the
    unmemoised restriction gives the same matrix bit for bit without making a plan.
    """
    matrix = weakref.ref(P)

    def rebuild() -> tuple[sp.csr_matrix, sp.csr_matrix]:
        P = matrix()
        if P is None:  # pragma: no cover -- the memo forgets a system with its matrix
            raise CheckError("the transition matrix of a kept linear system is gone")
        A64, residue, _ = linsolve.unplanned_parts(P, unknowns)
        return A64, residue

    return rebuild


def _superset(systems: Iterable[_System], maybe: BoolArray,
              allowed: BoolArray) -> _System | None:
    """A kept system whose unknowns lie between *maybe* and *allowed* (None if none)."""
    wanted = int(np.count_nonzero(maybe))
    for system in systems:
        unknowns = system.unknowns
        if (unknowns.size == maybe.size
                and wanted >= SUPERSET_SHARE * np.count_nonzero(unknowns)
                and not np.any(maybe & ~unknowns) and not np.any(unknowns & ~allowed)):
            return system
    return None


def shared_system(P: CsrMatrix, maybe: BoolArray, allowed: BoolArray) -> _System:
    """The linear system to solve the unknowns *maybe* on: a kept one on a superset
    *M* of them inside *allowed*, or a new one on *maybe* (see :func:`_system`).

    For kernels outside this module (conditional numerators), so that they share the
    factorisation of an unconditional property. ``.unknowns`` is *M*; ``.rows`` the
    rows ``P[M, :]`` (once a map is made, without each row's own diagonal entry: use
    them with known values that are 0 on *M*); ``.factorization`` the solver of
    ``I - P_MM``; ``.affine`` its maps.
    """
    return _system(P, maybe, allowed)


def prepare_reach(P: CsrMatrix, target: BoolArray) -> BoolArray:
    """Build (and keep) the system of ``R=? [ F target ]`` now, so that queries checked
    before it can be solved on it; returns its unknowns (empty: nothing to solve)."""
    maybe = reach_unknowns(P, target)
    if maybe.any():
        _system(P, maybe)
    return maybe


def prepare_untils(P: CsrMatrix, untils: list[tuple[BoolArray, BoolArray]]) -> bool:
    """Build (and keep) one system on the union of several untils' unknowns, so that each
    is solved on it (as a superset, or with pinned rows: docs/numerics.md, "Shared
    systems") instead of on a system of its own -- when that union holds at least
    ``QUICK_MIN_STATES`` unknowns, each until has its ``SUPERSET_SHARE`` of them, and
    the union's matrix is triangular in some order (then it is nonsingular: its
    diagonal, the leaving probabilities, is positive). Returns whether it was kept.

    :param untils: ``(remain, target)`` of each unbounded until.
    """
    maybes = [m for m in (until_unknowns(P, *until)[0] for until in untils) if m.any()]
    if len(maybes) < 2:
        return False
    union = np.logical_or.reduce(maybes)
    size = int(np.count_nonzero(union))
    if size < QUICK_MIN_STATES or any(np.count_nonzero(m) < SUPERSET_SHARE * size
                                      for m in maybes):
        return False
    system = _system(P, union)
    if system.factorization.triangular:
        return True
    _memo(P).systems.pop(_mask_key(union), None)  # not worth keeping for them
    return False


def until_unknowns(P: CsrMatrix, remain: BoolArray,
                   target: BoolArray) -> tuple[BoolArray, BoolArray]:
    """The unknowns of ``remain U target`` and the states whose exact values satisfy its
    equations (``remain & !target``), from the memoised pre-pass."""
    no = prob0(P, remain, target)
    yes = prob1(P, remain, target, no)
    return ~(no | yes), remain & ~target


def reach_unknowns(P: CsrMatrix, target: BoolArray) -> BoolArray:
    """The states of ``R=? [ F target ]``'s linear system: target almost sure, not in it."""
    everywhere = np.ones(P.shape[0], dtype=bool)
    sure = prob1(P, everywhere, target, prob0(P, everywhere, target))
    return sure & ~target


def _restrict(found: Bounds, unknowns: BoolArray, maybe: BoolArray) -> Bounds:
    """*found* (over the states of *unknowns*) at the states of *maybe* only."""
    if found.value.size == np.count_nonzero(maybe):
        return found
    where = np.flatnonzero(maybe[unknowns])
    return Bounds(found.value[where], found.lower[where], found.upper[where])


# ---------------------------------------------------------------------------
# Qualitative pre-pass: graph searches
# ---------------------------------------------------------------------------


def _backward_reach(P: CsrMatrix, through: BoolArray, seeds: BoolArray) -> BoolArray:
    """States with a path to *seeds* whose states before the last lie in *through*.

    One breadth-first search over the reversed graph from a virtual source joined to
    every seed, O(n + m) in C whatever the depth of the chain. Only the states of
    *seeds* or *through* are expanded (their predecessors kept); a state outside both
    may be reached as a leaf, so the answer is the reached states among those two (a
    reached state of *through* was entered from an expanded, truly reached state).
    """
    n = P.shape[0]
    if not seeds.any():
        return np.zeros(n, dtype=bool)
    indptr, indices = _reversed(P)
    expand = seeds | through
    lengths = np.diff(indptr)
    kept = indices[np.repeat(expand, lengths)]
    seed_idx = np.flatnonzero(seeds).astype(kept.dtype)
    pointer = np.zeros(n + 2, dtype=np.int64)
    np.cumsum(np.where(expand, lengths, 0), out=pointer[1 : n + 1])
    pointer[n + 1] = pointer[n] + seed_idx.size
    graph = sp.csr_matrix((np.ones(pointer[-1]), np.concatenate([kept, seed_idx]), pointer),
                          shape=(n + 1, n + 1))
    order = csgraph.breadth_first_order(graph, n, directed=True, return_predecessors=False)
    reached = np.zeros(n + 1, dtype=bool)
    reached[order] = True
    return reached[:n] & expand


def _reversed(P: CsrMatrix) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.integer]]:
    """The predecessors of every state along positive entries (CSR of the transposed
    pattern), built once per matrix."""
    memo = _memo(P)
    if memo.reversed is None:
        pattern = sp.csr_matrix((np.asarray(P.data > 0, dtype=np.int8), P.indices, P.indptr),
                                shape=P.shape)  # shares P's index arrays: not edited
        by_column = pattern.tocsc()  # new arrays: column j lists the i with P[i, j] stored
        by_column.eliminate_zeros()  # then only the positive ones
        memo.reversed = (by_column.indptr.astype(np.int64), by_column.indices)
    return memo.reversed


def prob0(P: CsrMatrix, remain: BoolArray, target: BoolArray) -> BoolArray:
    """States where ``remain U target`` holds with probability exactly 0.

    :param P: row-stochastic CSR transition matrix.
    :param remain: states that may be passed through before *target*.
    :param target: states to reach.
    :return: mask of the states that cannot reach *target* inside *remain*.
    """
    return _memoised_mask(P, "prob0", remain, target,
                          lambda: ~_backward_reach(P, remain & ~target, target))


def prob1(P: CsrMatrix, remain: BoolArray, target: BoolArray, no: BoolArray) -> BoolArray:
    """States where ``remain U target`` holds with probability exactly 1.

    In a finite DTMC the probability is below 1 exactly when a ``remain & !target``
    path leads to a probability-0 state, so this is the complement of one more
    backward search.

    :param P: row-stochastic CSR transition matrix.
    :param remain: states that may be passed through before *target*.
    :param target: states to reach.
    :param no: the result of :func:`prob0` for the same arguments.
    :return: mask of the states that reach *target* inside *remain* almost surely.
    """
    through = remain & ~target
    return _memoised_mask(P, "prob1", through, no, lambda: ~_backward_reach(P, through, no))


# ---------------------------------------------------------------------------
# Unbounded properties: pre-pass, then a certified linear system (see certify)
# ---------------------------------------------------------------------------


def until_probs(P: CsrMatrix, remain: BoolArray, target: BoolArray,
                focus_states: IntArray | None = None) -> Bounds:
    """Probability of ``remain U target`` in every state, with certified bounds.

    prob0/prob1 fix the states with value 0 and 1; the rest solve
    ``(I - P_mm) x = P_my 1`` under linsolve's residual rule, and the answer is
    certified (then refined if needed) by :func:`_certified`.

    :param P: row-stochastic CSR transition matrix.
    :param remain: states that may be passed through before *target*.
    :param target: states to reach.
    :param focus_states: the only states whose bounds the caller reads (the initial
        ones), or None; elsewhere the bounds may be the trivial ones (:mod:`focus`).
    :return: probabilities in [0, 1] and their certified enclosures.
    """
    kept = _memo(P)
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
        found = memo[key] = _until_probs(P, remain, target, focus_states)
        while len(memo) > RESULTS_KEPT:
            memo.popitem(last=False)
    else:
        memo.move_to_end(key)
    return found


def need_whole(P: CsrMatrix, remain: BoolArray, target: BoolArray) -> None:
    """Mark ``remain U target`` as needed in every state (a conditional property's
    condition), so that a query of it asked at the initial states only computes that
    once, not a focused copy first."""
    _memo(P).whole.add((_mask_key(remain), _mask_key(target)))


def _until_probs(P: CsrMatrix, remain: BoolArray, target: BoolArray,
                 focus_states: IntArray | None) -> Bounds:
    no = prob0(P, remain, target)
    yes = prob1(P, remain, target, no)
    result = yes.astype(np.float64)
    maybe = ~(no | yes)
    if not maybe.any():
        return Bounds.exact(result)
    pinned = _pinned_until(P, maybe, remain & ~target, result, focus_states)
    if pinned is not None:
        return pinned
    # Every state of remain & !target satisfies x = P x, its yes and no states included.
    system = _system(P, maybe, remain & ~target)
    known = np.where(system.unknowns, 0.0, result)
    F = system.affine(known, known, None)
    found = _certified(F, system, known, None, (0.0, 1.0), focus_states)
    return _spread(result, maybe, _restrict(found, system.unknowns, maybe))


def _pinned_until(P: CsrMatrix, maybe: BoolArray, allowed: BoolArray,
                  result: FloatArray, focus_states: IntArray | None) -> Bounds | None:
    """The until's values solved on a kept system that holds *maybe* and also states
    outside *allowed* (the target states inside ``R=? [ F "done" ]``'s system, for the
    recharge cap's ``P=? [ F rc=RC_MAX ]``), those rows pinned to their known values
    *result* (docs/numerics.md, "Shared systems"); None when there is no such system
    or the quick certificate does not succeed on it (the caller builds its own).
    """
    system = _pinnable(_memo(P).systems.values(), maybe, allowed)
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


def _pinnable(systems: Iterable[_System], maybe: BoolArray,
              allowed: BoolArray) -> _System | None:
    """A kept system (of at least ``QUICK_MIN_STATES`` unknowns) whose unknowns hold
    *maybe* and some states outside *allowed*, with *maybe* its ``SUPERSET_SHARE``."""
    wanted = int(np.count_nonzero(maybe))
    for system in systems:
        unknowns = system.unknowns
        size = int(np.count_nonzero(unknowns))
        if (unknowns.size == maybe.size and size >= QUICK_MIN_STATES
                and wanted >= SUPERSET_SHARE * size
                and not np.any(maybe & ~unknowns) and np.any(unknowns & ~allowed)):
            return system
    return None


def reach_rewards(P: CsrMatrix, rewards: FloatArray, target: BoolArray,
                  focus_states: IntArray | None = None) -> Bounds:
    """Expected reward accumulated until *target* is first reached (``R=? [F target]``).

    PRISM semantics: 0 in *target* states; infinity in states that reach
    *target* with probability below 1, even where the reward is 0. The reward
    of the step leaving a state is counted; that of the target state is not.

    :param P: row-stochastic CSR transition matrix.
    :param rewards: reward earned per step taken from each state (state + transition).
    :param target: states to reach.
    :param focus_states: as for :func:`until_probs`.
    :return: expected rewards, ``inf`` where *target* is not almost sure, with bounds.
    """
    maybe = reach_unknowns(P, target)
    result = np.where(maybe | target, 0.0, np.inf)
    if not maybe.any():
        return Bounds.exact(result)
    # Successors of almost-sure states are almost sure, so the system is closed
    # and every known value it reads is a target's 0.
    system = _system(P, maybe)
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
        b += linsolve.extended_product(system.rows, known)
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
    if F.states.size < QUICK_MIN_STATES:
        return None
    floor, ceiling = trivial
    # The trivial bounds as 0-d arrays: they broadcast (two fewer vectors at the peak).
    return quick_bounds(F, system.factorization, _right_side(system, known, offset, np.float64),
                        np.full((), floor), np.full((), ceiling),
                        focus_rows(system, F, focus_states))


def quick_bounds(F: certify.AffineMap, solver: linsolve.QuickSolver,
                 b: npt.NDArray[np.floating], floor: FloatArray, ceiling: FloatArray,
                 rows: Sequence[focus.FocusRow] | None = None) -> Bounds | None:
    """The fixed point of *F* (system ``solver.A x = b``) from one unrefined substitution,
    certified by :func:`certify.quick_certificate` -- or None when the system is
    below ``QUICK_MIN_STATES``, the pair fails its test or is not precise enough.

    With *rows* (:func:`focus_rows`), bounds tight at their focus states only are tried
    first: from the rows alone where they are bounded on both sides
    (:func:`focus.answered_bounds`, no solve), else from the approximate solution's
    defect (:func:`focus.focused_bounds`). For the kernels here and in
    :mod:`~veribattery.checker.conditional`.
    """
    if F.states.size < QUICK_MIN_STATES:
        return None
    b64 = np.asarray(b, dtype=np.float64)
    if rows is not None:  # answers at a few states only: focus is imported then
        from veribattery.checker import focus
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
    trim_for(F.states.size)  # the certificate's temporaries, before the next vectors
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
    from veribattery.checker import rational  # the last resort: imported when reached

    exact = rational.solve_exact(F)
    if exact is not None:
        return Bounds(*exact)
    low, high = certify.interval_iteration(F, low, high, found.value,
                                           lambda b: b.precise_states())
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
    if focus_states is None or F.states.size < QUICK_MIN_STATES:
        return None
    from veribattery.checker import focus  # answers at a few states only

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
    """Full-length bounds: *known* (exact) outside *unknown*, *found* inside."""
    value, lower, upper = known.copy(), known.copy(), known.copy()
    value[unknown], lower[unknown], upper[unknown] = found.value, found.lower, found.upper
    return Bounds(value, lower, upper)


# ---------------------------------------------------------------------------
# Step-bounded kernels: iterate, carrying a rigorous forward error bound
# ---------------------------------------------------------------------------


def _step_power(M: CsrMatrix, start: Bounds, offset: FloatArray, k: int) -> Bounds:
    """``k`` steps of ``x <- offset + M x`` from *start*, with a certified radius.

    The radius *e* bounds ``|x - exact|`` componentwise: ``e <- M e + delta`` where
    *delta* bounds the rounding of the step (:func:`certify.enclose_product`).
    The iteration stops early at an exact fixpoint of the float map; the
    remaining steps are accounted normwise with ``||M||_inf`` (rounded up).
    """
    if escalated() and np.array_equal(start.lower, start.upper):
        # Asked for exact bounds: iterate in rational arithmetic when small enough.
        from veribattery.checker import rational

        exact = rational.power_exact(M, start.value, offset, k)
        if exact is not None:
            return Bounds(*exact)
    terms = certify.row_terms(M)
    normwise = _step_power_normwise(M, start, offset, k, terms)
    if normwise is not None:
        return normwise
    x = start.value
    radius = np.maximum(round_up(x - start.lower), round_up(start.upper - x))
    for step in range(k):
        following, low, high = certify.enclose_product(M, x, offset, terms)
        rounding = np.maximum(high - following, following - low)
        if np.array_equal(following, x):
            return _finish(M, x, radius, rounding, k - step)
        radius = round_up(certify.enclose_product(M, radius, rounding, terms)[2])
        x = following
    return _finish(M, x, radius, np.zeros_like(x), 0)


def _step_power_normwise(M: CsrMatrix, start: Bounds, offset: FloatArray, k: int,
                         terms: FloatArray) -> Bounds | None:
    """:func:`_step_power` with one radius for every state: one product per step
    instead of two (the componentwise radius needs ``M e`` too), or None when that
    radius would not meet the required absolute precision everywhere.

    ``|x_j - exact_j| <= r_j`` for all states gives ``|M (x - exact)| <= ||M||_inf r_j``,
    so ``r <- ||M||_inf r + max(delta)`` (each operation rounded up) bounds every
    state's error after the step; *delta* is the step's rounding as above.
    """
    _, absolute = current_precision()
    x = start.value
    radius = float(np.max(np.maximum(round_up(x - start.lower), round_up(start.upper - x)),
                          initial=0.0))
    rho = max(1.0, certify.spectral_cap(M))
    for step in range(k):
        if not 2 * radius <= absolute:  # (NaN too) the componentwise radius may still be
            return None
        following, low, high = certify.enclose_product(M, x, offset, terms)
        rounding = float(np.max(np.maximum(high - following, following - low), initial=0.0))
        if np.array_equal(following, x):
            return _finish(M, x, np.full_like(x, radius), np.full_like(x, rounding), k - step)
        grown = math.nextafter(rho * radius, math.inf)  # each operation rounded up
        radius = math.nextafter(grown + rounding, math.inf)
        x = following
    if not 2 * radius <= absolute:
        return None
    return _finish(M, x, np.full_like(x, radius), np.zeros_like(x), 0)


def _finish(M: CsrMatrix, x: FloatArray, radius: FloatArray, rounding: FloatArray,
            remaining: int) -> Bounds:
    """Bounds after *remaining* more steps at a float fixpoint *x* (normwise)."""
    if remaining:
        rho = max(1.0, certify.spectral_cap(M))
        try:
            growth = rho**remaining
        except OverflowError:
            growth = np.inf
        extra = growth * (float(np.max(radius)) + remaining * float(np.max(rounding)))
        radius = round_up(np.full_like(x, extra)) if extra > 0 else radius
    with np.errstate(invalid="ignore"):
        return Bounds(x, round_down(x - radius), round_up(x + radius))


def _rows_in(P: CsrMatrix, mask: BoolArray) -> CsrMatrix:
    """*P* with the rows outside *mask* zeroed (those states stop moving)."""
    return sp.csr_matrix(sp.diags(mask.astype(np.float64), format="csr") @ P)


def _probabilities(found: Bounds) -> Bounds:
    """Probabilities: the value clipped to [0, 1], lower bounds to 0.

    Upper bounds are not clipped to 1: a stored row may sum to a little more
    than 1 in exact arithmetic, and the bounds are for the model as stored.
    """
    lower = np.maximum(found.lower, 0.0)
    return Bounds.around(np.clip(found.value, 0.0, 1.0), lower, found.upper)


def next_probs(P: CsrMatrix, target: BoolArray) -> Bounds:
    """Probability that the next state is in *target* (``X target``).

    :param P: row-stochastic CSR transition matrix.
    :param target: states to reach in one step.
    """
    value, lower, upper = certify.enclose_product(P, target.astype(np.float64))
    return _probabilities(Bounds(value, lower, upper))


def bounded_until_probs(P: CsrMatrix, remain: BoolArray, target: BoolArray,
                        k: int) -> Bounds:
    """Probability of reaching *target* within *k* steps while staying in *remain*.

    :param P: row-stochastic CSR transition matrix.
    :param remain: states that may be passed through before *target*.
    :param target: states to reach.
    :param k: step bound (``U<=k``), at least 0.
    """
    moving = _rows_in(P, remain & ~target)
    near = _within_steps(moving, target, k)
    if not near.any():
        return Bounds.exact(np.zeros(P.shape[0]))
    hit = target.astype(np.float64)
    if near.all():
        return _probabilities(_step_power(moving, Bounds.exact(hit), hit, k))
    # States farther than k steps from the target have probability exactly 0, and
    # so has every such successor of a nearer state at each of the k iterations:
    # iterating on the near states alone gives the same values (Storm does the same).
    index = np.flatnonzero(near)
    sub = sp.csr_matrix(moving[index][:, index])
    del moving
    found = _step_power(sub, Bounds.exact(hit[index]), hit[index], k)
    return _probabilities(_spread(np.zeros(P.shape[0]), near, found))


def _within_steps(moving: CsrMatrix, target: BoolArray, k: int) -> BoolArray:
    """States with a path of at most *k* steps of *moving* (rows of the states that
    may move) to *target*: a breadth-first search over the reversed graph cut at
    depth *k* (in C; any superset would do, so stored zeros may count as edges)."""
    n = moving.shape[0]
    if not target.any():
        return np.zeros(n, dtype=bool)
    # The transpose is a CSC view of the same arrays; csgraph makes one CSR copy.
    distance = csgraph.dijkstra(moving.T, directed=True, indices=np.flatnonzero(target),
                                unweighted=True, min_only=True, limit=k + 0.5)
    return np.asarray(np.isfinite(distance), dtype=bool)


def lower_bounded_until_probs(P: CsrMatrix, remain: BoolArray, target: BoolArray,
                              k: int) -> Bounds:
    """Probability of ``remain U>=k target``: *remain* for the first *k* steps, then until.

    :param P: row-stochastic CSR transition matrix.
    :param remain: states that must hold before *target* is reached.
    :param target: states to reach, at step *k* or later.
    :param k: lower step bound, at least 0.
    """
    later = until_probs(P, remain, target)
    found = _step_power(_rows_in(P, remain), later, np.zeros(P.shape[0]), k)
    return _probabilities(found)


def interval_until_probs(P: CsrMatrix, remain: BoolArray, target: BoolArray,
                         low: int, high: int) -> Bounds:
    """Probability of ``remain U[low,high] target``: *remain* for the first *low* steps,
    then *target* within ``high - low`` more steps, passing through *remain*.

    :param P: row-stochastic CSR transition matrix.
    :param remain: states that must hold before *target* is reached.
    :param target: states to reach, at a step in ``[low, high]``.
    :param low: first step that counts, at least 0.
    :param high: last step that counts, at least *low*.
    """
    later = bounded_until_probs(P, remain, target, high - low)
    found = _step_power(_rows_in(P, remain), later, np.zeros(P.shape[0]), low)
    return _probabilities(found)


def cumulative_rewards(P: CsrMatrix, rewards: FloatArray, k: int) -> Bounds:
    """Expected reward of the first *k* steps (``C<=k``).

    :param P: row-stochastic CSR transition matrix.
    :param rewards: reward earned per step taken from each state (state + transition).
    :param k: number of steps, at least 0.
    """
    offset = np.asarray(rewards, dtype=np.float64)
    return _step_power(P, Bounds.exact(np.zeros_like(offset)), offset, k)


def instantaneous_rewards(P: CsrMatrix, state_rewards: FloatArray, k: int) -> Bounds:
    """Expected state reward of the state occupied at step *k* (``I=k``).

    :param P: row-stochastic CSR transition matrix.
    :param state_rewards: reward of being in each state.
    :param k: the step, at least 0.
    """
    start = np.asarray(state_rewards, dtype=np.float64)
    return _step_power(P, Bounds.exact(start), np.zeros_like(start), k)


def absorption(P: CsrMatrix, fixed: BoolArray, known: Bounds) -> Bounds:
    """``x = P x`` off *fixed*, ``x = known`` on it: each state's expectation of the
    value of the *fixed* state where it is absorbed, with certified bounds.

    Every state outside *fixed* must reach *fixed* almost surely (the BSCCs, for
    long-run values), so the fixed point is unique; it is certified like
    :func:`until_probs`, with the known values as intervals.

    :param P: row-stochastic CSR transition matrix.
    :param fixed: the states whose values are known.
    :param known: the values (meaningful on *fixed* only), non-negative.
    """
    lower = np.where(fixed, known.lower, 0.0)
    upper = np.where(fixed, known.upper, 0.0)
    maybe = ~fixed & ~prob0(P, np.ones(P.shape[0], dtype=bool), fixed & (upper > 0))
    if not maybe.any():
        return Bounds.around(np.where(fixed, known.value, 0.0), lower, upper)
    # x = P x holds on every state outside fixed (0 where no positive value is reachable).
    system = _system(P, maybe, ~fixed)
    F = system.affine(lower, upper, None)
    point = np.where(fixed, known.value, 0.0)
    found = _certified(F, system, point, None, (0.0, float(np.max(upper))))
    found = _restrict(found, system.unknowns, maybe)
    value, low, high = point.copy(), lower.copy(), upper.copy()
    value[maybe], low[maybe], high[maybe] = found.value, found.lower, found.upper
    return Bounds.around(value, low, high)
