"""Approximate optimal values and strategies: policy iteration in floating point.

Policy iteration (Howard 1960; Puterman 1994, §6.4 and §7.2) evaluates a strategy
by one sparse LU solve of its induced system, then switches every class whose
best row beats its current one. Only the *approximation* comes from here: the
bounds returned to users are certified afterwards from the Bellman operator
itself (:mod:`~veribattery.checker.mdp.certificate`), so a rounding error or a
tie broken the wrong way here can widen an interval but never falsify it.
The first strategy usually comes from topological value iteration
(:mod:`~veribattery.checker.mdp.topological`), which leaves few rounds or none.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
from scipy.sparse.linalg import SuperLU, splu

from veribattery._types import BoolArray, FloatArray, IntArray
from veribattery.checker.certify import UNIT_ROUNDOFF
from veribattery.checker.certify.fixpoint import Progress
from veribattery.checker.linalg.compact_lu import compact_solve
from veribattery.checker.linalg.topological import TopologicalSolver
from veribattery.checker.mdp.graph import attractor
from veribattery.checker.mdp.system import ChoiceSystem, Objective
from veribattery.errors import CheckError

__all__ = ["Evaluation", "evaluate", "improve", "improvements", "is_improper", "policy_iteration",
           "progress_rows", "strategy_lu", "switched", "tightest_among_ties"]

#: A row replaces the current one only if it is better by this much, relative (a few
#: roundings of an image: the values are refined to about the last bit).
POLICY_TOLERANCE = 2.0**-48
#: Improvement rounds before the last strategy is taken as it is.
POLICY_ROUNDS = 200
#: Refinement steps after each LU solve (in float64).
REFINE_STEPS = 3
#: A tied row replaces the strategy's if it shrinks the margin by this much, relative ...
MARGIN_GAIN = 2.0**-20
#: ... in at most this many rounds (each one evaluation). A second round tightened
#: consensus ``c2`` and zeroconf K=2 by some 1e-11 relative, far inside the 1e-9 asked
#: for, and with the strategy before kept (:attr:`Evaluation.untied`) it made three
#: evaluations live at once: firewire ``time_max`` 287 -> 323 MB, zeroconf K=4 2.3 ->
#: 2.6 s.
TIE_ROUNDS = 1
#: Rows of a strategy's system copied to extended precision at a time for their sums.
WIDE_ROWS = 1 << 15


@dataclass(frozen=True, slots=True)
class Evaluation:
    """A strategy's values on the classes and an approximate solver of its system.

    :param values: the strategy's value per class.
    :param rows: the strategy: one row of the system per class.
    :param correct: ``delta -> (I - B)^-1 delta`` for the strategy's map
        ``x -> G_rows(x)`` (``B`` its linear part): how far a defect *delta* of that map
        moves its fixed point.
    :param solver: the solver of the strategy's system ``diag(s) - P'_inner`` (the same
        for every system with the same rows: see :func:`evaluate`).
    """

    values: FloatArray
    rows: IntArray
    correct: Callable[[FloatArray], FloatArray]
    solver: TopologicalSolver
    #: The strategy before :func:`tightest_among_ties` moved it (None: not moved), whose
    #: margin the certificate tries too: it may cover the other tied rows better.
    untied: Evaluation | None = None


def evaluate(system: ChoiceSystem, rows: IntArray, known: FloatArray,
             offset: FloatArray | None,
             solver: TopologicalSolver | None = None) -> Evaluation | None:
    """The values of the strategy *rows*, or None if its system is singular (the
    strategy stays forever among the unknown states from somewhere).

    Solved SCC by SCC in topological order (:class:`TopologicalSolver`: a
    strategy's induced system is mostly acyclic, and substitution there costs a
    fraction of a sparse LU of the whole system, in time and in memory), then
    iterative refinement with the residual
    computed in extended precision (``np.longdouble``, the leaving probabilities
    summed there too), so that the values are correct to about the last bit of a
    double wherever the system is not too ill-conditioned.

    :param solver: the :attr:`Evaluation.solver` of an evaluation of the same rows --
        the same entries of the same classes, as in a system restricted to some rows
        (:meth:`ChoiceSystem.restricted`) -- reused rather than made again.
    """
    leave = system.leave[rows]
    prepared = _prepared(system, rows, leave, known, offset, solver)
    if prepared is None:
        return None
    factors, residual = prepared
    x = factors.solve(residual.rhs.astype(np.float64))
    for _ in range(REFINE_STEPS):
        if not np.all(np.isfinite(x)):
            return None
        refined = x + factors.solve(residual.of_values(x))
        if np.array_equal(refined, x):
            break  # a fixed point: every later step would compute x again, bit for bit
        x = refined
    if not np.all(np.isfinite(x)):
        return None

    def correct(delta: FloatArray) -> FloatArray:
        return np.asarray(factors.solve(leave * delta), dtype=np.float64)

    return Evaluation(np.asarray(x, dtype=np.float64), rows, correct, factors)


def _prepared(system: ChoiceSystem, rows: IntArray, leave: FloatArray, known: FloatArray,
              offset: FloatArray | None, solver: TopologicalSolver | None
              ) -> tuple[TopologicalSolver, _Residual] | None:
    """The solver and the residual of the strategy *rows*, or None where its system is
    singular. (Its own function so that the strategy's rows, which neither keeps, die
    before the refinement's vectors are made.)"""
    chosen = sp.csr_matrix(system.off[rows])
    factors = solver if solver is not None else _solver(chosen, leave, system.size)
    if factors is None:
        return None
    return factors, _Residual.of(chosen, system.size, known,
                                 None if offset is None else offset[rows])


def _solver(chosen: sp.csr_matrix, leave: FloatArray, size: int) -> TopologicalSolver | None:
    """The solver of ``diag(leave) - chosen_inner``, or None where it is singular."""
    matrix = sp.csr_matrix(sp.diags(leave) - chosen[:, :size])
    try:
        return TopologicalSolver(matrix, _component_lu)
    except CheckError:
        return None


def _component_lu(block: sp.csr_matrix) -> Callable[[FloatArray], FloatArray] | None:
    """SuperLU with its default (column) ordering and partial pivoting for one large
    component: as fast as before on a strategy whose system is one big cycle (consensus),
    where the M-matrix ordering of the DTMC side's solver was slower."""
    try:
        return compact_solve(strategy_lu(block))
    except RuntimeError:
        return None


def strategy_lu(matrix: sp.spmatrix) -> SuperLU:
    """SuperLU of a strategy's system (default column order, partial pivoting), with
    supernodes relaxed over single columns only (``relax=1``, panels of 4 columns).

    A strategy's system fills in little (zeroconf's cyclic level: 1.0M entries in L and U
    for 0.47M in the matrix), and SuperLU's defaults (``sp_ienv``: every etree subtree of
    fewer than 10 columns made one dense supernode, panels of 20 columns) cost there more
    than they save: 0.41 -> 0.26 s (median of 5) on that level, 0.12 -> 0.07 s on
    firewire's. Systems that fill in heavily (a 2-D grid, random graphs) factorised as
    fast or faster.

    :raises RuntimeError: the matrix is singular.
    """
    return splu(sp.csc_matrix(matrix), panel_size=4, relax=1)


@dataclass(frozen=True, slots=True)
class _Residual:
    """``b - (diag(s) - P'_inner) x`` of a strategy's system in extended precision."""

    inner: sp.csr_matrix
    leave: npt.NDArray[np.longdouble]
    rhs: npt.NDArray[np.longdouble]

    @classmethod
    def of(cls, chosen: sp.csr_matrix, size: int, known: FloatArray,
           offset: FloatArray | None) -> _Residual:
        leave, rhs = _leaving_and_known(chosen, size, known)
        if offset is not None:
            rhs = rhs + offset.astype(np.longdouble)
        # (the float64 entries read exactly in extended precision, as from a wide copy;
        # made after that copy has died, so that two never live at once)
        return cls(sp.csr_matrix(chosen[:, :size], dtype=np.longdouble), leave, rhs)

    def of_values(self, x: FloatArray) -> FloatArray:
        wide = x.astype(np.longdouble)
        # ``rhs - (leave * wide - inner @ wide)``, the same operations in place
        residual = self.leave * wide
        residual -= self.inner @ wide
        np.subtract(self.rhs, residual, out=residual)
        return np.asarray(residual, dtype=np.float64)


def _leaving_and_known(chosen: sp.csr_matrix, size: int, known: FloatArray
                       ) -> tuple[npt.NDArray[np.longdouble], npt.NDArray[np.longdouble]]:
    """Per row of *chosen*, its sum and its product with the *known* values past column
    *size*, in extended precision.

    A block of rows at a time: each row's sums are the same floats as from one wide copy
    of all rows (a row is summed alone, entry by entry), and a block's wide copy costs a
    fraction of the whole one's 20 bytes an entry.
    """
    rows = int(chosen.shape[0])
    leave = np.zeros(rows, dtype=np.longdouble)
    rhs = np.zeros(rows, dtype=np.longdouble)
    ones = np.ones(chosen.shape[1], dtype=np.longdouble)
    wide_known = known.astype(np.longdouble)
    for lo in range(0, rows, WIDE_ROWS):
        hi = min(lo + WIDE_ROWS, rows)
        wide = sp.csr_matrix(chosen[lo:hi], dtype=np.longdouble)
        leave[lo:hi] = wide @ ones
        rhs[lo:hi] = wide[:, size:] @ wide_known
    return leave, rhs


def policy_iteration(system: ChoiceSystem, objective: Objective, known: FloatArray,
                     offset: FloatArray | None, start: IntArray,
                     rounds: int = POLICY_ROUNDS, *,
                     progress: Progress | None = None) -> Evaluation | None:
    """Policy iteration from the strategy *start* (rows per class).

    A class switches only where its best row beats the current one by more than
    :data:`POLICY_TOLERANCE` (relative), and the iteration stops when a switch makes
    no value better (or one worse) by more than that, so rounding noise cannot make
    it cycle.
    For minimising expected rewards *start* must reach the known states almost
    surely (a proper strategy); improvements keep that (Bertsekas & Tsitsiklis 1991).

    :param rounds: improvement rounds before the last strategy is taken as it is.
    :param progress: told ``(rounds done, rounds, "improvement rounds")`` after each.
    :return: the last strategy's evaluation, or None if even *start* is singular.
    """
    current = evaluate(system, start, known, offset)
    return None if current is None else improve(system, objective, known, offset, current,
                                                rounds, progress=progress)


def improve(system: ChoiceSystem, objective: Objective, known: FloatArray,
            offset: FloatArray | None, current: Evaluation,
            rounds: int = POLICY_ROUNDS, *, progress: Progress | None = None) -> Evaluation:
    """Policy iteration from the evaluated strategy *current* (:func:`policy_iteration`'s
    rounds): the last strategy's evaluation."""
    steps = improvements(system, objective, known, offset, current)
    for done in range(rounds):
        if progress is not None:
            progress(done, rounds, "improvement rounds")
        following = next(steps, None)
        if following is None:
            return current
        current = following
    return current


def improvements(system: ChoiceSystem, objective: Objective, known: FloatArray,
                 offset: FloatArray | None, current: Evaluation) -> Iterator[Evaluation]:
    """The strategies policy iteration moves to from *current*, one per round, until it
    stops (:func:`improve` takes as many rounds of them as it is given; a caller that
    wants more rounds later goes on from where it stopped instead of starting again)."""
    while True:
        following = _improved(system, objective, current, known, offset)
        if following is None:
            return
        accepted = _accepted(system, objective, known, offset, current, following)
        if accepted is None:
            return
        current, gain, noise = accepted
        yield current
        if not np.any(gain > noise):  # no real progress: a switch between near-ties
            return


def switched(system: ChoiceSystem, objective: Objective, known: FloatArray,
             offset: FloatArray | None, current: Evaluation,
             rows: IntArray) -> Evaluation | None:
    """The strategy *rows* evaluated, or None where its system is singular, its values
    are improper, or some value is worse than *current*'s by more than rounding (the
    tests of a round of :func:`improvements`, for a switch made elsewhere)."""
    accepted = _accepted(system, objective, known, offset, current, rows)
    return None if accepted is None else accepted[0]


def _accepted(system: ChoiceSystem, objective: Objective, known: FloatArray,
              offset: FloatArray | None, current: Evaluation, rows: IntArray
              ) -> tuple[Evaluation, FloatArray, FloatArray] | None:
    """The strategy *rows* evaluated, with its gain over *current* and the noise of that
    gain; None where its system is singular, its values are improper, or it is worse
    somewhere by more than rounding (rounding has taken over)."""
    candidate = evaluate(system, rows, known, offset)
    if candidate is None or is_improper(candidate.values):
        return None
    gain, noise = _change(candidate, current, objective)
    if np.any(gain < -np.maximum(noise, _noise_floor(candidate, current))):
        return None
    return candidate, gain, noise


def tightest_among_ties(system: ChoiceSystem, objective: Objective, known: FloatArray,
                        offset: FloatArray | None, current: Evaluation) -> Evaluation:
    """*current* after rounds of :func:`_tighter_ties` until no tied row is better.

    Which of several optimal strategies policy iteration ends with is an accident of
    its path, and the certificate's margin ``d = (I - B_sigma)^-1 d0`` (``d0`` the
    enclosed defect of the values) depends on it: consensus's ``steps_max`` certified
    -5.1e-10 below from one tied strategy and -4.4e-10 from the one found here. The
    strategy before is kept as :attr:`Evaluation.untied`: a smaller margin covers the
    other tied rows less, and where the test that reads every row then fails, *current*'s
    own margin may pass (resource-gathering's ``Tmin``: at once, where the tied rows'
    margin took 8 s).
    """
    start = current
    for _ in range(TIE_ROUNDS):
        following = _tighter_ties(system, objective, known, offset, current)
        if following is None:
            break
        current = following
    return current if current is start else replace(current, untied=start)


def _tighter_ties(system: ChoiceSystem, objective: Objective, known: FloatArray,
                  offset: FloatArray | None, current: Evaluation) -> Evaluation | None:
    """*current* with each class's row replaced by the tied row (image within
    :data:`POLICY_TOLERANCE` of the best) that makes the margin smallest, re-evaluated;
    None where no tied row does or the switch makes a value worse by more than rounding
    and the margin.

    With ``d`` the strategy's margin, ``d = d0 + P_sigma d / s``, a row *b* with ``P_b d
    / s_b`` smaller than the strategy's makes ``d`` a strict super-solution of the new
    strategy's margin equation (and so bounds it; a proper strategy stays proper).
    """
    margin = current.correct(system.defect(current.values, known, offset, objective))
    if not np.all(np.isfinite(margin)):
        return None
    rows = _tighter_rows(system, objective, known, offset, current, margin)
    if rows is None:
        return None
    candidate = evaluate(system, rows, known, offset)
    if candidate is None or is_improper(candidate.values):
        return None
    gain, noise = _change(candidate, current, objective)
    # Tied rows may differ by rounding, and the values by as much as the margin allows
    # for (they are approximations within it); worse than that is a real loss.
    if np.any(gain < -(np.maximum(noise, _noise_floor(candidate, current)) + margin)):
        return None
    return candidate


def _tighter_rows(system: ChoiceSystem, objective: Objective, known: FloatArray,
                  offset: FloatArray | None, current: Evaluation,
                  margin: FloatArray) -> IntArray | None:
    """:func:`_tighter_ties`'s switched strategy, or None where no tied row makes the
    margin smaller. (Its own function so that its vectors over the rows die before the
    switched strategy is evaluated.)"""
    images = system.images(current.values, known, offset)
    best = system.best(images, objective)[system.row_class]
    with np.errstate(invalid="ignore"):
        tied = np.abs(images - best) <= POLICY_TOLERANCE * np.abs(best)
    after = system.images(margin, np.zeros(system.known_states.size), None)
    rows = system.best_rows(np.where(tied, after, np.inf), "min")
    smaller = tied[rows] & (after[rows] < after[current.rows] * (1.0 - MARGIN_GAIN))
    if not smaller.any():
        return None
    return np.where(smaller, rows, current.rows)


def _change(candidate: Evaluation, current: Evaluation,
            objective: Objective) -> tuple[FloatArray, FloatArray]:
    """How much better *candidate* is than *current* per class (towards the objective),
    and the relative rounding noise (:data:`POLICY_TOLERANCE`) below which it is none."""
    gain = candidate.values - current.values
    if objective == "min":
        gain = -gain
    noise = POLICY_TOLERANCE * np.maximum(np.abs(candidate.values), np.abs(current.values))
    return gain, noise


def _noise_floor(candidate: Evaluation, current: Evaluation) -> float:
    """The rounding noise of values near 0: one unit roundoff of the largest value. A
    state of value 0 may come out as -3e-32 (a cancellation in the LU solve), which
    is no loss next to values of order 1 -- taking it for one stopped the iteration
    at its first strategy (the mission MDP's most recharges: 36.7 for 200)."""
    scale = max(float(np.max(np.abs(candidate.values), initial=0.0)),
                float(np.max(np.abs(current.values), initial=0.0)))
    return UNIT_ROUNDOFF * scale


def is_improper(values: FloatArray) -> bool:
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
