"""Strategies (schedulers): which choice is taken in each state, and the chain it induces."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from veribattery._types import BoolArray, CsrMatrix, FloatArray, IntArray
from veribattery.checker.mdp.components import EndComponents
from veribattery.checker.mdp.graph import ChoiceGraph, attractor
from veribattery.checker.mdp.model import MDP
from veribattery.checker.mdp.system import ChoiceSystem

__all__ = ["StepStrategy", "Strategy", "first_choice_where", "induced_chain", "induced_rewards"]


@dataclass(frozen=True, slots=True)
class Strategy:
    """A memoryless deterministic strategy.

    :param choices: per state, the index of the choice it takes (a row of the MDP).
    """

    choices: IntArray

    def __repr__(self) -> str:
        # One choice per state: a notebook would print the whole array.
        return f"Strategy(states={self.choices.size:,})"

    def local(self, mdp: MDP) -> IntArray:
        """Per state, the position of its choice among the state's own (0 = first)."""
        return self.choices - mdp.row_groups[:-1]


@dataclass(frozen=True, slots=True)
class StepStrategy:
    """A strategy for a step-bounded objective: the choice depends on the step.

    Stored compactly: *last* is the choice per state with one step to go; *changes*
    lists, for 2, 3, ... steps to go, the states whose choice differs from the one
    with a step less, and their new choices. After the bounded part (*steps*
    taken) the strategy *then* applies, or any choice if it is None.
    """

    steps: int
    last: IntArray
    changes: tuple[tuple[IntArray, IntArray], ...]
    then: Strategy | StepStrategy | None = None

    def __repr__(self) -> str:
        # Sizes, not the per-state arrays of every step.
        return (f"StepStrategy(steps={self.steps:,}, states={self.last.size:,}, "
                f"then={self.then!r})")

    def at(self, step: int) -> Strategy:
        """The memoryless strategy used at step *step* (0 = the first move)."""
        if step >= self.steps:
            if self.then is None:
                raise ValueError(f"the strategy is bounded to {self.steps} steps")
            if isinstance(self.then, StepStrategy):
                return self.then.at(step - self.steps)
            return self.then
        choices = self.last.copy()
        for states, picked in self.changes[: self.steps - 1 - step]:
            choices[states] = picked
        return Strategy(choices)


def first_choice_where(mdp: MDP, flags: BoolArray) -> IntArray:
    """Per state, its first choice with *flags* set, or -1 where none is."""
    marked = np.where(flags, np.arange(mdp.num_choices), mdp.num_choices)
    first = np.minimum.reduceat(marked, mdp.row_groups[:-1])
    return np.where(first < mdp.num_choices, first, -1).astype(np.int64)


def induced_chain(mdp: MDP, strategy: Strategy) -> CsrMatrix:
    """The DTMC the strategy induces: row *s* is the distribution of its choice."""
    return sp.csr_matrix(mdp.transitions[strategy.choices])


def induced_rewards(mdp: MDP, rewards: FloatArray, strategy: Strategy) -> FloatArray:
    """Per state, the reward per step (*rewards* per choice) under the strategy."""
    return np.asarray(rewards[strategy.choices], dtype=np.float64)


def lifted(mdp: MDP, graph: ChoiceGraph, system: ChoiceSystem, rows: IntArray,
           components: EndComponents | None, base: IntArray) -> IntArray:
    """A strategy on the states from one on the system's classes (*rows*, one per class).

    A state that is its own class takes its row's choice. In a collapsed end
    component, the state owning the chosen row takes it and every other state
    moves towards that state with the component's inside choices, so the component
    is left through the chosen row almost surely (de Alfaro 1997).

    :param base: the choices of the states outside the system (copied).
    """
    choices = base.copy()
    picked = system.choices[rows]
    exits = mdp.choice_owner[picked]
    choices[exits] = picked
    if components is None or components.count == 0:
        return choices
    in_class = system.class_of >= 0
    collapsed = in_class & (components.component >= 0)
    seeds = np.zeros(mdp.num_states, dtype=bool)
    seeds[exits] = True
    seeds &= collapsed
    _, via = attractor(graph, collapsed & ~seeds, seeds, components.inside)
    moving = collapsed & ~seeds
    choices[moving] = via[moving]
    return choices
