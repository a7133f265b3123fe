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

from veribattery.checker import certify, kernels, linalg
from veribattery.checker.formula import share
from veribattery.checker.kernels import conditional, steady
from veribattery.explore.dtmc import DTMC
from veribattery.lang.nodes import Expr


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

    __slots__ = ("conditions", "kernels", "long_run", "row_plans", "solvers")

    def __init__(self) -> None:
        #: Per transition matrix: the 0/1 pre-pass (shared by matrices of one pattern),
        #: linear systems with their solvers, results (:class:`kernels.KernelMemos`).
        self.kernels = kernels.KernelMemos()
        #: Restriction and substitution plans by pattern (:class:`linalg.SolverPlans`).
        self.solvers = linalg.SolverPlans()
        #: The index work of the certificates' maps (:class:`certify.RowPlans`).
        self.row_plans = certify.RowPlans()
        #: ``P(F b)`` of the last conditions (:class:`conditional.Conditions`).
        self.conditions = conditional.Conditions()
        #: The BSCCs and stationary distribution of the last matrix (:class:`steady.LongRun`).
        self.long_run = steady.LongRun()

    @property
    def empty(self) -> bool:
        """Whether nothing is kept yet (a new workspace, or one no check has used)."""
        return all(part.empty for part in (self.kernels, self.solvers, self.row_plans,
                                           self.conditions, self.long_run))

    def prepare(self, dtmc: DTMC, formulas: Sequence[Expr]) -> None:
        """Choose the linear systems the unbounded queries among *formulas* will share on
        *dtmc*, and build them now, so that the order the formulas are then checked in
        with this workspace does not matter
        (:func:`~veribattery.checker.formula.share.share_systems`).

        :param dtmc: the chain the formulas will be checked on.
        :param formulas: property formulas (constants substituted, labels inlined).
        """
        share.share_systems(dtmc, self, formulas)
