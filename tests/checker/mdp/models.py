"""Small MDPs written out by hand, with their values solved on paper."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from fractions import Fraction

import numpy as np
import scipy.sparse as sp

from veribattery.checker.mdp import MDP, MdpRewards

#: Per state, its choices; per choice, ``(successor, probability)`` pairs.
Choices = Sequence[Sequence[Sequence[tuple[int, Fraction | float]]]]


def mdp_from(states: Choices, *, rewards: Sequence[Sequence[float]] | None = None,
             labels: Mapping[str, Sequence[int]] | None = None) -> MDP:
    """An :class:`MDP` from per-state choice lists (and per-state, per-choice rewards)."""
    data, columns, indptr, groups = [], [], [0], [0]
    for choices in states:
        for choice in choices:
            for successor, probability in choice:
                columns.append(successor)
                data.append(float(probability))
            indptr.append(len(columns))
        groups.append(len(indptr) - 1)
    n = len(states)
    transitions = sp.csr_matrix((data, columns, indptr), shape=(len(indptr) - 1, n))
    masks = {}
    for name, members in (labels or {}).items():
        mask = np.zeros(n, dtype=bool)
        mask[list(members)] = True
        masks[name] = mask
    structures = ()
    if rewards is not None:
        per_choice = np.array([r for state in rewards for r in state], dtype=float)
        structures = (MdpRewards("r", np.zeros(n), per_choice),)
    return MDP(transitions, np.array(groups), np.array([0]), masks, rewards=structures)


def mask(n: int, members: Sequence[int]) -> np.ndarray:
    """A boolean mask of *n* states with *members* set."""
    out = np.zeros(n, dtype=bool)
    out[list(members)] = True
    return out


HALF, THIRD = Fraction(1, 2), Fraction(1, 3)

#: A two-state end component {0, 1} with exits: from 0, 0.4 to the goal (2) and 0.6
#: to a sink (3); from 1, 0.7 to the goal. Pmax = 0.7 in 0 and 1, but in state 1 the
#: choice back to 0 (listed first) ties with the exit: a strategy that takes it
#: stays in the component forever (probability 0).
TIED_EXIT = mdp_from([
    [[(1, 1)], [(2, 0.4), (3, 0.6)]],
    [[(0, 1)], [(2, 0.7), (3, 0.3)]],
    [[(2, 1)]],
    [[(3, 1)]],
], labels={"goal": [2]})

#: States 0 and 1 swap at reward 0; state 1 may leave to the goal (2) at reward 5.
#: Rmin [F goal] = 5 in both (value iteration from 0 stays at 0: the cycle's fixed
#: point). State 3 never reaches the goal (Rmin = inf); state 4 chooses between a
#: gamble that may fall into 3 (reward 1, infinite expectation) and a sure way at
#: reward 10 (Rmin = 10).
ZERO_CYCLE = mdp_from([
    [[(1, 1)]],
    [[(0, 1)], [(2, 1)]],
    [[(2, 1)]],
    [[(3, 1)]],
    [[(2, HALF), (3, HALF)], [(2, 1)]],
], rewards=[[0], [0, 5], [0], [0], [1, 10]], labels={"goal": [2]})


def entries_of(states: Choices) -> np.ndarray:
    """The probabilities of :func:`mdp_from`'s stored entries as exact ``mpq``s, read
    from their decimal or fraction text (not from the float)."""
    from gmpy2 import mpq

    return np.array([mpq(str(Fraction(str(p)) if isinstance(p, float) else p))
                     for choices in states for choice in choices for _, p in choice],
                    dtype=object)


TIED_EXIT_CHOICES: Choices = [
    [[(1, 1)], [(2, 0.4), (3, 0.6)]],
    [[(0, 1)], [(2, 0.7), (3, 0.3)]],
    [[(2, 1)]],
    [[(3, 1)]],
]
