"""The two-objective front by weighted sums: hand-solved vertices and answers between
them, and agreement with the linear programme and with Storm on random MDPs."""

from __future__ import annotations

import itertools
import random
from fractions import Fraction
from pathlib import Path

import pytest

from tests.checker.mdp.models import mask, mdp_from
from veribattery.checker.mdp import (
    Constraint,
    FrontSearch,
    Reach,
    Total,
    least_total_at,
    multi_optimum,
    pareto_front,
)

# 0 chooses: a (free) to the dead end 3; b (reward 1) to the goal 1 or to 3, 1/2 each;
# c (reward 2) to 2, then (reward 2) to the goal surely; d (reward 3) as b: dominated.
# The points (P, E[R]): a (0, 0), b (1/2, 1), c (1, 4), d (1/2, 3). The front has three
# vertices a, b, c (slopes 2 then 6: convex), and d lies above it.
FORK = mdp_from([[[(3, 1)], [(1, 0.5), (3, 0.5)], [(2, 1)], [(1, 0.5), (3, 0.5)]],
                 [[(1, 1)]], [[(1, 1)]], [[(3, 1)]]],
                rewards=[[0, 1, 2, 3], [0], [2], [0]])
GOAL = Reach(mask(4, [1]))
COST = Total(FORK.rewards[0].per_choice(FORK))
VERTICES = [(Fraction(0), Fraction(0)), (Fraction(1, 2), Fraction(1)), (Fraction(1), Fraction(4))]


def _holds(interval: object, exact: Fraction) -> bool:
    lower, upper = interval.lower, interval.upper  # type: ignore[attr-defined]
    return bool(Fraction(lower) <= exact <= Fraction(upper))


def test_the_front_has_the_three_vertices_solved_by_hand() -> None:
    front = pareto_front(FORK, GOAL, COST)
    assert len(front.vertices) == 3 and front.complete
    for vertex, (p, total) in zip(front.vertices, VERTICES, strict=True):
        assert _holds(vertex.p, p) and _holds(vertex.total, total)
    assert _holds(front.pmax, Fraction(1))
    # each vertex's strategy takes its own choice in state 0 (a, b, c: rows 0, 1, 2)
    assert [int(v.strategy.choices[0]) for v in front.vertices] == [0, 1, 2]


@pytest.mark.parametrize(("p", "expected", "mixing"), [
    (Fraction(0), Fraction(0), Fraction(0)),  # a meets it: lam = 0 certifies it
    (Fraction(1, 4), Fraction(1, 2), Fraction(1, 2)),  # half a, half b
    # b, whose P is certified only to within 1e-15 of 1/2: mixed with c by as much
    (Fraction(1, 2), Fraction(1), None),
    (Fraction(3, 4), Fraction(5, 2), Fraction(1, 2)),  # half b, half c
    (Fraction(9, 10), Fraction(17, 5), Fraction(4, 5)),  # 1 + (4/5) 3
    (Fraction(1), Fraction(4), Fraction(1)),  # c
])
def test_the_answer_between_vertices_is_their_interpolation(
        p: Fraction, expected: Fraction, mixing: Fraction | None) -> None:
    answer = least_total_at(FORK, GOAL, COST, float(p))
    assert answer is not None and answer.achievable and answer.total is not None
    assert _holds(answer.total, expected)
    assert answer.total.upper - answer.total.lower < 1e-12
    if mixing is not None:
        assert float(answer.mixing) == pytest.approx(float(mixing), abs=1e-12)


def test_above_pmax_no_strategy_meets_it() -> None:
    answer = least_total_at(FORK, GOAL, COST, 1.0 + 1e-9)
    assert answer is not None and not answer.achievable and answer.total is None


def test_the_extra_reward_is_the_mixed_strategys() -> None:
    # count the steps: a 1, b 1, c 2 (to the goal); at p = 3/4 half b, half c: 3/2
    steps = Total(FORK.rewards[0].per_choice(FORK) * 0 + 1)
    search = FrontSearch(FORK, GOAL, COST, [steps])
    answer = search.least_total_at(0.75)
    assert answer is not None and answer.extras
    # the steps are counted until the run stops in an absorbing state (its own loop is
    # not a zero-reward end component for the steps, but the runs are stopped there)
    assert _holds(answer.extras[0], Fraction(3, 2))


@pytest.mark.parametrize("rewards", [[0, 0], [0, 1]], ids=["tied", "dominated"])
def test_a_point_a_safer_one_matches_is_no_vertex(rewards: list[int]) -> None:
    # 0 goes to the dead end 2 (free) or to the goal 1 (free, or at reward 1 -- then the
    # dead end is a vertex); tied at 0, the safe choice alone is the front
    mdp = mdp_from([[[(2, 1)], [(1, 1)]], [[(1, 1)]], [[(2, 1)]]],
                   rewards=[rewards, [0], [0]])
    total = Total(mdp.rewards[0].per_choice(mdp))
    front = pareto_front(mdp, Reach(mask(3, [1])), total)
    points = [(v.p.value, v.total.value) for v in front.vertices]
    assert points == ([(1.0, 0.0)] if rewards == [0, 0] else [(0.0, 0.0), (1.0, 1.0)])


