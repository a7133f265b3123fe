"""Reward-bounded reachability on an MDP: ``Pmin``/``Pmax`` of ``left U{"r"}<=T right``.

As on the DTMC side (and in Storm), *right* must be reached through *left* states with
at most T of reward accumulated, the step that enters *right* included; each step costs
its state's reward plus its choice's action reward, a non-negative integer. The budget
left is part of the state: the product MDP has a copy of the model per budget
``0..T`` and one absorbing *spent* state, and a choice taken with budget ``b`` leads to
its successors with budget ``b - r`` (to *spent* if that is negative). Its optimum
from ``(s, T)`` is the reward-bounded optimum from ``s``, so the product is solved by
:func:`~veribattery.checker.mdp.reach.reach_probability` with its certified bounds (a
strategy on the product depends on the budget left: none is exported).

The product has ``T + 1`` times the model's transitions; one that would pass
:data:`PRODUCT_LIMIT` is refused with its size (Storm's epoch-by-epoch algorithm keeps
one copy at a time, which this one does not).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from veribattery._types import BoolArray, IntArray
from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.mdp.model import MDP, MdpRewards
from veribattery.checker.mdp.reach import reach_probability
from veribattery.checker.mdp.system import Objective
from veribattery.errors import CheckError, Span
from veribattery.explore.build.successors import format_state

__all__ = ["PRODUCT_LIMIT", "reward_bounded_reach"]

#: The most transitions the product of budgets may have (about 20 bytes each while it
#: is solved, several times over: some 2 GB at the limit).
PRODUCT_LIMIT = 20_000_000


def reward_bounded_reach(mdp: MDP, structure: MdpRewards, budget: int, left: BoolArray,
                         right: BoolArray, *, objective: Objective, span: Span) -> Bounds:
    """Certified ``Pmin``/``Pmax`` of ``left U{"r"}<=budget right`` in every state.

    :raises CheckError: a step's reward is negative or not an integer, or the product
        would have more than :data:`PRODUCT_LIMIT` transitions.
    """
    n = mdp.num_states
    if budget < 0:
        return Bounds.exact(np.zeros(n))
    costs = _step_costs(mdp, structure, span)
    size = (budget + 1) * mdp.transitions.nnz
    if size > PRODUCT_LIMIT:
        raise CheckError(f"a reward bound of {budget} makes a product of {size:,} transitions "
                         f"on this MDP (at most {PRODUCT_LIMIT:,}): use a smaller bound",
                         span)
    product = _budget_product(mdp, costs, budget)
    spent = np.zeros(1, dtype=bool)
    target = np.concatenate([np.tile(right, budget + 1), spent])
    remain = np.concatenate([np.tile(left, budget + 1), spent])
    found = reach_probability(product, target, objective=objective, remain=remain).bounds
    return found.at(np.arange(budget * n, (budget + 1) * n))


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


def _budget_product(mdp: MDP, costs: IntArray, budget: int) -> MDP:
    """The MDP over (state, budget left) pairs, ``b * n + s``, then the *spent* state."""
    n, m = mdp.num_states, mdp.num_choices
    matrix = sp.csr_matrix(mdp.transitions)
    per_row = np.diff(matrix.indptr)
    entry_cost = np.repeat(costs, per_row)
    spent = (budget + 1) * n
    columns = [np.where(b - entry_cost >= 0, (b - entry_cost) * n + matrix.indices, spent)
               for b in range(budget + 1)]
    indices = np.concatenate([*columns, [spent]]).astype(np.int64)
    data = np.concatenate([np.tile(matrix.data, budget + 1), [1.0]])
    layers = np.arange(budget + 1, dtype=np.int64)[:, None]
    entries, rows = (budget + 1) * matrix.nnz, (budget + 1) * m
    indptr = np.concatenate([(layers * matrix.nnz + matrix.indptr[:-1]).ravel(),
                             [entries, entries + 1]])
    groups = np.concatenate([(layers * m + mdp.row_groups[:-1]).ravel(), [rows, rows + 1]])
    transitions = sp.csr_matrix((data, indices, indptr), shape=(rows + 1, spent + 1))
    initial = budget * n + mdp.initial
    return MDP(transitions, groups.astype(np.int64), initial.astype(np.int64))
