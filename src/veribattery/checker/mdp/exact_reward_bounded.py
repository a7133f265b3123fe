"""Reward-bounded reachability on an MDP in rationals (``--exact``).

The float check's product (:func:`~veribattery.checker.mdp.reward_bounded.budget_product`)
with the model's exact probabilities copied onto every layer, solved by exact policy
iteration (:func:`~veribattery.checker.mdp.exact.exact_reach_probability`). The step
rewards must be integers exactly (a float reward within rounding of an integer is not
enough here).
"""

from __future__ import annotations

import numpy as np
from gmpy2 import mpq

from veribattery._types import BoolArray, IntArray
from veribattery.checker.formula.leaves import RewardLimit
from veribattery.checker.mdp.exact import exact_reach_probability
from veribattery.checker.mdp.model import MDP
from veribattery.checker.mdp.rational import ObjectArray
from veribattery.checker.mdp.reward_bounded import budget_product, non_integer_reward
from veribattery.checker.mdp.system import Objective
from veribattery.errors import Span
from veribattery.explore.exact.mdp import ExactMdpRewards

__all__ = ["exact_reward_bounded"]

_ZERO = mpq(0)
_ONE = mpq(1)


def exact_reward_bounded(mdp: MDP, probabilities: ObjectArray, structure: ExactMdpRewards,
                         limit: RewardLimit, left: BoolArray, right: BoolArray, *,
                         objective: Objective, span: Span) -> ObjectArray:
    """Exact ``Pmin``/``Pmax`` of ``left U{"r"}<=T right`` (``>=B``: *limit*) per state.

    :param probabilities: the exact value of each stored entry of ``mdp.transitions``.
    :raises CheckError: a step reward is negative or not an integer, or the product
        would be too large.
    """
    if not limit.gather and limit.total < 0:
        return np.full(mdp.num_states, _ZERO, dtype=object)
    from veribattery.checker.kernels.reward_layers import layered_data

    costs = _integer_costs(mdp, structure, span)
    product = budget_product(mdp, costs, limit, left, right, span)
    laid = layered_data(probabilities, product.top, gather=product.gather, one=_ONE)
    found = exact_reach_probability(product.mdp, product.target, objective=objective,
                                    remain=product.remain, probabilities=laid)
    return np.asarray(found.values[product.answer], dtype=object)


def _integer_costs(mdp: MDP, structure: ExactMdpRewards, span: Span) -> IntArray:
    """Each choice's exact step reward as a non-negative integer, or the error naming it."""
    rewards = structure.per_choice(mdp.choice_owner)
    for choice, value in enumerate(rewards):
        if value < 0 or mpq(value).denominator != 1:
            raise non_integer_reward(mdp, structure.name, choice, float(value), span)
    return np.array([int(value) for value in rewards], dtype=np.int64)
