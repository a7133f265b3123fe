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
from veribattery.checker.bounds import Bounds
from veribattery.checker.mdp import graph as qualitative
from veribattery.checker.mdp.components import EndComponents, end_components
from veribattery.checker.mdp.graph import ChoiceGraph, all_successors_in, attractor
from veribattery.checker.mdp.model import MDP
from veribattery.checker.mdp.optimum import optimise, spread
from veribattery.checker.mdp.result import MdpResult
from veribattery.checker.mdp.strategy import Strategy, first_choice_where, lifted
from veribattery.checker.mdp.system import Objective, quotient_classes

__all__ = ["reach_reward", "total_reward"]


def reach_reward(mdp: MDP, rewards: FloatArray, target: BoolArray, *,
                 objective: Objective) -> MdpResult:
    """Minimal or maximal expected reward accumulated until *target* (``R [ F target ]``).

    :param mdp: the model.
    :param rewards: per choice, the reward of one step taken with it (nonnegative).
    :param target: the states to reach (their own reward is not counted).
    :param objective: ``"min"`` (Rmin) or ``"max"`` (Rmax).
    :return: values (``inf`` where the target is not reached almost surely under the
        optimising strategy), their enclosures and a memoryless optimal strategy.
    """
    _check_rewards(mdp, rewards)
    graph = ChoiceGraph.of(mdp.transitions, mdp.choice_owner)
    everywhere = np.ones(mdp.num_states, dtype=bool)
    if objective == "max":
        zero = qualitative.prob0e(graph, everywhere, target)
        finite = qualitative.prob1a(graph, everywhere, target, zero)
        choices = _escaping(mdp, graph, ~finite, zero)
        allowed = None
    else:
        finite = qualitative.prob1e(graph, everywhere, target)
        choices = mdp.row_groups[:-1].copy()
        allowed = all_successors_in(graph, finite)
    values = Bounds.exact(np.where(finite, 0.0, math.inf))
    maybe = finite & ~target
    if not maybe.any():
        return MdpResult(values, Strategy(choices))
    components = None
    if objective == "min":
        free = allowed & (rewards == 0) & all_successors_in(graph, maybe)
        components = end_components(graph, maybe, free)
    return _optimised(mdp, graph, maybe, components, np.zeros(mdp.num_states), rewards, allowed,
                      target, objective, values, choices)


def total_reward(mdp: MDP, rewards: FloatArray, *, objective: Objective) -> MdpResult:
    """Minimal or maximal expected total reward (``R [ C ]``), every step counted forever.

    Rmax is infinite where some strategy reaches, with positive probability, an end
    component in which a choice of positive reward can be taken forever; Rmin is
    infinite where no strategy stays almost surely in zero-reward end components
    from some step on.

    :param rewards: per choice, the reward of one step taken with it (nonnegative).
    """
    _check_rewards(mdp, rewards)
    graph = ChoiceGraph.of(mdp.transitions, mdp.choice_owner)
    if objective == "max":
        return _total_max(mdp, graph, rewards)
    return _total_min(mdp, graph, rewards)


def _total_max(mdp: MDP, graph: ChoiceGraph, rewards: FloatArray) -> MdpResult:
    everywhere = np.ones(mdp.num_states, dtype=bool)
    components = end_components(graph, everywhere)
    paying = components.inside & (rewards > 0)
    rich = _states_of_components(components, graph.owner[paying])
    infinite = qualitative.can_reach(graph, everywhere, rich)
    choices = _collecting(mdp, graph, components, paying, rich, infinite)
    finite = ~infinite
    inner = end_components(graph, finite, all_successors_in(graph, finite))
    closed = _closed_components(graph, inner)
    choices[closed] = first_choice_where(mdp, inner.inside)[closed]
    values = Bounds.exact(np.where(finite, 0.0, math.inf))
    maybe = finite & ~closed
    if not maybe.any():
        return MdpResult(values, Strategy(choices))
    return _optimised(mdp, graph, maybe, inner, np.zeros(mdp.num_states), rewards, None, closed,
                      "max", values, choices)


def _total_min(mdp: MDP, graph: ChoiceGraph, rewards: FloatArray) -> MdpResult:
    everywhere = np.ones(mdp.num_states, dtype=bool)
    free = end_components(graph, everywhere, rewards == 0)
    resting = free.states
    finite = qualitative.prob1e(graph, everywhere, resting)
    choices = mdp.row_groups[:-1].copy()
    choices[resting] = first_choice_where(mdp, free.inside)[resting]
    values = Bounds.exact(np.where(finite, 0.0, math.inf))
    maybe = finite & ~resting
    if not maybe.any():
        return MdpResult(values, Strategy(choices))
    return _optimised(mdp, graph, maybe, None, np.zeros(mdp.num_states), rewards,
                      all_successors_in(graph, finite), resting, "min", values, choices)


def _optimised(mdp: MDP, graph: ChoiceGraph, maybe: BoolArray,
               components: EndComponents | None, known: FloatArray, rewards: FloatArray,
               allowed: BoolArray | None, goal: BoolArray, objective: Objective,
               values: Bounds, choices: IntArray) -> MdpResult:
    """The maybe states solved (end components of *components* collapsed) and merged."""
    class_of = quotient_classes(maybe, None if components is None else components.component)
    found = optimise(mdp, class_of, known, objective, rewards=rewards, allowed=allowed,
                     goal=goal, ceiling=math.inf)
    strategy = lifted(mdp, graph, found.system, found.rows, components, choices)
    return MdpResult(spread(values, class_of, found.bounds), Strategy(strategy))


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
    first = np.unique(components.component[graph.owner[paid]], return_index=True)[1]
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
