"""The Bellman equations of the unknown states of an MDP, with rigorous images.

After the qualitative pre-pass the unknown states are grouped into *classes*
(one per state, or one per end component that is collapsed, de Alfaro 1997);
each class has the choices of its states that leave it. With ``P'_a`` the
entries of choice *a* that leave its class, ``s_a = sum_j P'_aj`` and ``o_a``
its reward, choice *a* maps a value vector *x* to

    G_a(x) = (o_a + sum_j P'_aj ext(x)_j) / s_a

(``ext(x)`` reads *x* on the classes and the known values elsewhere): the mass
that stays in the class is read as ``1 - s_a``, exactly -- the reading the DTMC
side gives a self-loop (``docs/numerics.md``), of which a collapsed class is the
generalisation. The Bellman operator is the maximum or minimum of ``G_a`` over
each class's choices. Dividing by ``s_a`` changes no fixed point and no test
``B(u) <= u``: for ``s_a > 0``, ``G_a(u) <= u_c`` iff ``o_a + P'_a ext(u) +
(1 - s_a) u_c <= u_c`` (``docs/mdp-numerics.md``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
import scipy.sparse as sp

from veribattery._types import BoolArray, CsrMatrix, FloatArray, IntArray
from veribattery.checker.certify import (
    UNIT_ROUNDOFF,
    enclose_product,
    product_error,
    step_down_in_place,
    step_up_in_place,
)
from veribattery.checker.mdp.graph import ChoiceGraph, distinct, segments

__all__ = ["BellmanImage", "ChoiceSystem", "Objective", "equations", "quotient_classes"]

#: Which player the values are optimal for.
Objective = Literal["min", "max"]


@dataclass(frozen=True, slots=True)
class ChoiceSystem:
    """The equations of *size* classes: one row per choice that leaves its class.

    :param class_of: per state, its class, or -1 for a state whose value is known.
    :param choices: per row, the MDP's choice index (rows grouped by class).
    :param groups: ``size + 1`` offsets of each class's rows.
    :param off: rows x ``(size + len(known_states))``: the entries that leave the row's
        class, columns ``0..size-1`` the classes, then the known states.
    :param positions: per stored entry of *off*, its position in the MDP's
        ``transitions.data`` (for exact arithmetic on the same rows).
    :param known_states: the states of known value that some row reaches.
    :param leave: per row, ``s_a`` in floating point.
    :param leave_lower: a rigorous lower bound of ``s_a`` (its exact sum).
    :param leave_upper: a rigorous upper bound of ``s_a``.
    :param pattern: *off* with its stored entries set to 1.
    """

    class_of: IntArray
    choices: IntArray
    groups: IntArray
    off: CsrMatrix
    positions: IntArray
    known_states: IntArray
    leave: FloatArray
    leave_lower: FloatArray
    leave_upper: FloatArray
    #: *off* with every stored entry 1 (counts the nonzero terms of a product).
    pattern: CsrMatrix

    @property
    def size(self) -> int:
        """Number of classes (unknowns)."""
        return int(self.groups.size - 1)

    @property
    def row_class(self) -> IntArray:
        """The class of each row."""
        return np.repeat(np.arange(self.size, dtype=np.int64), np.diff(self.groups))

    @property
    def inner(self) -> CsrMatrix:
        """The columns of the classes: entries between unknowns."""
        return sp.csr_matrix(self.off[:, : self.size])

    @property
    def outer(self) -> CsrMatrix:
        """The columns of the known states."""
        return sp.csr_matrix(self.off[:, self.size:])

    def graph(self) -> ChoiceGraph:
        """The rows as a choice graph over classes then known states."""
        return ChoiceGraph.of(self.off, self.row_class)

    def images(self, x: FloatArray, known: FloatArray, offset: FloatArray | None) -> FloatArray:
        """``G_a(x)`` of every row in floating point (not rigorous)."""
        numerator = self.off @ np.concatenate([x, known])
        if offset is not None:
            numerator = numerator + offset
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.asarray(numerator / self.leave, dtype=np.float64)

    def bound_images(self, x: FloatArray, known: FloatArray, offset: FloatArray | None,
                     *, up: bool, rows: IntArray | None = None) -> FloatArray:
        """Rigorous bounds of ``G_a(x)`` per row: from above if *up*, else from below.

        *x*, *known* and *offset* must be nonnegative (so is every term). The
        numerator's rounding is bounded by Higham's ``gamma_k`` over the row's *nonzero*
        terms only (a product with an exact 0 is exactly 0 and adding it is exact), so
        a row that reads only zeros has the exact image 0 -- which lets exact zeros
        pass the certificate's tests. The quotient is divided by the other side of
        ``s_a``'s enclosure and stepped one float outward (and clamped at 0 below).

        :param rows: only these rows, in this order (None: all); each row's bound is
            the same float either way.
        """
        return self.extended_bound_images(np.concatenate([x, known]), offset, up=up,
                                          rows=rows)

    def extended_bound_images(self, extended: FloatArray, offset: FloatArray | None,
                              *, up: bool, rows: IntArray | None = None,
                              terms: FloatArray | None = None) -> FloatArray:
        """:meth:`bound_images` of ``ext(x)``: *x* followed by the known values.

        :param terms: with every row, :meth:`nonzero_terms` of *extended*, if known.
        """
        if rows is None:
            if terms is None:
                terms = self.nonzero_terms(extended != 0)
            return _bounded_images(self.off, terms, extended, offset, self.leave_lower,
                                   self.leave_upper, up=up)
        off = self.off[rows]
        return _bounded_images(off, _nonzero_terms(off, extended), extended,
                               None if offset is None else offset[rows],
                               self.leave_lower[rows], self.leave_upper[rows], up=up)

    def nonzero_terms(self, nonzero: BoolArray) -> FloatArray:
        """Per row, how many of its entries read an entry of *nonzero* (as floats)."""
        return np.asarray(self.pattern @ nonzero.astype(np.float64), dtype=np.float64)

    def defect(self, x: FloatArray, known: FloatArray, offset: FloatArray | None,
               objective: Objective) -> FloatArray:
        """An upper bound of ``|B(x) - x|`` per class from the rigorous images (plus four
        units of roundoff of *x*, the certificate's floor): the defect its margin is
        made of (*x* is clipped at 0)."""
        x = np.maximum(x, 0.0)
        with np.errstate(invalid="ignore", over="ignore"):
            above = self.best(self.bound_images(x, known, offset, up=True), objective) - x
            below = x - self.best(self.bound_images(x, known, offset, up=False), objective)
        return np.maximum(np.maximum(above, below), 0.0) + 4.0 * UNIT_ROUNDOFF * x

    def restricted(self, keep: BoolArray) -> ChoiceSystem:
        """The same classes with only the rows *keep* (each class must keep one)."""
        counts = np.bincount(self.row_class[keep], minlength=self.size)
        if np.any(counts == 0):
            raise ValueError("every class needs a row")
        entries = np.repeat(keep, np.diff(self.off.indptr))
        off = sp.csr_matrix(self.off[np.flatnonzero(keep)])
        pattern = sp.csr_matrix((np.ones(off.nnz), off.indices, off.indptr), shape=off.shape)
        groups = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        return ChoiceSystem(self.class_of, self.choices[keep], groups, off,
                            self.positions[entries], self.known_states, self.leave[keep],
                            self.leave_lower[keep], self.leave_upper[keep], pattern)

    def best(self, row_values: FloatArray, objective: Objective) -> FloatArray:
        """The maximum or minimum of *row_values* over each class's rows."""
        reduce = np.maximum if objective == "max" else np.minimum
        return np.asarray(reduce.reduceat(row_values, self.groups[:-1]), dtype=np.float64)

    def best_of(self, row_values: FloatArray, classes: IntArray,
                objective: Objective) -> FloatArray:
        """:meth:`best` of the (sorted, distinct) *classes* only."""
        reduce = np.maximum if objective == "max" else np.minimum
        positions = segments(self.groups, classes)
        starts = np.cumsum(self.groups[classes + 1] - self.groups[classes]) - (
            self.groups[classes + 1] - self.groups[classes])
        return np.asarray(reduce.reduceat(row_values[positions], starts), dtype=np.float64)

    def best_rows(self, row_values: FloatArray, objective: Objective) -> IntArray:
        """Per class, the first row attaining :meth:`best`."""
        best = self.best(row_values, objective)
        hits = row_values == best[self.row_class]
        rows = np.where(hits, np.arange(row_values.size), row_values.size)
        return np.asarray(np.minimum.reduceat(rows, self.groups[:-1]), dtype=np.int64)


#: Share of the rows above which :class:`BellmanImage` recomputes every row at once.
RECOMPUTE_ALL = 0.25
#: Classes of at most this many rows take the best of their rows a row at a time
#: (:class:`_ClassRows`); larger ones by ``reduceat``.
FEW_ROWS = 8


@dataclass(frozen=True, slots=True)
class _ClassRows:
    """Where each class's rows lie, to take the best of rigorous row images quickly.

    ``reduceat`` pays some 15 ns per class, more than the comparisons themselves on a
    system of many classes of one to three rows (a third of a full image of the
    mission MDP); here each class's first row is read, then its second, third, ... in
    whole-array operations. Rigorous images hold no NaN and no -0.0 (the bounds
    replace NaN and clip at +0.0), so their maximum or minimum is the same float in
    any order -- the one ``reduceat`` finds.

    :param firsts: per class, its first row.
    :param later: per row position ``k = 1, 2, ...``: the classes of at most
        :data:`FEW_ROWS` rows that have a row there, and that row.
    :param large: the classes of more rows; *large_rows* their rows, class by class,
        and *large_starts* where each class begins in them.
    """

    firsts: IntArray
    later: tuple[tuple[IntArray, IntArray], ...]
    large: IntArray
    large_rows: IntArray
    large_starts: IntArray

    @classmethod
    def of(cls, groups: IntArray) -> _ClassRows:
        """The layout of the classes whose rows start at *groups* (then the end)."""
        firsts, sizes = groups[:-1], np.diff(groups)
        few = sizes <= FEW_ROWS
        later = []
        for k in range(1, int(np.max(np.where(few, sizes, 0), initial=0))):
            classes = np.flatnonzero(few & (sizes > k))
            later.append((classes, firsts[classes] + k))
        large = np.flatnonzero(~few)
        lengths = sizes[large]
        return cls(firsts, tuple(later), large, segments(groups, large),
                   np.cumsum(lengths) - lengths)

    def best(self, row_images: FloatArray, objective: Objective) -> FloatArray:
        """Per class, the maximum or minimum of its rigorous *row_images*."""
        reduce = np.maximum if objective == "max" else np.minimum
        best = row_images[self.firsts]
        for classes, rows in self.later:
            best[classes] = reduce(best[classes], row_images[rows])
        if self.large.size:
            best[self.large] = reduce.reduceat(row_images[self.large_rows], self.large_starts)
        return best


class BellmanImage:
    """One side of the rigorous Bellman image of a system, ``x -> best_a bound(G_a(x))``,
    remembering its last argument: the next call recomputes only the rows that read an
    entry that changed (the others' bounds would be the same floats), and the best of
    only their classes. The certificate's rounds change few entries at a time.

    :param up: upper bounds (else lower bounds) of the images.
    """

    def __init__(self, system: ChoiceSystem, known: FloatArray, offset: FloatArray | None,
                 objective: Objective, *, up: bool) -> None:
        self._system, self._known, self._offset = system, known, offset
        self._objective, self._up = objective, up
        self._readers: tuple[IntArray, IntArray] | None = None
        self._row_class = np.empty(0, dtype=np.int64)  # (made with the readers)
        self._last: tuple[FloatArray, FloatArray, FloatArray] | None = None
        self._rows: _ClassRows | None = None
        self._terms: tuple[BoolArray, FloatArray] | None = None

    def __call__(self, x: FloatArray) -> FloatArray:
        """The image of *x* (a new array)."""
        if self._last is not None:
            extended, rows_now, _ = self._last
            argument = extended[: x.size]
            changed = np.flatnonzero(x.view(np.int64) != argument.view(np.int64))
            if not changed.size:  # (the certificate maps a vector again as it hands over)
                return self._last[2].copy()
            if changed.size <= RECOMPUTE_ALL * x.size:
                rows = self._rows_reading(changed)
                if rows.size <= RECOMPUTE_ALL * rows_now.size:
                    return self._updated(x, changed, rows)
        extended = np.concatenate([x, self._known])
        row_images = self._system.extended_bound_images(extended, self._offset, up=self._up,
                                                        terms=self._terms_of(extended))
        if self._rows is None:
            self._rows = _ClassRows.of(self._system.groups)
        best = self._rows.best(row_images, self._objective)
        self._last = (extended, row_images, best)
        return best.copy()

    def _terms_of(self, extended: FloatArray) -> FloatArray:
        """The rows' nonzero terms of *extended*: the last ones while the same entries
        are 0 (interval iteration moves every bound, rarely off or onto 0)."""
        nonzero = extended != 0
        if self._terms is None or not np.array_equal(nonzero, self._terms[0]):
            self._terms = (nonzero, self._system.nonzero_terms(nonzero))
        return self._terms[1]

    def _updated(self, x: FloatArray, changed: IntArray, rows: IntArray) -> FloatArray:
        """The image of *x* from the last one, whose argument differs at *changed*:
        *rows* recomputed, the remembered vectors updated in place (a copy of each
        would cost more than the rows themselves)."""
        assert self._last is not None
        system = self._system
        extended, row_images, best = self._last
        extended[changed] = x[changed]
        if rows.size:
            row_images[rows] = system.extended_bound_images(extended, self._offset,
                                                            up=self._up, rows=rows)
            owners = self._row_class[rows]  # nondecreasing: rows are sorted
            classes = owners[np.concatenate([[True], owners[1:] != owners[:-1]])]
            best[classes] = system.best_of(row_images, classes, self._objective)
        return best.copy()

    def _rows_reading(self, columns: IntArray) -> IntArray:
        """The rows with an entry in any of the class *columns* (sorted, once each)."""
        if self._readers is None:
            inner = sp.csc_matrix(self._system.off[:, : self._system.size])
            self._readers = (inner.indptr.astype(np.int64), inner.indices.astype(np.int64))
            self._row_class = self._system.row_class
        indptr, rows = self._readers
        return distinct(rows[segments(indptr, columns)])


def _nonzero_terms(off: CsrMatrix, full: FloatArray) -> FloatArray:
    """Per row of *off*, how many of its stored entries read a nonzero of *full* (as
    floats: the same counts as the pattern's product, which sums ones exactly)."""
    with np.errstate(invalid="ignore"):
        read = np.concatenate([[0], np.cumsum(full[off.indices] != 0)])
    return np.asarray(read[off.indptr[1:]] - read[off.indptr[:-1]], dtype=np.float64)


def _bounded_images(off: CsrMatrix, terms: FloatArray, full: FloatArray,
                    offset: FloatArray | None, leave_lower: FloatArray,
                    leave_upper: FloatArray, *, up: bool) -> FloatArray:
    """:meth:`ChoiceSystem.bound_images` of the rows *off* (*terms* their nonzero terms,
    *full* the classes' then the known states' values)."""
    numerator = np.asarray(off @ full, dtype=np.float64)
    if offset is not None:
        numerator = numerator + offset
        terms = terms + (offset != 0)
    # A row without a nonzero term has the exact image 0 (every formula below gives
    # 0 there, through subnormal steps that cost ~10x): compute the others only.
    live = np.flatnonzero(terms)
    numerator_rows = terms.size
    every = live.size == numerator_rows
    if not every:
        numerator, terms = numerator[live], terms[live]
        leave_lower, leave_upper = leave_lower[live], leave_upper[live]
    error = product_error(numerator, terms, terms)
    # The formulas of the docstring, in place on the vectors made here: the same
    # operations on the same floats, without a temporary per step.
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        quotient = (_upper_quotient(numerator, error, leave_lower) if up
                    else _lower_quotient(numerator, error, leave_upper))
    if every:
        return quotient
    images = np.zeros(numerator_rows, dtype=np.float64)
    images[live] = quotient
    return images


def _upper_quotient(numerator: FloatArray, error: FloatArray,
                    leave_lower: FloatArray) -> FloatArray:
    """``step_up(step_up(numerator + error) / leave_lower)``, 0 where the sum is 0 and
    ``inf`` where NaN (in *error*'s storage; every entry is >= 0, NaN or ``+inf``)."""
    error += numerator
    zero = error == 0
    step_up_in_place(error)
    error /= leave_lower
    step_up_in_place(error)
    error[zero] = 0.0
    error[np.isnan(error)] = np.inf
    return error


def _lower_quotient(numerator: FloatArray, error: FloatArray,
                    leave_upper: FloatArray) -> FloatArray:
    """``max(step_down(max(step_down(numerator - error), 0) / leave_upper), 0)``, 0 where
    NaN (in *numerator*'s storage)."""
    numerator -= error
    # A difference <= 0 steps down below 0 and is clipped to 0: clipping it first
    # gives the same 0 and leaves only entries >= 0 (or NaN) to step down.
    np.maximum(numerator, 0.0, out=numerator)
    step_down_in_place(numerator)
    np.maximum(numerator, 0.0, out=numerator)
    numerator /= leave_upper
    step_down_in_place(numerator)
    numerator[np.isnan(numerator)] = 0.0
    np.maximum(numerator, 0.0, out=numerator)
    return numerator


def equations(transitions: CsrMatrix, owner: IntArray, class_of: IntArray,
              allowed: BoolArray | None = None) -> ChoiceSystem:
    """The rows of the classes of *class_of* (states with -1 are known).

    :param transitions: the MDP's choice matrix; *owner* the state of each choice.
    :param allowed: the choices that may be used (None: all); choices that keep all
        their mass in their class are dropped (they never change a value).
    :raises ValueError: when a class is left without any row.
    """
    size = int(class_of.max(initial=-1)) + 1
    candidate = class_of[owner] >= 0
    if allowed is not None:
        candidate &= allowed
    rows = np.flatnonzero(candidate)
    rows = rows[np.argsort(class_of[owner[rows]], kind="stable")]
    leaving = _leaving_entries(transitions, owner, class_of, rows)[2]
    rows = rows[leaving > 0]
    positions, row_of, _ = _leaving_entries(transitions, owner, class_of, rows)
    counts = np.bincount(class_of[owner[rows]], minlength=size)
    if np.any(counts == 0):
        raise ValueError(f"{int(np.sum(counts == 0))} classes have no choice leaving them")
    columns, known_states = _local_columns(class_of, transitions.indices[positions], size)
    indptr = np.concatenate([[0], np.cumsum(np.bincount(row_of, minlength=rows.size))])
    off = sp.csr_matrix((transitions.data[positions], columns, indptr),
                        shape=(rows.size, size + known_states.size))
    leave, leave_lower, leave_upper = enclose_product(off, np.ones(off.shape[1]))
    groups = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    pattern = sp.csr_matrix((np.ones(off.nnz), off.indices, off.indptr), shape=off.shape)
    return ChoiceSystem(class_of, rows, groups, off, positions, known_states, leave,
                        np.maximum(leave_lower, 0.0), leave_upper, pattern)


def _leaving_entries(transitions: CsrMatrix, owner: IntArray, class_of: IntArray,
                     rows: IntArray) -> tuple[IntArray, IntArray, IntArray]:
    """Positions of the positive entries of *rows* outside the row's class, the index
    in *rows* of each, and how many each row has."""
    starts = transitions.indptr[rows].astype(np.int64)
    lengths = transitions.indptr[rows + 1].astype(np.int64) - starts
    row_of = np.repeat(np.arange(rows.size, dtype=np.int64), lengths)
    ends = np.cumsum(lengths)
    positions = np.repeat(starts, lengths) + (np.arange(row_of.size) - np.repeat(ends - lengths,
                                                                                 lengths))
    column_class = class_of[transitions.indices[positions]]
    keep = (transitions.data[positions] > 0) & (column_class != class_of[owner[rows]][row_of])
    positions, row_of = positions[keep], row_of[keep]
    return positions, row_of, np.bincount(row_of, minlength=rows.size)


def _local_columns(class_of: IntArray, columns: IntArray, size: int) -> tuple[IntArray, IntArray]:
    """Columns renumbered: a class keeps its index, a known state gets ``size + k``."""
    column_class = class_of[columns]
    known = column_class < 0
    known_states, inverse = np.unique(columns[known], return_inverse=True)
    local = column_class.copy()
    local[known] = size + inverse
    return local, known_states.astype(np.int64)


def quotient_classes(unknown: BoolArray, component: IntArray | None = None) -> IntArray:
    """Classes of the *unknown* states: one per end component in *component* (>= 0),
    one per other unknown state; -1 for the states that are not unknown."""
    class_of = np.full(unknown.size, -1, dtype=np.int64)
    if component is None:
        class_of[unknown] = np.arange(int(unknown.sum()))
        return class_of
    grouped = unknown & (component >= 0)
    _, dense = np.unique(component[grouped], return_inverse=True)
    class_of[grouped] = dense
    count = int(dense.max(initial=-1)) + 1
    single = unknown & ~grouped
    class_of[single] = count + np.arange(int(single.sum()))
    return class_of
