"""Linear systems ``(I - P_mm) x = b`` of the unbounded kernels.

- :mod:`~veribattery.checker.linalg.restriction`: the restricted matrix and its plans;
- :mod:`~veribattery.checker.linalg.factorization`: the direct solvers with
  extended-precision refinement, and the acceptance rule;
- :mod:`~veribattery.checker.linalg.triangular`: substitution on acyclic systems;
- :mod:`~veribattery.checker.linalg.iterative`: backward error and the iterative fallback;
- :mod:`~veribattery.checker.linalg.scc`, :mod:`~veribattery.checker.linalg.topological`:
  SCC-wise solves; :mod:`~veribattery.checker.linalg.rational`: the exact fallback;
- :mod:`~veribattery.checker.linalg.monitor`: how far a long solve is, for a listener;
- :mod:`~veribattery.checker.linalg.scatter`: ``M^T x`` at the cost of *x*'s nonzeros.

This package re-exports the public names of the first four modules, the monitor and the
transposed product.

The modules are imported when a name is first read from this package: an MDP's check
reads :mod:`~veribattery.checker.linalg.topological` only.
"""

from __future__ import annotations

from types import MappingProxyType
from typing import TYPE_CHECKING

from veribattery._lazy import lazy_exports

if TYPE_CHECKING:
    from veribattery.checker.linalg.factorization import (
        Factorization,
        PinnedSolver,
        QuickSolver,
        extended_product,
        solve,
    )
    from veribattery.checker.linalg.iterative import backward_error, matrix_norm, solve_iterative
    from veribattery.checker.linalg.monitor import SolveListener, SolveMonitor
    from veribattery.checker.linalg.restriction import (
        SolverPlans,
        index_digest,
        restricted_matrix,
        restricted_parts,
        unplanned_parts,
    )
    from veribattery.checker.linalg.scatter import TransposedProduct

_EXPORTS = MappingProxyType({
    "veribattery.checker.linalg.factorization": (
        "Factorization", "PinnedSolver", "QuickSolver", "extended_product", "solve"),
    "veribattery.checker.linalg.iterative": ("backward_error", "matrix_norm", "solve_iterative"),
    "veribattery.checker.linalg.monitor": ("SolveListener", "SolveMonitor"),
    "veribattery.checker.linalg.restriction": (
        "SolverPlans", "index_digest", "restricted_matrix", "restricted_parts",
        "unplanned_parts"),
    "veribattery.checker.linalg.scatter": ("TransposedProduct",),
})
__getattr__ = lazy_exports(__name__, _EXPORTS)


__all__ = [
    "Factorization",
    "PinnedSolver",
    "QuickSolver",
    "SolveListener",
    "SolveMonitor",
    "SolverPlans",
    "TransposedProduct",
    "backward_error",
    "extended_product",
    "index_digest",
    "matrix_norm",
    "restricted_matrix",
    "restricted_parts",
    "solve",
    "solve_iterative",
    "unplanned_parts",
]
