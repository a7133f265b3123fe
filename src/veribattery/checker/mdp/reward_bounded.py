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

The product has ``T + 1`` times the model's transitions; past
:data:`~veribattery.checker.kernels.reward_layers.PRODUCT_LIMIT` the layers are solved
one at a time instead, from layer 0 up, as Storm's epoch-based algorithm does
(:mod:`~veribattery.checker.kernels.reward_epochs`). ``--exact`` builds the product
(:mod:`.exact_reward_bounded`) and refuses one past the limit.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from veribattery._types import BoolArray, CsrMatrix, IntArray
from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.certify.fixpoint import Progress
from veribattery.checker.formula.leaves import RewardLimit
from veribattery.checker.mdp.model import MDP, MdpRewards
from veribattery.checker.mdp.reach import reach_probability
from veribattery.checker.mdp.reward_levels import LevelledLayers
from veribattery.checker.mdp.system import Objective
from veribattery.errors import CheckError, Span
from veribattery.explore.build.successors import format_state

if TYPE_CHECKING:
    from veribattery.checker.kernels.reward_epochs import LayerSolve

__all__ = ["BudgetProduct", "budget_product", "non_integer_reward", "reward_bounded_reach"]


@dataclass(frozen=True, slots=True)
class BudgetProduct:
    """The product MDP of a reward bound, and where to read the answer in it.

    :param answer: per model state, its product state with the whole bound ahead.
    :param top: the last layer (T or B).
    :param gather: the layers count reward still needed (``>=B``), not budget left.
    """

    mdp: MDP
    target: BoolArray
    remain: BoolArray
    answer: IntArray
    top: int
    gather: bool


def reward_bounded_reach(mdp: MDP, structure: MdpRewards, limit: RewardLimit,
                         left: BoolArray, right: BoolArray, *, objective: Objective,
                         span: Span, progress: Progress | None = None) -> Bounds:
    """Certified ``Pmin``/``Pmax`` of ``left U{"r"}<=T right`` (``>=B``: *limit*) in every
    state.

    :param progress: told how many layers are solved, where they are solved one at a time.
    :raises CheckError: a step's reward is negative or not an integer, or the bound
        makes too many layers (:func:`~veribattery.checker.kernels.reward_layers.
        product_built`).
    """
    if not limit.gather and limit.total < 0:
        return Bounds.exact(np.zeros(mdp.num_states))
    costs = _step_costs(mdp, structure, span)
    # (the DTMC kernels' package, imported only when a reward bound is checked: an MDP's
    # other checks do not read it)
    from veribattery.checker.kernels import reward_layers
    from veribattery.checker.kernels.reward_epochs import RewardEpochs

    top = max(limit.total, 0)
    one_pass = LevelledLayers(mdp.transitions, mdp.row_groups, costs, objective, left, right)
    # (where every layer is one pass, layers beat the product below its limit too:
    # firewire's deadline at delay=3, deadline=800, 0.8 s and 60 MB against 3.2 s and
    # 763 MB; the layers of a lower bound pass through the target, so not all in one)
    layered = (not limit.gather and top + 1 <= reward_layers.EPOCH_LIMIT
               and one_pass.passes(left, right))
    if layered or not reward_layers.product_built(mdp.transitions.nnz, top, limit.total,
                                                  span):
        epochs = RewardEpochs(mdp.transitions, costs, left, right, limit.gather)
        return epochs.bounds(top, _layer_until(mdp, objective), progress, one_pass)
    product = budget_product(mdp, costs, limit, left, right, span)
    found = reach_probability(product.mdp, product.target, objective=objective,
                              remain=product.remain).bounds
    return found.at(product.answer)


def _layer_until(mdp: MDP, objective: Objective) -> LayerSolve:
    """The optimum of ``remain U target`` on one layer's choices (the model's, then one
    each for the *yes* and *no* states of :mod:`~veribattery.checker.kernels.reward_epochs`)."""
    rows = mdp.num_choices
    groups = np.concatenate([mdp.row_groups, [rows + 1, rows + 2]])

    def solve(choices: CsrMatrix, remain: BoolArray, target: BoolArray) -> Bounds:
        layer = MDP(choices, groups, mdp.initial)
        return reach_probability(layer, target, objective=objective, remain=remain).bounds

    return solve


def budget_product(mdp: MDP, costs: IntArray, limit: RewardLimit, left: BoolArray,
                   right: BoolArray, span: Span) -> BudgetProduct:
    """The product of *mdp* with the budget left (the reward still needed) of *limit*, a
    bound that admits some path (not ``<=T`` with ``T < 0``).

    :param costs: each choice's step reward, a non-negative integer.
    :raises CheckError: the product would be too large (:func:`~veribattery.checker.
        kernels.reward_layers.require_product_size`).
    """
    # (the DTMC kernels' package, imported only when a reward bound is checked: an MDP's
    # other checks do not read it)
    from veribattery.checker.kernels.reward_layers import (
        LayeredSets,
        layered_groups,
        layered_rows,
        require_product_size,
    )

    n, top, gather = mdp.num_states, max(limit.total, 0), limit.gather
    require_product_size(mdp.transitions.nnz, top, limit.total, span)
    product = MDP(layered_rows(mdp.transitions, costs, top, gather=gather),
                  layered_groups(mdp.row_groups, top, gather=gather),
                  (top * n + mdp.initial).astype(np.int64))
    sets = LayeredSets.of(left, right, top, gather=gather)
    return BudgetProduct(product, sets.target, sets.remain, sets.answer, top, gather)


def _step_costs(mdp: MDP, structure: MdpRewards, span: Span) -> IntArray:
    """Each choice's step reward (its state's plus its own) as a non-negative integer."""
    from veribattery.checker.kernels.reward_bounded import NonIntegerReward, integer_levels

    try:
        return integer_levels(structure.per_choice(mdp))
    except NonIntegerReward as exc:
        raise non_integer_reward(mdp, structure.name, exc.state, exc.value, span) from None


def non_integer_reward(mdp: MDP, name: str | None, choice: int, value: float,
                       span: Span) -> CheckError:
    """The error for a reward bound on a structure that gives *choice* a step reward
    that is negative or not an integer."""
    state = int(mdp.choice_owner[choice])
    shown = f'"{name}"' if name else "(unnamed)"
    return CheckError(f"a reward bound needs non-negative integer rewards, but reward "
                      f"structure {shown} gives {value:g} to a choice of state "
                      f"{_state_text(mdp, state)}", span)


def _state_text(mdp: MDP, state: int) -> str:
    """``(x=1, y=2)``, or the state's index where the MDP has no valuations."""
    if mdp.states is None:
        return str(state)
    return f"({format_state(mdp.variable_names, mdp.states[state])})"
