"""The kernels' memos and the linear systems they keep, per transition matrix.

A :class:`KernelMemos` lives in the caller's workspace: the 0/1 pre-pass per sparsity
pattern, and per matrix the restricted systems ``I - P_mm`` with their prepared
solvers, so that properties on the same unknown states share one factorisation
(:func:`shared_system`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import weakref
from collections import OrderedDict
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

from veribattery._types import BoolArray, CsrMatrix, FloatArray
from veribattery.checker import certify, linalg
from veribattery.checker.certify.bounds import Bounds
from veribattery.errors import CheckError

if TYPE_CHECKING:
    from veribattery.checker.certify import focus
    from veribattery.checker.workspace import Workspace


# ---------------------------------------------------------------------------
# Memo per transition matrix, kept in the caller's workspace: properties of one
# model share targets (``F "done"`` under two reward structures) and hence graph
# searches and linear systems. Matrices are keyed by identity and forgotten with
# them; they must not be modified in place afterwards (a DTMC's never is).
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


@dataclass(slots=True)
class _System:
    """``I - P_mm``, the rows ``P[maybe, :]`` and the prepared solver.

    *template* is the first fixed-point map built on these rows: properties on the
    same unknown states (``R{"mt"}`` and ``R{"rc"}`` until ``"done"``) share its
    off-diagonal matrix and per-row constants.
    """

    rows: CsrMatrix
    factorization: linalg.Factorization
    #: The unknown states of the system (a mask over all states).
    unknowns: BoolArray
    #: Where the maps' index work is kept for later rows of the same pattern.
    row_plans: certify.RowPlans | None = None
    template: certify.AffineMap | None = None
    #: Certified rows of ``(I - B)^-1`` by focus position (None: its test failed).
    focus_rows: dict[int, focus.FocusRow | None] = field(default_factory=dict)

    def affine(self, known_lower: FloatArray, known_upper: FloatArray,
               offset: FloatArray | None) -> certify.AffineMap:
        """The fixed-point map on these rows with the given known values and offset."""
        F = certify.AffineMap.of(self.rows, np.flatnonzero(self.unknowns), known_lower,
                                 known_upper, offset, self.template, self.row_plans)
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
    reversed: tuple[npt.NDArray[np.integer], npt.NDArray[np.integer]] | None = None
    #: Untils (keys of ``remain``, ``target``) that some query needs in every state.
    whole: set[tuple[bytes, bytes]] = field(default_factory=set)
    #: The exact checker's prepared systems and conditions (:mod:`~veribattery.checker.exact.pctl`).
    exact: dict[bytes, object] = field(default_factory=dict)


#: Graph-search results per sparsity pattern: the 0/1 pre-pass depends only on
#: which transitions exist, so matrices that differ only in their probabilities
#: (a sweep re-using one state space) share them. A few patterns are kept.
PATTERNS_KEPT = 4


class KernelMemos:
    """The kernels' memos, held by a :class:`~veribattery.checker.workspace.Workspace`:
    one per transition matrix (by identity, forgotten with the matrix or the
    workspace, whichever goes first) and the 0/1 pre-pass per sparsity pattern."""

    def __init__(self) -> None:
        self._matrices: dict[int, _Memo] = {}
        self._patterns: OrderedDict[bytes, _MaskMemo] = OrderedDict()

    @property
    def matrices(self) -> int:
        """How many matrices have a memo here."""
        return len(self._matrices)

    @property
    def empty(self) -> bool:
        """Whether nothing is kept yet."""
        return not (self._matrices or self._patterns)

    def of(self, P: CsrMatrix) -> _Memo:
        """The memo of *P*, made on first use."""
        key = id(P)
        memo = self._matrices.get(key)
        if memo is None or memo.matrix() is not P:
            memo = _Memo(weakref.ref(P))
            self._matrices[key] = memo
            # The finalizer holds these memos weakly: a workspace dropped before its
            # matrix frees its systems then, not when the matrix goes.
            weakref.finalize(P, _forget, weakref.ref(self), key)
        return memo

    def exact(self, P: CsrMatrix) -> dict[bytes, object]:
        """The exact checker's memo of *P* (prepared systems and conditions, by key)."""
        return self.of(P).exact

    def pattern_masks(self, key: bytes) -> _MaskMemo:
        """The pre-pass memo of the pattern with digest *key* (the last few are kept)."""
        masks = self._patterns.get(key)
        if masks is None:
            masks = self._patterns[key] = {}
            while len(self._patterns) > PATTERNS_KEPT:
                self._patterns.popitem(last=False)
        else:
            self._patterns.move_to_end(key)
        return masks


