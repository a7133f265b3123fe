"""The built MDP: one row per choice, rows grouped by the state that owns them.

A state of a PRISM ``mdp`` model has one *choice* per enabled command (or
enabled combination of synchronising commands); each choice is a probability
distribution over successor states, labelled by its action. The model is stored
as PRISM and Storm store it: one sparse matrix with a row per choice and a
column per state, and ``row_groups`` saying which rows belong to which state.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from veribattery._named import by_key
from veribattery._types import BoolArray, CsrMatrix, FloatArray, IntArray

__all__ = ["MDP", "MdpRewards"]


@dataclass(frozen=True, slots=True)
class MdpRewards:
    """One reward structure of an MDP.

    :param name: the structure's name (None when unnamed).
    :param state: reward of being in each state (one per state).
    :param choice: reward of taking each choice (its action's transition reward).
    """

    name: str | None
    state: FloatArray
    choice: FloatArray

    def per_choice(self, mdp: MDP) -> FloatArray:
        """The reward of one step taken by each choice: its state's reward plus its own.

        This is what ``F``, ``C`` and ``C<=k`` accumulate; ``I=k`` reads :attr:`state`.
        """
        return np.asarray(self.state[mdp.choice_owner] + self.choice, dtype=np.float64)


@dataclass(frozen=True, slots=True)
class MDP:
    """A Markov decision process over the reachable states of a model.

    :param transitions: ``num_choices x num_states`` CSR matrix; row *c* is the
        distribution of choice *c* (nonnegative, summing to 1).
    :param row_groups: ``num_states + 1`` offsets: the choices of state *s* are the rows
        ``row_groups[s]:row_groups[s + 1]`` (at least one per state; a deadlock has its
        self-loop).
    :param initial: indices of the initial states.
    :param labels: label name to boolean state mask.
    :param choice_actions: per choice, the index of its action in *actions*.
    :param actions: action names; ``""`` is the unlabelled action.
    :param rewards: the reward structures, in declaration order.
    :param states: one row per state, one column per variable (values), if known; it may
        be stored narrower than int64 (read columns through int64 copies).
    :param variable_names: the columns of *states*.
    :param deadlocks: number of states that had no enabled choice (given a self-loop).
    """

    transitions: CsrMatrix
    row_groups: IntArray
    initial: IntArray
    labels: Mapping[str, BoolArray] = field(default_factory=dict)
    choice_actions: IntArray | None = None
    actions: tuple[str, ...] = ("",)
    rewards: tuple[MdpRewards, ...] = ()
    states: IntArray | None = None
    variable_names: tuple[str, ...] = ()
    deadlocks: int = 0
    #: The state that owns each choice (derived from *row_groups*).
    choice_owner: IntArray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        groups = np.asarray(self.row_groups, dtype=np.int64)
        object.__setattr__(self, "row_groups", groups)
        _check_shape(self.transitions, groups)
        sizes = np.diff(groups)
        owner = np.repeat(np.arange(sizes.size, dtype=np.int64), sizes)
        object.__setattr__(self, "choice_owner", owner)
        if self.choice_actions is None:
            object.__setattr__(self, "choice_actions", np.zeros(owner.size, dtype=np.int64))
        _check_parts(self)

    @property
    def num_states(self) -> int:
        """Number of states."""
        return int(self.row_groups.size - 1)

    @property
    def num_choices(self) -> int:
        """Number of choices (rows of :attr:`transitions`)."""
        return int(self.transitions.shape[0])

    @property
    def num_transitions(self) -> int:
        """Number of stored transition probabilities (over all choices)."""
        return int(self.transitions.nnz)

    @property
    def initial_mask(self) -> BoolArray:
        """Boolean mask of the initial states."""
        mask = np.zeros(self.num_states, dtype=bool)
        mask[self.initial] = True
        return mask

    def __repr__(self) -> str:
        # Sizes and names, not the matrix and the per-choice arrays (a notebook shows it).
        return (f"MDP(states={self.num_states:,}, choices={self.num_choices:,}, "
                f"transitions={self.num_transitions:,}, initial={self.initial.size:,}, "
                f"variables={self.variable_names}, labels={tuple(self.labels)}, "
                f"rewards={tuple(r.name for r in self.rewards)}, deadlocks={self.deadlocks})")

    def action_of(self, choice: int) -> str:
        """The action label of *choice* (``""`` when unlabelled)."""
        assert self.choice_actions is not None
        return self.actions[int(self.choice_actions[choice])]

    def choices_of(self, state: int) -> range:
        """The choice indices of *state*."""
        return range(int(self.row_groups[state]), int(self.row_groups[state + 1]))

    def reward(self, key: str | int | None) -> MdpRewards:
        """The reward structure named *key*, at index *key*, or the first (None)."""
        return by_key(self.rewards, key)


def _check_shape(transitions: CsrMatrix, groups: IntArray) -> None:
    """Row groups that cover the rows in order, each state with at least one choice."""
    choices, states = transitions.shape
    if groups.ndim != 1 or groups.size != states + 1:
        raise ValueError(f"row_groups needs {states + 1} entries, not {groups.size}")
    if groups[0] != 0 or groups[-1] != choices:
        raise ValueError("row_groups must start at 0 and end at the number of choices")
    if np.any(np.diff(groups) < 1):
        raise ValueError("every state needs at least one choice (deadlocks get a self-loop)")


def _check_parts(mdp: MDP) -> None:
    """Probabilities that are distributions, and parts of the right lengths."""
    data = mdp.transitions.data
    if data.size and not (np.all(np.isfinite(data)) and np.all(data >= 0)):
        raise ValueError("transition probabilities must be finite and nonnegative")
    if np.any(np.diff(mdp.transitions.indptr) == 0) or np.any(
            np.add.reduceat(data > 0, mdp.transitions.indptr[:-1]) == 0):
        raise ValueError("every choice needs a successor with positive probability")
    assert mdp.choice_actions is not None
    if mdp.choice_actions.shape != (mdp.num_choices,):
        raise ValueError("choice_actions needs one entry per choice")
    for structure in mdp.rewards:
        if structure.state.shape != (mdp.num_states,) or structure.choice.shape != (
                mdp.num_choices,):
            raise ValueError(f"reward structure {structure.name!r} has the wrong length")
    for name, mask in mdp.labels.items():
        if mask.shape != (mdp.num_states,):
            raise ValueError(f"label {name!r} needs one entry per state")
