"""Markov decision processes: optimal values with certified bounds, and strategies.

The numeric core of the MDP checker, independent of the language: kernels take an
:class:`MDP` (a row per choice, rows grouped by state) and state masks, and return
an :class:`MdpResult` -- per state, the optimal value inside a certified interval,
and a strategy that attains it. ``docs/mdp-numerics.md`` says how each operator is
certified.
"""

from veribattery.checker.mdp.exact import (
    ExactMdpResult,
    exact_probabilities,
    exact_reach_probability,
    exact_reach_reward,
    exact_total_reward,
)
from veribattery.checker.mdp.model import MDP, MdpRewards
from veribattery.checker.mdp.multi import (
    Constraint,
    MultiResult,
    Reach,
    Total,
    multi_achievable,
    multi_optimum,
)
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

__all__ = [
    "MDP",
    "Constraint",
    "ExactMdpResult",
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
    "multi_achievable",
    "multi_optimum",
    "next_probability",
    "reach_probability",
    "reach_reward",
    "total_reward",
]