def _forget(memos: weakref.ref[KernelMemos], key: int) -> None:
    """Drop the memo of a matrix that is gone (if its workspace is still there)."""
    kept = memos()
    if kept is not None:
        memo = kept._matrices.get(key)
        if memo is not None and memo.matrix() is None:
            del kept._matrices[key]


def _pattern_key(P: CsrMatrix, workspace: Workspace) -> bytes:
    """A digest of the positive entries' positions (not their values)."""
    digest = hashlib.blake2b(digest_size=20)
    digest.update(np.asarray(P.shape, dtype=np.int64).tobytes())
    digest.update(linalg.index_digest(P.indptr, P.indices, workspace.solvers))
    digest.update(np.packbits(P.data > 0).data)
    return digest.digest()


def _pattern_masks(P: CsrMatrix, workspace: Workspace) -> _MaskMemo:
    """The pre-pass memo shared by every matrix with *P*'s pattern."""
    memo = workspace.kernels.of(P)
    if memo.masks is None:
        memo.masks = workspace.kernels.pattern_masks(_pattern_key(P, workspace))
    return memo.masks


def _mask_key(mask: BoolArray) -> bytes:
    return np.packbits(mask).tobytes() + mask.size.to_bytes(8, "little")


def _memoised_mask(P: CsrMatrix, kind: str, a: BoolArray, b: BoolArray,
                   compute: Callable[[], BoolArray], workspace: Workspace) -> BoolArray:
    masks = _pattern_masks(P, workspace)
    key = (kind, _mask_key(a), _mask_key(b))
    if key not in masks:
        masks[key] = compute()
    return masks[key].copy()


def _system(P: CsrMatrix, maybe: BoolArray, allowed: BoolArray | None = None, *,
            workspace: Workspace) -> _System:
    """The restricted system on *maybe*, built (and its solver prepared) once per matrix
    and workspace.

    With *allowed*, a kept system whose unknowns *M* satisfy ``maybe <= M <= allowed``
    (and hold not many more states, :data:`SUPERSET_SHARE`) is returned instead: the
    caller guarantees that the exact values satisfy the system's equations on every
    state of *allowed* (docs/numerics.md, "Shared systems"), so solving on *M* with the
    values outside *M* known gives the same fixed point on *maybe*.
    """
    systems = workspace.kernels.of(P).systems
    key = _mask_key(maybe)
    found = systems.get(key)
    if found is None and allowed is not None:
        found = _superset(systems.values(), maybe, allowed)
    if found is None:
        # Make room first: the old system is freed before the new one is built, not
        # after (on the 11x11 mission each takes ~250 MB).
        while systems and len(systems) >= SYSTEMS_KEPT:
            systems.popitem(last=False)
        A64, residue, rows = linalg.restricted_parts(P, maybe, workspace.solvers)
        unknowns = maybe.copy()
        solver = linalg.Factorization(A64, residue, _rebuilder(P, unknowns),
                                        workspace.solvers, workspace.monitor)
        del A64, residue
        found = _System(rows, solver, unknowns, workspace.row_plans)
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
        A64, residue, _ = linalg.unplanned_parts(P, unknowns)
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


def shared_system(P: CsrMatrix, maybe: BoolArray, allowed: BoolArray, *,
                  workspace: Workspace) -> _System:
    """The linear system to solve the unknowns *maybe* on: a kept one on a superset
    *M* of them inside *allowed*, or a new one on *maybe* (see :func:`_system`).

    For kernels outside this module (conditional numerators), so that they share the
    factorisation of an unconditional property. ``.unknowns`` is *M*; ``.rows`` the
    rows ``P[M, :]`` (once a map is made, without each row's own diagonal entry: use
    them with known values that are 0 on *M*); ``.factorization`` the solver of
    ``I - P_MM``; ``.affine`` its maps.
    """
    return _system(P, maybe, allowed, workspace=workspace)


def _restrict(found: Bounds, unknowns: BoolArray, maybe: BoolArray) -> Bounds:
    """*found* (over the states of *unknowns*) at the states of *maybe* only."""
    if found.value.size == np.count_nonzero(maybe):
        return found
    where = np.flatnonzero(maybe[unknowns])
    return Bounds(found.value[where], found.lower[where], found.upper[where])
