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
"""

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
