"""Markov decision processes: optimal values with certified bounds, and strategies.

The numeric core of the MDP checker, independent of the language: kernels take an
:class:`MDP` (a row per choice, rows grouped by state) and state masks, and return
an :class:`MdpResult` -- per state, the optimal value inside a certified interval,
and a strategy that attains it. ``docs/mdp-numerics.md`` says how each operator is
certified.
"""

from __future__ import annotations

from types import MappingProxyType
from typing import TYPE_CHECKING

from veribattery._lazy import lazy_exports
from veribattery.checker.mdp.model import MDP, MdpRewards
from veribattery.checker.mdp.reach import reach_probability
from veribattery.checker.mdp.result import MdpResult
from veribattery.checker.mdp.rewards import reach_reward, total_reward
from veribattery.checker.mdp.stepped import (
    bounded_reach_probability,
    cumulative_reward,
    instantaneous_reward,
    interval_reach_probability,
    later_reach_probability,
    next_probability,
)
from veribattery.checker.mdp.strategy import StepStrategy, Strategy, induced_chain
from veribattery.checker.mdp.system import Objective

if TYPE_CHECKING:
    from veribattery.checker.mdp.exact import (
        ExactMdpResult,
        exact_probabilities,
        exact_reach_probability,
        exact_reach_reward,
        exact_total_reward,
    )
    from veribattery.checker.mdp.multi import (
        Constraint,
        MultiResult,
        Reach,
        Total,
        multi_achievable,
        multi_optimum,
    )
    from veribattery.checker.mdp.multi_front import (
        CertifiedAnswer,
        Front,
        FrontSearch,
        least_total_at,
        pareto_front,
    )

# Imported on first use: the exact engine (gmpy2) and the multi-objective LP are not
# needed to check a float property, and small models are dominated by start-up.
_EXPORTS = MappingProxyType({
    "veribattery.checker.mdp.exact": ("ExactMdpResult", "exact_probabilities",
                                      "exact_reach_probability", "exact_reach_reward",
                                      "exact_total_reward"),
    "veribattery.checker.mdp.multi": ("Constraint", "MultiResult", "Reach", "Total",
                                      "multi_achievable", "multi_optimum"),
    "veribattery.checker.mdp.multi_front": ("CertifiedAnswer", "Front", "FrontSearch",
                                            "least_total_at", "pareto_front"),
})
__getattr__ = lazy_exports(__name__, _EXPORTS)


__all__ = [
    "MDP",
    "CertifiedAnswer",
    "Constraint",
    "ExactMdpResult",
    "Front",
    "FrontSearch",
    "MdpResult",
    "MdpRewards",
    "MultiResult",
    "Objective",
    "Reach",
    "StepStrategy",
    "Strategy",
    "Total",
    "bounded_reach_probability",
    "cumulative_reward",
    "exact_probabilities",
    "exact_reach_probability",
    "exact_reach_reward",
    "exact_total_reward",
    "induced_chain",
    "instantaneous_reward",
    "interval_reach_probability",
    "later_reach_probability",
    "least_total_at",
    "multi_achievable",
    "multi_optimum",
    "next_probability",
    "pareto_front",
    "reach_probability",
    "reach_reward",
    "total_reward",
]
