"""Rmin and Rmax of reachability rewards (``F target``) and total rewards (``C``).

PRISM's semantics: the reward of each step is the state's reward plus the
chosen action's (the caller passes them per choice, :meth:`MdpRewards.per_choice`);
``R [ F target ]`` counts the steps before *target* is first reached and is
infinite under a strategy that reaches it with probability below 1, so Rmin is
infinite where even Pmax < 1 and Rmax where Pmin < 1. ``R [ C ]`` counts every
step forever. Rewards must be nonnegative.

End components are what makes these hard (Baier et al. 2017; Kretinsky &
Meggendorfer 2017): a strategy can stay forever in one where the rewards are 0,
which value iteration from 0 takes for a cheap way to the target. Each operator
first decides which states are infinite by graph search, then collapses the
zero-reward end components that remain, so that the equations of the rest have
one fixed point (``docs/mdp-numerics.md``).
"""

from __future__ import annotations

import math

import numpy as np

from veribattery._types import BoolArray, FloatArray, IntArray
from veribattery._unique import distinct_first
from veribattery.checker.certify.fixpoint import Progress
from veribattery.checker.mdp import graph as qualitative
from veribattery.checker.mdp.components import EndComponents, end_components
from veribattery.checker.mdp.graph import ChoiceGraph, all_successors_in, attractor
from veribattery.checker.mdp.model import MDP
from veribattery.checker.mdp.optimum import Problem, solve
from veribattery.checker.mdp.result import MdpResult
from veribattery.checker.mdp.strategy import first_choice_where
from veribattery.checker.mdp.system import Objective

__all__ = ["reach_reward", "reach_reward_problem", "total_reward", "total_reward_problem"]


def reach_reward(mdp: MDP, rewards: FloatArray, target: BoolArray, *,
                 objective: Objective, progress: Progress | None = None) -> MdpResult:
    """Minimal or maximal expected reward accumulated until *target* (``R [ F target ]``).

    :param mdp: the model.
    :param rewards: per choice, the reward of one step taken with it (nonnegative).
    :param target: the states to reach (their own reward is not counted).
    :param objective: ``"min"`` (Rmin) or ``"max"`` (Rmax).
    :return: values (``inf`` where the target is not reached almost surely under the
        optimising strategy), their enclosures and a memoryless optimal strategy.
    """
    graph = ChoiceGraph.of(mdp.transitions, mdp.choice_owner)
    problem = reach_reward_problem(mdp, graph, rewards, target, objective)
    return solve(mdp, graph, problem, rewards, progress=progress)


def total_reward(mdp: MDP, rewards: FloatArray, *, objective: Objective,
                 progress: Progress | None = None) -> MdpResult:
    """Minimal or maximal expected total reward (``R [ C ]``), every step counted forever.

    Rmax is infinite where some strategy reaches, with positive probability, an end
    component in which a choice of positive reward can be taken forever; Rmin is
    infinite where no strategy stays almost surely in zero-reward end components
    from some step on.

    :param rewards: per choice, the reward of one step taken with it (nonnegative).
    """
    graph = ChoiceGraph.of(mdp.transitions, mdp.choice_owner)
    return solve(mdp, graph, total_reward_problem(mdp, graph, rewards, objective), rewards,
                 progress=progress)


def reach_reward_problem(mdp: MDP, graph: ChoiceGraph, rewards: FloatArray,
                         target: BoolArray, objective: Objective) -> Problem:
    """The pre-pass of Rmin or Rmax ``[ F target ]``."""
    _check_rewards(mdp, rewards)
    if objective == "max":
        return _reach_max(mdp, graph, rewards, target)
    return _reach_min(mdp, graph, rewards, target)


def total_reward_problem(mdp: MDP, graph: ChoiceGraph, rewards: FloatArray,
                         objective: Objective) -> Problem:
    """The pre-pass of Rmin or Rmax ``[ C ]``."""
    _check_rewards(mdp, rewards)
    if objective == "max":
        return _total_max(mdp, graph, rewards)
    return _total_min(mdp, graph, rewards)


def _reach_max(mdp: MDP, graph: ChoiceGraph, rewards: FloatArray,
               target: BoolArray) -> Problem:
    """Finite where Pmin(F target) = 1; there no end component is left outside *target*."""
    everywhere = np.ones(mdp.num_states, dtype=bool)
    zero = qualitative.prob0e(graph, everywhere, target)
    finite = qualitative.prob1a(graph, everywhere, target, zero)
    choices = _escaping(mdp, graph, ~finite, zero)
    maybe = finite & ~target
    maybe &= _can_earn(mdp, graph, maybe, rewards)
    return _problem("max", maybe, finite, choices, finite & ~maybe)


def _reach_min(mdp: MDP, graph: ChoiceGraph, rewards: FloatArray,
               target: BoolArray) -> Problem:
    """Finite where Pmax(F target) = 1; 0 where the target is reached almost surely
    through choices of reward 0; zero-reward end components of the rest collapsed."""
    everywhere = np.ones(mdp.num_states, dtype=bool)
    finite = qualitative.prob1e(graph, everywhere, target)
    allowed = all_successors_in(graph, finite)
    free, via = qualitative.almost_surely(graph, everywhere, target, allowed & (rewards == 0))
    choices = mdp.row_groups[:-1].copy()
    choices[free & ~target] = via[free & ~target]
    maybe = finite & ~free
    idle = allowed & (rewards == 0) & all_successors_in(graph, maybe)
    components = end_components(graph, maybe, idle)
    return _problem("min", maybe, finite, choices, free, components, allowed)


