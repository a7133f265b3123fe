"""The ``--exact`` checker: PCTL in exact rational arithmetic (gmpy2).

- :mod:`~veribattery.checker.exact.pctl`: the recursion over formulas and the results;
- :mod:`~veribattery.checker.exact.numeric`: path probabilities and rewards on state masks;
- :mod:`~veribattery.checker.exact.filtered`: exact results, and top-level filters;
- :mod:`~veribattery.checker.exact.storm`: Storm's conditional and reward-bounded formulas;
- :mod:`~veribattery.checker.exact.solve`: the SCC-wise exact solve of the linear systems.

Importing this package imports gmpy2: callers import it when ``--exact`` is asked for.
"""

from veribattery.checker.exact.filtered import ExactCheckResult
from veribattery.checker.exact.numeric import ExactValues
from veribattery.checker.exact.pctl import (
    check_exact,
    exact_values,
)

__all__ = ["ExactCheckResult", "ExactValues", "check_exact", "exact_values"]
