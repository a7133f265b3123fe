"""Numeric kernels of the DTMC checker: matrices and masks in, arrays out.

Every kernel takes the row-stochastic CSR transition matrix *P* and boolean
state masks, never formulas (the recursion over formulas lives in
:mod:`veribattery.checker.formula.pctl`). Unbounded properties run the qualitative
pre-pass first (:func:`prob0`, :func:`prob1`, both graph searches in C via
:mod:`scipy.sparse.csgraph`, in :mod:`~veribattery.checker.kernels.prepass`), so the
linear systems are only solved on the states whose value is strictly between the
trivial ones, where they are nonsingular.

Every kernel returns :class:`~veribattery.checker.certify.bounds.Bounds`: point values
with certified enclosures (``docs/numerics.md``). The modules:

- :mod:`~veribattery.checker.kernels.systems`: the memos and the kept linear systems;
- :mod:`~veribattery.checker.kernels.prepass`: the 0/1 pre-pass and the systems' unknowns;
- :mod:`~veribattery.checker.kernels.until`: unbounded until and reachability rewards;
- :mod:`~veribattery.checker.kernels.steps`: step-bounded kernels;
- :mod:`~veribattery.checker.kernels.conditional`, :mod:`~veribattery.checker.kernels.steady`,
  :mod:`~veribattery.checker.kernels.reward_bounded` (with
  :mod:`~veribattery.checker.kernels.reward_radius`): conditional, long-run and
  reward-bounded properties.

This package re-exports the first four modules' public functions.
"""

from veribattery.checker.kernels.prepass import (
    prepare_reach,
    prepare_untils,
    prob0,
    prob1,
    reach_unknowns,
    reward_free_zeros,
    until_unknowns,
)
from veribattery.checker.kernels.steps import (
    absorption,
    bounded_until_probs,
    cumulative_rewards,
    instantaneous_rewards,
    interval_until_probs,
    lower_bounded_until_probs,
    next_probs,
)
from veribattery.checker.kernels.systems import KernelMemos, shared_system
from veribattery.checker.kernels.until import (
    focus_rows,
    need_whole,
    quick_bounds,
    reach_rewards,
    until_probs,
)

__all__ = [
    "KernelMemos",
    "absorption",
    "bounded_until_probs",
    "cumulative_rewards",
    "focus_rows",
    "instantaneous_rewards",
    "interval_until_probs",
    "lower_bounded_until_probs",
    "need_whole",
    "next_probs",
    "prepare_reach",
    "prepare_untils",
    "prob0",
    "prob1",
    "quick_bounds",
    "reach_rewards",
    "reach_unknowns",
    "reward_free_zeros",
    "shared_system",
    "until_probs",
    "until_unknowns",
]