def test_resting_without_the_target_is_an_option() -> None:
    # 0 may idle forever (free) or pay 5 to reach the goal: R = 5 p, from (0, 0) to (1, 5)
    mdp = mdp_from([[[(0, 1)], [(1, 1)]], [[(1, 1)]]], rewards=[[0, 5], [0]])
    total = Total(mdp.rewards[0].per_choice(mdp))
    answer = least_total_at(mdp, Reach(mask(2, [1])), total, 0.3)
    assert answer is not None and answer.total is not None
    assert _holds(answer.total, Fraction(3, 2))


def test_no_strategy_with_a_finite_total() -> None:
    # 0 must loop forever, paying 1 each step
    mdp = mdp_from([[[(0, 1)]], [[(1, 1)]]], rewards=[[1], [0]])
    total = Total(mdp.rewards[0].per_choice(mdp))
    answer = least_total_at(mdp, Reach(mask(2, [1])), total, 0.0)
    assert answer is not None and not answer.achievable
    assert not multi_optimum(mdp, total, "min", [Constraint(Reach(mask(2, [1])), ">=", 0.0)]
                             ).achievable
    assert pareto_front(mdp, Reach(mask(2, [1])), total).vertices == ()


#: Per state, its choices; per choice, its reward and its (successor, probability) pairs.
Table = list[list[tuple[int, list[tuple[int, Fraction]]]]]


def _random_table(seed: int) -> Table:
    """A random MDP of 5 to 8 states whose fronts have several vertices: the last two
    states absorb (the goal, then a dead end); the others have one to three choices of
    reward 0 to 3 (often 0), each to one to three successors with dyadic probabilities."""
    rng = random.Random(seed)
    n = rng.randint(5, 8)
    table: Table = []
    for _ in range(n - 2):
        choices = []
        for _ in range(rng.randint(1, 3)):
            successors = rng.sample(range(n), rng.randint(1, 3))
            weights = rng.choice([[1], [1, 1], [1, 3], [1, 1, 2]])[: len(successors)]
            weights += [1] * (len(successors) - len(weights))
            total = sum(weights)
            pairs = [(t, Fraction(w, total)) for t, w in zip(successors, weights, strict=True)]
            choices.append((rng.choice([0, 0, 1, 2, 3]), pairs))
        table.append(choices)
    return [*table, [(0, [(n - 2, Fraction(1))])], [(0, [(n - 1, Fraction(1))])]]


def _as_mdp(table: Table) -> tuple[object, Reach, Total]:
    mdp = mdp_from([[pairs for _, pairs in choices] for choices in table],
                   rewards=[[float(r) for r, _ in choices] for choices in table])
    return mdp, Reach(mask(len(table), [len(table) - 2])), Total(
        mdp.rewards[0].per_choice(mdp))


def _as_prism(table: Table) -> str:
    """The same MDP in PRISM's language (one action name per choice, for its reward)."""
    n = len(table)
    lines = ["mdp", "module m", f"  s : [0..{n - 1}] init 0;"]
    rewards = ['rewards "r"']
    for i, choices in enumerate(table):
        for k, (reward, pairs) in enumerate(choices):
            update = " + ".join(f"{p.numerator}/{p.denominator}:(s'={t})" for t, p in pairs)
            lines.append(f"  [c{i}_{k}] s={i} -> {update};")
            rewards.append(f"  [c{i}_{k}] s={i} : {reward};")
    return "\n".join([*lines, "endmodule", *rewards, "endrewards",
                      f'label "goal" = s={n - 2};', ""])


@pytest.mark.parametrize("seed", range(40), ids=lambda s: f"seed{s}")
def test_random_mdps_agree_with_the_linear_programme(seed: int) -> None:
    """At p across the front: the LP's optimum lies in the certified interval (to the
    LP's tolerance), and an infeasible p is infeasible for both."""
    mdp, reach, total = _as_mdp(_random_table(seed))
    search = FrontSearch(mdp, reach, total)  # type: ignore[arg-type]
    top = search.safest()[0].value
    for p in (0.0, 0.3 * top, 0.6 * top, 0.9 * top, top, min(1.0, top + 1e-3)):
        answer = search.least_total_at(p)
        lp = multi_optimum(mdp, total, "min", [Constraint(reach, ">=", p)])  # type: ignore[arg-type]
        if answer is None:  # within Pmax's interval, above what B certainly meets
            continue
        assert answer.achievable == (lp.achievable and lp.value is not None), p
        if answer.total is None:
            continue
        assert lp.value is not None
        slack = 1e-6 * max(1.0, abs(lp.value))
        assert answer.total.lower - slack <= lp.value <= answer.total.upper + slack, p
        assert answer.total.value == pytest.approx(lp.value, rel=1e-6, abs=1e-6)
        assert answer.total.upper - answer.total.lower <= 1e-9 * max(1.0, answer.total.value)


