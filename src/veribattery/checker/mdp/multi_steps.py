"""The MDP unfolded with a step counter, for step-bounded objectives in ``multi(...)``.

``R [ C<=k ]`` counts the rewards of the first *k* steps only, and a strategy that
optimises it together with other objectives must know how many steps it has taken.
Unfolding the MDP with a counter ``t = 0..horizon`` (saturating at *horizon*) makes
that count part of the state: ``R [ C<=k ]`` becomes the total reward of the
choices taken while ``t < k``, which the multi-objective programme
(:mod:`~veribattery.checker.mdp.multi`) handles as it handles ``R [ C ]``. State
``(s, t)`` is ``t * n + s`` and choice ``(c, t)`` is ``t * m + c`` (*n* states, *m*
choices); layer *t* moves to layer ``min(t + 1, horizon)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from veribattery._types import BoolArray, FloatArray
from veribattery.checker.mdp.model import MDP

__all__ = ["SteppedMdp"]


@dataclass(frozen=True, slots=True)
class SteppedMdp:
    """*mdp* unfolded with a step counter saturating at *horizon*.

    :param original: the MDP unfolded.
    :param horizon: the last counter value (the largest step bound).
    :param mdp: the unfolded MDP; its initial states are the original ones at step 0.
    """

    original: MDP
    horizon: int
    mdp: MDP

    @classmethod
    def of(cls, original: MDP, horizon: int) -> SteppedMdp:
        """Unfold *original* up to step *horizon* (``horizon + 1`` copies of it)."""
        n, m = original.num_states, original.num_choices
        layers = horizon + 1
        rows = sp.csr_matrix(original.transitions)
        blocks = []
        for step in range(layers):
            following = min(step + 1, horizon)
            blocks.append(sp.csr_matrix((rows.data, rows.indices + following * n, rows.indptr),
                                        shape=(m, layers * n)))
        sizes = np.tile(np.diff(original.row_groups), layers)
        groups = np.concatenate([[0], np.cumsum(sizes)])
        assert original.choice_actions is not None
        unfolded = MDP(sp.csr_matrix(sp.vstack(blocks)), groups, original.initial.copy(),
                       choice_actions=np.tile(original.choice_actions, layers),
                       actions=original.actions)
        return cls(original, horizon, unfolded)

    def states(self, mask: BoolArray) -> BoolArray:
        """A state set of the original MDP, at every step."""
        return np.tile(np.asarray(mask, dtype=bool), self.horizon + 1)

    def rewards(self, per_choice: FloatArray, steps: int | None = None) -> FloatArray:
        """Per choice of the unfolded MDP, *per_choice* for the choices taken before
        step *steps* (``C<=steps``), 0 after; every step when *steps* is None (``C``)."""
        layers = self.horizon + 1
        tiled = np.tile(np.asarray(per_choice, dtype=np.float64), layers)
        if steps is None:
            return tiled
        counting = np.repeat(np.arange(layers) < steps, self.original.num_choices)
        return np.where(counting, tiled, 0.0)
