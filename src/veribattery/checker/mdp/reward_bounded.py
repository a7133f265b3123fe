"""Reward-bounded reachability on an MDP: ``Pmin``/``Pmax`` of ``left U{"r"}<=T right``
and of ``left U{"r"}>=B right``.

As on the DTMC side (and in Storm), *right* must be reached through *left* states with
at most T (at least B) of reward accumulated, the step that enters *right* included;
each step costs its state's reward plus its choice's action reward, a non-negative
integer. The reward left to spend (still to gather) is part of the state: the product
MDP has a copy of the model per layer ``0..T`` (``0..B``), built by
:mod:`~veribattery.checker.kernels.reward_layers`. With an upper bound a choice taken
with budget ``b`` leads to its successors with budget ``b - r`` (to an absorbing
*spent* state if that is negative); with a lower bound, to ``max(0, b - r)``, and
*right* counts only on layer 0 (elsewhere the path goes on, through *left*). The
product's optimum from ``(s, T)`` is the reward-bounded optimum from ``s``, so the
product is solved by :func:`~veribattery.checker.mdp.reach.reach_probability` with its
certified bounds (a strategy on the product depends on the layer: none is exported).

The product has ``T + 1`` times the model's transitions; one that would pass
:data:`~veribattery.checker.kernels.reward_layers.PRODUCT_LIMIT` is refused with its
size (Storm's epoch-by-epoch algorithm keeps one copy at a time, which this one does
not).
"""

from __future__ import annotations

import numpy as np

from veribattery._types import BoolArray, IntArray
from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.formula.leaves import RewardLimit
from veribattery.checker.mdp.model import MDP, MdpRewards
from veribattery.checker.mdp.reach import reach_probability
from veribattery.checker.mdp.system import Objective
from veribattery.errors import CheckError, Span
from veribattery.explore.build.successors import format_state

__all__ = ["reward_bounded_reach"]


def reward_bounded_reach(mdp: MDP, structure: MdpRewards, limit: RewardLimit,
                         left: BoolArray, right: BoolArray, *, objective: Objective,
                         span: Span) -> Bounds:
    """Certified ``Pmin``/``Pmax`` of ``left U{"r"}<=T right`` (``>=B``: *limit*) in every
    state.

    :raises CheckError: a step's reward is negative or not an integer, or the product
        would be too large (:func:`~veribattery.checker.kernels.reward_layers.
        require_product_size`).
    """
    # (the DTMC kernels' package, imported only when a reward bound is checked: an MDP's
    # other checks do not read it)
    from veribattery.checker.kernels.reward_layers import (
        layered_groups,
        layered_rows,
        require_product_size,
    )

    n = mdp.num_states
    if not limit.gather and limit.total < 0:
        return Bounds.exact(np.zeros(n))
    top = max(limit.total, 0)
    costs = _step_costs(mdp, structure, span)
    require_product_size(mdp.transitions.nnz, top, limit.total, span)
    product = MDP(layered_rows(mdp.transitions, costs, top, gather=limit.gather),
                  layered_groups(mdp.row_groups, top, gather=limit.gather),
                  (top * n + mdp.initial).astype(np.int64))
    if limit.gather:
        target = np.concatenate([right, np.zeros(top * n, dtype=bool)])
        remain = np.tile(left, top + 1)
    else:
        target = np.concatenate([np.tile(right, top + 1), [False]])
        remain = np.concatenate([np.tile(left, top + 1), [False]])
    found = reach_probability(product, target, objective=objective, remain=remain).bounds
    return found.at(np.arange(top * n, (top + 1) * n))


def _step_costs(mdp: MDP, structure: MdpRewards, span: Span) -> IntArray:
    """Each choice's step reward (its state's plus its own) as a non-negative integer."""
    # (the DTMC kernels' package, imported only when a reward bound is checked: an MDP's
    # other checks do not read it)
    from veribattery.checker.kernels.reward_bounded import NonIntegerReward, integer_levels

    try:
        return integer_levels(structure.per_choice(mdp))
    except NonIntegerReward as exc:
        state = int(mdp.choice_owner[exc.state])
        name = f'"{structure.name}"' if structure.name else "(unnamed)"
        raise CheckError(f"a reward bound needs non-negative integer rewards, but reward "
                         f"structure {name} gives {exc.value:g} to a choice of state "
                         f"{_state_text(mdp, state)}", span) from None


def _state_text(mdp: MDP, state: int) -> str:
    """``(x=1, y=2)``, or the state's index where the MDP has no valuations."""
    if mdp.states is None:
        return str(state)
    return f"({format_state(mdp.variable_names, mdp.states[state])})"
