"""The built DTMC: the object that the builder produces and the checker consumes."""

from __future__ import annotations

from dataclasses import field

import numpy as np

from veribattery._record import record
from veribattery._types import BoolArray, CsrMatrix, FloatArray, IntArray


@record
class RewardVectors:
    """One reward structure, as expected reward per state and step.

    *state* is the state reward of each state; *transition* the expected
    transition (action) reward of the step taken from each state. ``C<=k`` and
    ``F`` count both; ``I=k`` counts *state* only.
    """

    name: str | None
    state: FloatArray
    transition: FloatArray

    @property
    def total(self) -> FloatArray:
        """State plus expected transition reward per step."""
        return self.state + self.transition


@record
class DTMC:
    """A discrete-time Markov chain over the reachable states of a model.

    :param transitions: row-stochastic CSR matrix (num_states x num_states).
    :param states: one row per state, one column per variable (values, not offsets).
    :param variable_names: column names of *states*.
    :param initial: indices of the initial states.
    :param labels: model labels as boolean masks (``"deadlock"`` and ``"init"`` included).
    :param rewards: reward structures in declaration order.
    :param deadlocks: number of states that had no enabled command (given a self-loop).
    :param nondeterministic: number of states where several commands were enabled.
    """

    transitions: CsrMatrix
    states: IntArray
    variable_names: tuple[str, ...]
    initial: IntArray
    labels: dict[str, BoolArray]
    rewards: tuple[RewardVectors, ...]
    deadlocks: int = 0
    nondeterministic: int = 0
    warnings: tuple[str, ...] = field(default=())

    @property
    def num_states(self) -> int:
        """Number of reachable states."""
        return int(self.transitions.shape[0])

    @property
    def num_transitions(self) -> int:
        """Number of non-zero transition probabilities (distinct successors summed)."""
        return int(self.transitions.nnz)

    @property
    def initial_mask(self) -> BoolArray:
        """Boolean mask of the initial states."""
        mask = np.zeros(self.num_states, dtype=bool)
        mask[self.initial] = True
        return mask

    def column(self, name: str) -> IntArray:
        """The values of variable *name* in every state."""
        return self.states[:, self.variable_names.index(name)]

    def reward(self, key: str | int | None) -> RewardVectors:
        """The reward structure named *key*, at index *key*, or the first (None)."""
        if key is None or isinstance(key, int):
            return self.rewards[key or 0]
        for structure in self.rewards:
            if structure.name == key:
                return structure
        raise KeyError(key)
