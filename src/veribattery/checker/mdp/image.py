"""The rigorous Bellman image of a :class:`~veribattery.checker.mdp.system.ChoiceSystem`,
remembering its last argument.

The certificate (:mod:`~veribattery.checker.mdp.certificate`) maps one vector after
another that differ in a few entries (its push rounds) or in all of them (interval
iteration); :class:`BellmanImage` recomputes only the rows that read a changed entry,
and a whole image with as few passes over the rows as it can. Every image is the
same float that ``system.best(system.bound_images(x, ...))`` gives.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from veribattery._types import BoolArray, FloatArray, IntArray
from veribattery._unique import distinct
from veribattery.checker.mdp.graph import segments
from veribattery.checker.mdp.system import ChoiceSystem, LiveRows, Objective

__all__ = ["BellmanImage"]

#: Share of the rows above which :class:`BellmanImage` recomputes every row at once.
RECOMPUTE_ALL = 0.25


class _Readers:
    """Which rows read each class (the inner columns of the system in CSC: int64
    offsets, then rows) and the class of each row, made on first use: one per system,
    shared by the two sides of its image (each the same arrays it would make)."""

    def __init__(self, system: ChoiceSystem) -> None:
        self._system = system
        self._index: tuple[IntArray, IntArray, IntArray] | None = None

    def index(self) -> tuple[IntArray, IntArray, IntArray]:
        """``(indptr, rows, row_class)``."""
        if self._index is None:
            system = self._system
            inner = sp.csc_matrix(system.off[:, : system.size])
            indptr, rows = inner.indptr.astype(np.int64), inner.indices.astype(np.int64)
            del inner
            self._index = (indptr, rows, system.row_class)
        return self._index


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
        self._readers = _Readers(system)
        self._last: tuple[FloatArray, FloatArray, FloatArray] | None = None
        self._live: tuple[BoolArray, LiveRows] | None = None

    @classmethod
    def pair(cls, system: ChoiceSystem, known: FloatArray, offset: FloatArray | None,
             objective: Objective) -> tuple[BellmanImage, BellmanImage]:
        """The lower and the upper image of *system*, sharing the index of which rows
        read each class (the same arrays for both: made once, kept once)."""
        lower = cls(system, known, offset, objective, up=False)
        upper = cls(system, known, offset, objective, up=True)
        upper._readers = lower._readers
        return lower, upper

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
                                                        live=self._live_of(extended))
        best = self._system.layout.best(row_images, self._objective)
        self._last = (extended, row_images, best)
        return best.copy()

    def _live_of(self, extended: FloatArray) -> LiveRows:
        """The live rows of *extended*: the last ones while the same entries are 0
        (interval iteration moves every bound, rarely off or onto 0)."""
        nonzero = extended != 0
        if self._live is None or not np.array_equal(nonzero, self._live[0]):
            self._live = (nonzero, self._system.live_rows(nonzero, self._offset, up=self._up))
        return self._live[1]

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
            owners = self._readers.index()[2][rows]  # nondecreasing: rows are sorted
            classes = owners[np.concatenate([[True], owners[1:] != owners[:-1]])]
            best[classes] = system.best_of(row_images, classes, self._objective)
        return best.copy()

    def _rows_reading(self, columns: IntArray) -> IntArray:
        """The rows with an entry in any of the class *columns* (sorted, once each)."""
        indptr, rows, _ = self._readers.index()
        return distinct(rows[segments(indptr, columns)])
