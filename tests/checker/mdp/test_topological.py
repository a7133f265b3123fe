"""Topological value iteration: the first approximation policy iteration starts from."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from tests.checker.mdp.counting import counted_evaluations
from tests.checker.mdp.models import HALF, mask, mdp_from
from veribattery.checker.mdp import MDP, certificate, reach_probability, reach_reward, topological
from veribattery.checker.mdp import solve as solve_module
from veribattery.checker.mdp.solve import evaluate, policy_iteration, progress_rows
from veribattery.checker.mdp.system import ChoiceSystem, Objective, equations, quotient_classes
from veribattery.checker.mdp.topological import (
    LevelOrder,
    class_levels,
    greedy_rows,
    is_proper,
    topological_values,
)

GOAL, SINK = 5, 6

#: A cycle {3, 4} below a chain 2 -> 1 -> 0, every state with a safe gamble:
#: Pmax: x4 = max(x3 / 2, 0.35), x3 = max(x4 / 2 + 1/2, 0.6) -> 0.35, 0.675 (both through
#: the cycle's other state or exit: x3 = 0.175 + 0.5); x2 = max(1/2, 0.6, x3) = 0.675;
#: x1 = max(x2, 0.7) = 0.7; x0 = max(0.9 x1, 0.62) = 0.63.
#: Pmin: x4 = min(x3 / 2, 0.35), x3 = min(x4 / 2 + 1/2, 0.6) -> 0.3, 0.6; x2 = 0.5,
#: x1 = min(x2, 0.7) = 0.5, x0 = min(0.9 x1, 0.62) = 0.45.
#: Each state's value needs its successors' first: the order matters.
LADDER = mdp_from([
    [[(1, 0.9), (SINK, 0.1)], [(GOAL, 0.62), (SINK, 0.38)]],
    [[(2, 1)], [(GOAL, 0.7), (SINK, 0.3)]],
    [[(GOAL, 0.5), (SINK, 0.5)], [(GOAL, 0.6), (SINK, 0.4)], [(3, 1)]],
    [[(4, 0.5), (GOAL, 0.5)], [(GOAL, 0.6), (SINK, 0.4)]],
    [[(3, 0.5), (SINK, 0.5)], [(GOAL, 0.35), (SINK, 0.65)]],
    [[(GOAL, 1)]],
    [[(SINK, 1)]],
], labels={"goal": [GOAL]})
LADDER_MAX = [0.63, 0.7, 0.675, 0.675, 0.35]
LADDER_MIN = [0.45, 0.5, 0.5, 0.6, 0.3]


def _system(mdp: MDP, unknown: list[int]) -> ChoiceSystem:
    class_of = quotient_classes(mask(mdp.num_states, unknown))
    return equations(mdp.transitions, mdp.choice_owner, class_of)


def test_levels_put_the_cycle_first_and_the_chain_above_it() -> None:
    system = _system(LADDER, [0, 1, 2, 3, 4])
    levels = class_levels(system)
    assert levels.count == 4
    per_level = [sorted(levels.classes[lo:hi].tolist())
                 for lo, hi in zip(levels.starts[:-1], levels.starts[1:], strict=True)]
    assert per_level == [[3, 4], [2], [1], [0]]  # classes are the states here
    # Level 0 is all cyclic; the others all trivial (their cyclic part starts at their end).
    assert levels.cyclic_from.tolist() == [0, 3, 4, 5]


def test_level_blocks_are_the_system_s_rows_in_level_order() -> None:
    """A level's block, gathered from the system (no copy of the matrix in level order),
    holds the same rows with the same entries in the same order as the system's rows
    indexed in level order: products over it sum the same terms alike."""
    system = _system(LADDER, [0, 1, 2, 3, 4])
    levels = class_levels(system)
    order = LevelOrder.of(system, None, levels)
    whole = system.off[order.rows]
    assert not np.array_equal(order.rows, np.arange(order.rows.size))  # rows permuted
    spans = [(0, order.rows.size), *(order.row_range(lo, hi) for lo, hi in
                                     zip(levels.starts[:-1], levels.starts[1:], strict=True))]
    for first, last in spans:
        block, expected = order.block(first, last), whole[first:last]
        assert block.shape == expected.shape
        assert np.array_equal(block.indptr, expected.indptr)
        assert np.array_equal(block.indices, expected.indices)
        assert np.array_equal(block.data, expected.data)
        assert np.array_equal(order.per_row(system.leave, first, last),
                              system.leave[order.rows[first:last]])


@pytest.mark.parametrize(("objective", "expected"), [("max", LADDER_MAX), ("min", LADDER_MIN)])
def test_topological_values_solve_the_ladder(objective: Objective,
                                             expected: list[float]) -> None:
    system = _system(LADDER, [0, 1, 2, 3, 4])
    known = np.array([1.0 if s == GOAL else 0.0 for s in system.known_states])
    start = progress_rows(system, system.known_states == GOAL)
    values = topological_values(system, objective, known, None, start, class_levels(system))
    assert values == pytest.approx(expected, rel=1e-14)


def test_ladder_end_to_end_with_one_evaluation(monkeypatch: pytest.MonkeyPatch) -> None:
    calls = counted_evaluations(monkeypatch)
    high = reach_probability(LADDER, LADDER.labels["goal"], objective="max")
    assert high.values[:5] == pytest.approx(LADDER_MAX, rel=1e-14)
    assert high.strategy.choices[:5].tolist() == [0, 3, 6, 7, 10]
    low = reach_probability(LADDER, LADDER.labels["goal"], objective="min")
    assert low.values[:5] == pytest.approx(LADDER_MIN, rel=1e-14)
    assert low.strategy.choices[:5].tolist() == [0, 2, 4, 8, 9]
    assert calls[0] == 2  # one per problem: the first strategy is already optimal


def _chain(n: int) -> tuple[MDP, list[Fraction]]:
    """State i advances to i + 1 (0.999; the last to the goal with 0.95) or gambles on
    the goal with 0.9; the exact Pmax by backward induction (advance everywhere:
    0.95 * 0.999^19 > 0.9 for n = 20)."""
    goal, sink = n, n + 1
    step, last, gamble = Fraction(999, 1000), Fraction(95, 100), Fraction(9, 10)
    states = [[[(i + 1, step), (sink, 1 - step)], [(goal, gamble), (sink, 1 - gamble)]]
              for i in range(n - 1)]
    states.append([[(goal, last), (sink, 1 - last)], [(goal, gamble), (sink, 1 - gamble)]])
    mdp = mdp_from([*states, [[(goal, 1)]], [[(sink, 1)]]], labels={"goal": [goal]})
    values = [max(last, gamble)]
    for _ in range(n - 1):
        values.insert(0, max(step * values[0], gamble))
    return mdp, values


def test_an_acyclic_mdp_needs_no_evaluation_where_progress_needed_many(
        monkeypatch: pytest.MonkeyPatch) -> None:
    n = 20
    mdp, exact = _chain(n)
    calls = counted_evaluations(monkeypatch)
    result = reach_probability(mdp, mdp.labels["goal"], objective="max")
    assert result.values[:n] == pytest.approx([float(v) for v in exact], rel=1e-13)
    assert result.strategy.choices[:n].tolist() == list(range(0, 2 * n, 2))  # advance
    assert calls[0] == 0  # acyclic: one certified pass over the levels (checker.mdp.acyclic)
    # Today's start, the progress strategy (every state gambles: the goal is one step
    # away), learns one state per round that advancing pays: from the end backwards.
    system = _system(mdp, list(range(n)))
    known = np.array([1.0 if s == n else 0.0 for s in system.known_states])
    calls[0] = 0
    found = policy_iteration(system, "max", known, None,
                             progress_rows(system, system.known_states == n))
    assert found is not None and calls[0] >= n
    assert found.values == pytest.approx([float(v) for v in exact], rel=1e-13)


def test_minimal_rewards_leave_a_positive_cycle() -> None:
    # 0 <-> 1 at cost 1 a step, or to the goal at cost 5: Rmin = 5 in both. A strategy
    # taking the cycle in both states never reaches the goal (it is improper).
    mdp = mdp_from([
        [[(1, 1)], [(2, 1)]],
        [[(0, 1)], [(2, 1)]],
        [[(2, 1)]],
    ], rewards=[[1, 5], [1, 5], [0]])
    rewards = np.array([1.0, 5.0, 1.0, 5.0, 0.0])
    result = reach_reward(mdp, rewards, mask(3, [2]), objective="min")
    assert result.values.tolist() == [5.0, 5.0, 0.0]
    assert result.strategy.choices[:2].tolist() == [1, 3]


def test_is_proper_tells_a_closed_cycle() -> None:
    mdp = mdp_from([
        [[(1, 1)], [(2, 1)]],
        [[(0, 1)], [(2, 1)]],
        [[(2, 1)]],
    ])
    system = _system(mdp, [0, 1])
    assert not is_proper(system, np.array([0, 2]))  # 0 -> 1 -> 0 forever
    assert is_proper(system, np.array([0, 3]))  # 1 leaves, and 0 reaches 1
    assert is_proper(system, np.array([1, 2]))


def test_greedy_rows_keep_the_preferred_row_on_ties() -> None:
    images = np.array([0.5, 0.5, 0.3, 0.2, 0.9])
    starts = np.array([0, 3])
    assert greedy_rows(images, starts, "max", np.array([1, 3])).tolist() == [1, 4]
    assert greedy_rows(images, starts, "max", np.array([2, 4])).tolist() == [0, 4]
    assert greedy_rows(images, starts, "min", np.array([0, 4])).tolist() == [2, 3]
    nearly = np.array([0.5, 0.5 * (1 - 2.0**-50), 0.25])
    assert greedy_rows(nearly, np.array([0]), "max", np.array([1])).tolist() == [1]


def test_an_improper_greedy_start_falls_back_to_progress(monkeypatch: pytest.MonkeyPatch) -> None:
    # From values 0, the cycle (cost 1) looks cheaper than the exit (cost 5) in both
    # states: that greedy strategy never reaches the goal, and is refused.
    mdp = mdp_from([
        [[(1, 1)], [(2, 1)]],
        [[(0, 1)], [(2, 1)]],
        [[(2, 1)]],
    ])
    rewards = np.array([1.0, 5.0, 1.0, 5.0, 0.0])
    monkeypatch.setattr(topological, "topological_values",
                        lambda system, *_, **__: np.zeros(system.size))
    system = _system(mdp, [0, 1])
    offset = rewards[system.choices]
    start = progress_rows(system, np.ones(system.known_states.size, dtype=bool))
    known = np.zeros(system.known_states.size)
    assert topological.topological_policy_iteration(system, "min", known, offset, start) is None
    result = reach_reward(mdp, rewards, mask(3, [2]), objective="min")
    assert result.values.tolist() == [5.0, 5.0, 0.0]


def test_too_many_levels_fall_back_to_progress(monkeypatch: pytest.MonkeyPatch) -> None:
    n = 20
    mdp, exact = _chain(n)
    monkeypatch.setattr(topological, "LEVEL_LIMIT", n - 1)
    calls = counted_evaluations(monkeypatch)
    result = reach_probability(mdp, mdp.labels["goal"], objective="max")
    assert result.values[:n] == pytest.approx([float(v) for v in exact], rel=1e-13)
    assert calls[0] >= n  # the progress start's rounds, one per state


def test_ties_go_to_the_row_with_the_smaller_margin() -> None:
    # State 0 gets 1/2 straight away (its second row) or through state 1 (its first):
    # tied, but the detour adds state 1's defect to state 0's margin.
    mdp = mdp_from([
        [[(1, 1)], [(2, HALF), (3, HALF)]],
        [[(2, HALF), (3, HALF)]],
        [[(2, 1)]],
        [[(3, 1)]],
    ])
    system = _system(mdp, [0, 1])
    known = np.array([1.0, 0.0])
    detour = solve_module.evaluate(system, np.array([0, 2]), known, None)
    assert detour is not None and detour.values.tolist() == [0.5, 0.5]
    found = solve_module.tightest_among_ties(system, "max", known, None, detour)
    assert found.rows.tolist() == [1, 2] and found.values.tolist() == [0.5, 0.5]
    assert found.untied is detour  # (kept: the certificate tries its margin too)
    assert solve_module.tightest_among_ties(system, "max", known, None, found) is found


def test_the_tied_problem_solved_level_by_level_is_its_optimum() -> None:
    """The certificate's margin problem (the most expected *reward* over the rows it
    keeps) restarted from the greedy strategy of its values solved level by level: the
    strategy policy iteration ends with, from a start that reaches the goal worst."""
    system = _system(LADDER, [0, 1, 2, 3, 4])
    known = np.zeros(system.known_states.size)
    reward = np.linspace(1.0, 2.0, system.choices.size)
    problem = certificate._TiedProblem(system, reward)
    start = progress_rows(system, system.known_states == GOAL)
    first = evaluate(system, start, known, reward)
    assert first is not None
    levelled = problem.levelled(first)
    optimum = policy_iteration(system, "max", known, reward, start)
    assert levelled is not None and optimum is not None
    assert not np.array_equal(first.rows, optimum.rows)  # (the restart has work to do)
    assert levelled.rows.tolist() == optimum.rows.tolist()
    assert levelled.values == pytest.approx(optimum.values, rel=1e-14)
    assert problem.levelled(levelled) is None  # (nothing left to switch)
