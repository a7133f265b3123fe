"""The built DTMC: the object that the builder produces and the checker consumes."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from veribattery._named import by_key
from veribattery._types import BoolArray, CsrMatrix, FloatArray, IntArray
from veribattery.errors import ArgumentError, PrismSemanticError

#: Reward vectors at least this long are stored as one broadcast zero when all zero.
_ZERO_VIEW_MIN = 1 << 16


def require_dtmc(model_type: str) -> None:
    """Refuse to build a DTMC of a model of another type: an MDP's choices are a
    strategy's to make, not coin tosses.

    :raises PrismSemanticError: when *model_type* is not ``dtmc``.
    """
    if model_type != "dtmc":
        # Library callers (check_model, build_dtmc) and CLI runs (--explain, --simulate)
        # both end here: name the way to check an MDP for each.
        raise PrismSemanticError(
            f"this is an {model_type.upper()}, but this builds a DTMC and needs a 'dtmc' "
            "model: check an MDP's properties with veribattery.check_prism_file (from "
            "Python) or 'veribattery prism' without --explain or --simulate")


def _all_plus_zero(values: FloatArray) -> bool:
    """Whether every entry is +0.0 (no nonzero, no -0.0)."""
    return not values.any() and not np.signbit(values).any()


@dataclass(frozen=True, slots=True)
class RewardVectors:
    """One reward structure, as expected reward per state and step.

    *state* is the state reward of each state; *transition* the expected
    transition (action) reward of the step taken from each state. ``C<=k`` and
    ``F`` count both; ``I=k`` counts *state* only.
    """

    name: str | None
    state: FloatArray
    transition: FloatArray

    def __post_init__(self) -> None:
        # A part that is +0 everywhere (the mission's rewards are all transition
        # rewards) is kept as a read-only broadcast of one zero: 11 MB less per part
        # at 1.4M states, the same values to every reader.
        for part in ("state", "transition"):
            values = getattr(self, part)
            if values.size >= _ZERO_VIEW_MIN and _all_plus_zero(values):
                object.__setattr__(self, part, np.broadcast_to(np.float64(0.0), values.shape))

    @property
    def total(self) -> FloatArray:
        """State plus expected transition reward per step."""
        return self.state + self.transition


@dataclass(frozen=True, slots=True)
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
    :param stopped: number of states left unexpanded, every property decided there
        (given a self-loop; see ``explore.build.halting``).
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
    stopped: int = 0

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

    def __repr__(self) -> str:
        # Sizes and names: a notebook showing the matrix and every state's row would
        # print thousands of lines for a mission.
        return (f"DTMC(states={self.num_states:,}, transitions={self.num_transitions:,}, "
                f"initial={len(self.initial):,}, variables={self.variable_names}, "
                f"labels={tuple(self.labels)}, "
                f"rewards={tuple(r.name for r in self.rewards)}, deadlocks={self.deadlocks})")

    def compact(self) -> DTMC:
        """This DTMC with its state table in the narrowest integer type holding every
        value (int8, int16 or int32; itself if it needs int64).

        The table is one int64 per state and variable (65 MB at 1.4M states and six
        variables); a checker that only reads it through :meth:`column` and its own
        int64 copies of the columns an expression reads can keep it narrow. (The
        builder, exact exploration and structure re-use do arithmetic on whole rows:
        give them the int64 table.)
        """
        if self.states.size == 0:
            return self
        low, high = int(self.states.min()), int(self.states.max())
        for kind in (np.int8, np.int16, np.int32):
            limits = np.iinfo(kind)
            if limits.min <= low and high <= limits.max:
                return replace(self, states=self.states.astype(kind))
        return self

    def column(self, name: str) -> IntArray:
        """The values of variable *name* in every state.

        :raises ArgumentError: for a name that is no variable (also a ValueError, which
            ``tuple.index`` raised with only "x not in tuple").
        """
        if name not in self.variable_names:
            raise ArgumentError(f"no variable {name!r}: the variables are {self.variable_names}")
        return self.states[:, self.variable_names.index(name)]

    def reward(self, key: str | int | None) -> RewardVectors:
        """The reward structure named *key*, at index *key*, or the first (None)."""
        return by_key(self.rewards, key)
