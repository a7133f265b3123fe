"""What the checker remembers between queries, in one object its caller owns.

The kernels keep graph searches, linear systems and their factorisations, results,
the index work of restrictions and substitutions, conditions and stationary
distributions for the queries that follow: properties of one model share targets
(``F "done"`` under two reward structures), and the points of a structure-reusing
sweep share sparsity patterns. All of it lives in a :class:`Workspace` that the
caller makes and passes down, never in module state: two checks influence each
other only through a workspace they share, and everything it holds goes with it.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

from veribattery.checker import certify, kernels, linalg
from veribattery.checker.formula import share
from veribattery.explore.dtmc import DTMC
from veribattery.lang.nodes import Expr

if TYPE_CHECKING:
    from veribattery.checker.kernels.conditional import Conditions
    from veribattery.checker.kernels.steady import LongRun


class Workspace:
    """The caches of the checker, for the checks that share it.

    Every cache is bounded (a few patterns, systems or conditions each), and those of
    one matrix are keyed by its identity and forgotten with it, so a workspace may
    live as long as its owner: one pipeline run (the properties of one model), or a
    sweep whose points re-use one state space. Kept data never changes a value: a
    plan gives the same arrays bit for bit, and a shared system the same certified
    bounds (``docs/numerics.md``, "Shared systems").

    Not for concurrent use: give each thread its own.
    """

    __slots__ = ("_conditions", "_long_run", "kernels", "monitor", "row_plans", "solvers")

    def __init__(self) -> None:
        #: Per transition matrix: the 0/1 pre-pass (shared by matrices of one pattern),
        #: linear systems with their solvers, results (:class:`kernels.KernelMemos`).
        self.kernels = kernels.KernelMemos()
        #: Restriction and substitution plans by pattern (:class:`linalg.SolverPlans`).
        self.solvers = linalg.SolverPlans()
        #: The index work of the certificates' maps (:class:`certify.RowPlans`).
        self.row_plans = certify.RowPlans()
        #: Hears how far the long solves of this workspace's systems are: the caller
        #: listens while it checks (:meth:`linalg.SolveMonitor.listening`). Not a cache.
        self.monitor = linalg.SolveMonitor()
        # The caches of rarer kinds of property, made on first use (below): their
        # kernels' modules are imported only by checks that meet such a property.
        self._conditions: Conditions | None = None
        self._long_run: LongRun | None = None

    @property
    def conditions(self) -> Conditions:
        """``P(F b)`` of the last conditions (:class:`conditional.Conditions`)."""
        if self._conditions is None:
            from veribattery.checker.kernels.conditional import Conditions

            self._conditions = Conditions()
        return self._conditions

    @property
    def long_run(self) -> LongRun:
        """The BSCCs and stationary distribution of the last matrix (:class:`steady.LongRun`)."""
        if self._long_run is None:
            from veribattery.checker.kernels.steady import LongRun

            self._long_run = LongRun()
        return self._long_run

    @property
    def empty(self) -> bool:
        """Whether nothing is kept yet (a new workspace, or one no check has used)."""
        made = [part for part in (self._conditions, self._long_run) if part is not None]
        return all(part.empty for part in (self.kernels, self.solvers, self.row_plans, *made))

    def prepare(self, dtmc: DTMC, formulas: Sequence[Expr]) -> None:
        """Choose the linear systems the unbounded queries among *formulas* will share on
        *dtmc*, and build them now, so that the order the formulas are then checked in
        with this workspace does not matter
        (:func:`~veribattery.checker.formula.share.share_systems`).

        :param dtmc: the chain the formulas will be checked on.
        :param formulas: property formulas (constants substituted, labels inlined).
        """
        share.share_systems(dtmc, self, formulas)