@pytest.mark.parametrize("seed", range(12), ids=lambda s: f"seed{s}")
def test_random_mdps_agree_with_storm(seed: int, tmp_path: Path) -> None:
    stormpy = pytest.importorskip("stormpy")
    table = _random_table(seed)
    mdp, reach, total = _as_mdp(table)
    path = tmp_path / "model.prism"
    path.write_text(_as_prism(table), encoding="utf-8")
    program = stormpy.parse_prism_program(str(path))
    options = stormpy.BuilderOptions()
    options.set_build_all_reward_models(True)
    options.set_build_all_labels(True)
    built = stormpy.build_model(program, options=options)
    assert built.nr_states <= len(table)  # (the reachable ones)
    search = FrontSearch(mdp, reach, total)  # type: ignore[arg-type]
    top = search.safest()[0].value
    env = stormpy.Environment()
    env.modelchecker().multi().precision = stormpy.Rational("1/100000000")
    for p in (0.5 * top, 0.9 * top):
        answer = search.least_total_at(p)
        assert answer is not None and answer.total is not None
        formula = f'multi(R{{"r"}}min=? [ C ], P>={p!r} [ F "goal" ])'
        prop = stormpy.parse_properties(formula, program)[0]
        result = stormpy.model_checking(built, prop, environment=env)
        theirs = float(result.get_value(built.initial_states[0]))
        assert answer.total.value == pytest.approx(theirs, rel=1e-6, abs=1e-6), p


@pytest.mark.parametrize(("seed", "count"), [(3, 4), (27, 5), (33, 4), (48, 4)])
def test_each_vertex_is_the_linear_programmes_optimum_at_its_p(seed: int, count: int) -> None:
    mdp, reach, total = _as_mdp(_random_table(seed))
    front = pareto_front(mdp, reach, total)  # type: ignore[arg-type]
    assert len(front.vertices) == count
    for vertex in front.vertices:
        lp = multi_optimum(mdp, total, "min",  # type: ignore[arg-type]
                           [Constraint(reach, ">=", vertex.p.lower)])
        assert lp.value == pytest.approx(vertex.total.value, rel=1e-6, abs=1e-9)


def _on_line(points: list[tuple[float, float]], p: float) -> float:
    """The polyline through *points* (by increasing P) at *p*."""
    for (p0, r0), (p1, r1) in itertools.pairwise(points):
        if p0 <= p <= p1:
            return r0 + (r1 - r0) * (p - p0) / (p1 - p0)
    raise AssertionError(p)


@pytest.mark.parametrize(("tolerance", "count"), [(0.05, 5), (0.2, 4), (10.0, 3)])
def test_a_front_with_a_tolerance_lies_that_close_above_the_exact_one(tolerance: float,
                                                                     count: int) -> None:
    mdp, reach, total = _as_mdp(_random_table(27))
    exact = pareto_front(mdp, reach, total)  # type: ignore[arg-type]
    rough = FrontSearch(mdp, reach, total).front(tolerance)  # type: ignore[arg-type]
    assert len(rough.vertices) == count and len(exact.vertices) == 5
    line = [(v.p.value, v.total.value) for v in rough.vertices]
    for vertex in exact.vertices:
        above = _on_line(line, vertex.p.value) - vertex.total.value
        assert -1e-9 <= above <= tolerance * max(1.0, vertex.total.value)


# 0 chooses: a (reward 3) to 1, which reaches the goal 6 surely; b (reward 1) to 2, 3, 4
# with 1/7, 4/7, 2/7, each of which reaches 6 surely; c (free) to the dead end 5. In
# doubles 1/7 + 4/7 + 2/7 sums to 0.9999999999999999 < 1 = Pmax, yet b attains Pmax:
# the fastest safest strategy is b, (1, 1), not a, (1, 3).
SEVENTHS = mdp_from([[[(1, 1)], [(2, 1 / 7), (3, 4 / 7), (4, 2 / 7)], [(5, 1)]],
                     [[(6, 1)]], [[(6, 1)]], [[(6, 1)]], [[(6, 1)]], [[(5, 1)]], [[(6, 1)]]],
                    rewards=[[3, 1, 0], [0], [0], [0], [0], [0], [0]])


def test_a_choice_whose_float_sum_rounds_below_pmax_still_attains_it() -> None:
    goal, cost = Reach(mask(7, [6])), Total(SEVENTHS.rewards[0].per_choice(SEVENTHS))
    front = pareto_front(SEVENTHS, goal, cost)
    assert [(v.p.value, v.total.value) for v in front.vertices] == [(0.0, 0.0), (1.0, 1.0)]
    answer = least_total_at(SEVENTHS, goal, cost, 0.5)
    assert answer is not None and answer.total is not None
    assert answer.total.lower <= 0.5 <= answer.total.upper
    assert answer.total.upper - answer.total.lower < 1e-12  # was [0.5, 1.5]