def _total_max(mdp: MDP, graph: ChoiceGraph, rewards: FloatArray) -> Problem:
    """Infinite where an end component with a paying inside choice is reachable; the
    zero-reward end components of the rest collapsed, those no choice leaves known 0."""
    everywhere = np.ones(mdp.num_states, dtype=bool)
    components = end_components(graph, everywhere)
    paying = components.inside & (rewards > 0)
    rich = _states_of_components(components, graph.owner[paying])
    infinite = qualitative.can_reach(graph, everywhere, rich)
    choices = _collecting(mdp, graph, components, paying, rich, infinite)
    finite = ~infinite
    inner = end_components(graph, finite, all_successors_in(graph, finite))
    maybe = finite & ~_closed_components(graph, inner)
    maybe &= _can_earn(mdp, graph, maybe, rewards)
    return _problem("max", maybe, finite, choices, finite & ~maybe, inner)


def _total_min(mdp: MDP, graph: ChoiceGraph, rewards: FloatArray) -> Problem:
    """Finite where the zero-reward end components are reached almost surely; 0 where
    they are reached through choices of reward 0 (then stayed in forever)."""
    everywhere = np.ones(mdp.num_states, dtype=bool)
    resting = end_components(graph, everywhere, rewards == 0)
    finite = qualitative.prob1e(graph, everywhere, resting.states)
    free, via = qualitative.almost_surely(graph, everywhere, resting.states, rewards == 0)
    choices = mdp.row_groups[:-1].copy()
    choices[free] = via[free]
    choices[resting.states] = first_choice_where(mdp, resting.inside)[resting.states]
    maybe = finite & ~free
    return _problem("min", maybe, finite, choices, free, None, all_successors_in(graph, finite))


def _problem(objective: Objective, maybe: BoolArray, finite: BoolArray, choices: IntArray,
             goal: BoolArray, components: EndComponents | None = None,
             allowed: BoolArray | None = None) -> Problem:
    """A reward problem: 0 on the known finite states, infinite on the others."""
    known = np.where(finite, 0.0, math.inf)
    return Problem(objective, maybe, known, choices, goal, components, allowed, math.inf)


def _can_earn(mdp: MDP, graph: ChoiceGraph, states: BoolArray, rewards: FloatArray) -> BoolArray:
    """The *states* from which, inside *states*, a choice of positive reward is reachable
    (elsewhere every strategy earns exactly 0 there)."""
    earning = np.bincount(graph.owner[rewards > 0], minlength=mdp.num_states) > 0
    return qualitative.can_reach(graph, states, earning & states)


def _check_rewards(mdp: MDP, rewards: FloatArray) -> None:
    if rewards.shape != (mdp.num_choices,):
        raise ValueError("rewards need one entry per choice")
    if not (np.all(np.isfinite(rewards)) and np.all(rewards >= 0)):
        raise ValueError("MDP rewards must be finite and nonnegative")


def _escaping(mdp: MDP, graph: ChoiceGraph, infinite: BoolArray, zero: BoolArray) -> IntArray:
    """Choices that keep the target's probability below 1 from the *infinite* states:
    towards the states of probability 0 (*zero*), then never leaving them."""
    choices = mdp.row_groups[:-1].copy()
    avoiding = first_choice_where(mdp, all_successors_in(graph, zero))
    choices[zero] = avoiding[zero]
    moving = infinite & ~zero
    _, via = attractor(graph, moving, zero)
    choices[moving] = via[moving]
    return choices


def _states_of_components(components: EndComponents, owners: IntArray) -> BoolArray:
    """The states of the end components that contain any of the states *owners*."""
    marked = np.zeros(components.count, dtype=bool)
    marked[components.component[owners]] = True
    return _members(components, marked)


def _members(components: EndComponents, marked: BoolArray) -> BoolArray:
    """The states of the components whose entry of *marked* is set."""
    if components.count == 0:
        return np.zeros(components.component.size, dtype=bool)
    return (components.component >= 0) & marked[np.maximum(components.component, 0)]


def _collecting(mdp: MDP, graph: ChoiceGraph, components: EndComponents, paying: BoolArray,
                rich: BoolArray, infinite: BoolArray) -> IntArray:
    """Choices that collect infinite reward from the *infinite* states: into an end
    component with a paying inside choice, then that choice again and again."""
    choices = mdp.row_groups[:-1].copy()
    paid = np.flatnonzero(paying)
    first = distinct_first(components.component[graph.owner[paid]])[1]
    payers = paid[first]
    hubs = np.zeros(mdp.num_states, dtype=bool)
    hubs[graph.owner[payers]] = True
    choices[graph.owner[payers]] = payers
    _, inside = attractor(graph, rich & ~hubs, hubs, components.inside)
    choices[rich & ~hubs] = inside[rich & ~hubs]
    moving = infinite & ~rich
    _, via = attractor(graph, moving, rich)
    choices[moving] = via[moving]
    return choices


def _closed_components(graph: ChoiceGraph, components: EndComponents) -> BoolArray:
    """The states of the end components that no choice leaves (their total reward is 0)."""
    component = components.component
    sizes = np.diff(graph.successor_ptr)
    own = np.repeat(component[graph.owner], sizes)
    leaves = np.logical_or.reduceat(component[graph.successors] != own, graph.successor_ptr[:-1])
    leaving = leaves & (component[graph.owner] >= 0)
    open_ = np.zeros(components.count, dtype=bool)
    open_[component[graph.owner[leaving]]] = True
    return _members(components, ~open_)
