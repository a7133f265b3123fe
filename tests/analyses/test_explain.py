"""The breakdown of P(F target) and the most probable paths, against hand-solved chains.

Expected values are solved by hand with exact fractions, or by brute force:
every path up to a length beyond which no path can compete (its probability is
bounded by the largest transition probability to the power of its length).
"""

from __future__ import annotations

import dataclasses
import heapq
from fractions import Fraction

import numpy as np
import pytest

from tests.checker.chains import dtmc, mask
from veribattery.analyses.explain import explain_target, group_inflow, target_inflow
from veribattery.analyses.folding import fold_path
from veribattery.analyses.paths import most_probable_paths
from veribattery.checker import check
from veribattery.errors import CheckError
from veribattery.explore.dtmc import DTMC
from veribattery.lang import parse_property

# 0 -> 1 (1/2), good 2 (3/10), bad 3 (1/5); 1 -> 0 (2/5), bad 3 (1/10), good 2 (1/2).
LOOP = {0: {1: 0.5, 2: 0.3, 3: 0.2}, 1: {0: 0.4, 3: 0.1, 2: 0.5}}


def _loop() -> DTMC:
    return dtmc(LOOP, 4, labels={"bad": [3], "good": [2]})


def test_breakdown_of_a_loop_by_hand() -> None:
    # p0 = 1/5 + 1/2 p1, p1 = 1/10 + 2/5 p0  =>  p0 = 5/16.
    # visits: v0 = 1 / (1 - 1/2 * 2/5) = 5/4, v1 = 1/2 * v0 = 5/8.
    chain = _loop()
    inflow = target_inflow(chain, mask(4, [3]))
    assert inflow.probability == pytest.approx(float(Fraction(5, 16)), abs=1e-15)
    assert inflow.states.tolist() == [0, 1]
    assert inflow.visits == pytest.approx([1.25, 0.625], abs=1e-15)
    assert inflow.contributions == pytest.approx([0.25, 0.0625], abs=1e-15)


def test_grouping_sums_contributions_per_key() -> None:
    chain = _loop()
    inflow = target_inflow(chain, mask(4, [3]))
    columns = {"parity": np.array(["even", "odd"]), "s": np.array([0, 1])}
    grouping = group_inflow(inflow, columns, ["parity"])
    assert grouping.groups == ((("even",), pytest.approx(0.25)), (("odd",), pytest.approx(0.0625)))
    assert grouping.records()[1] == {"parity": "odd", "probability": pytest.approx(0.0625)}
    with pytest.raises(CheckError, match="cannot group by wind"):
        group_inflow(inflow, columns, ["wind"])


def test_most_probable_paths_of_a_loop_by_hand() -> None:
    # 0→3: 1/5; 0→1→3: 1/20; 0→1→0→3: 1/25; then 1/100 and 1/125 (one more loop each).
    chain = _loop()
    paths = most_probable_paths(chain.transitions, 0, mask(4, [3]), 5)
    assert [p.states.tolist() for p in paths] == [
        [0, 3], [0, 1, 3], [0, 1, 0, 3], [0, 1, 0, 1, 3], [0, 1, 0, 1, 0, 3],
    ]
    assert [p.probability for p in paths] == pytest.approx([0.2, 0.05, 0.04, 0.01, 0.008])


def test_a_path_below_the_float_range_keeps_its_probability() -> None:
    # 0 -> 1 -> ... -> 400, each step 1/10 (else back to 0): P(path) = 1e-400 < 5e-324.
    n = 400
    chain = dtmc({i: {i + 1: 0.1, 0: 0.9} for i in range(1, n)} | {0: {1: 0.1, 0: 0.9}},
                 n + 1)
    (path,) = most_probable_paths(chain.transitions, 0, mask(n + 1, [n]), 1)
    assert path.steps == n and path.probability == 0.0
    assert path.log10_probability == pytest.approx(-400, rel=1e-12)
    assert path.probability_text == "1e-400"
    rounded = dataclasses.replace(path, log10_probability=-400.00000000001)
    assert rounded.probability_text == "1e-400"  # not 10e-401


def test_paths_when_target_unreachable_or_initial() -> None:
    chain = _loop()
    assert most_probable_paths(chain.transitions, 2, mask(4, [3]), 3) == ()
    (only,) = most_probable_paths(chain.transitions, 3, mask(4, [3]), 3)
    assert only.states.tolist() == [3] and only.probability == 1.0
    with pytest.raises(CheckError, match="at least 1"):
        most_probable_paths(chain.transitions, 0, mask(4, [3]), 0)


def _random_chain(seed: int, n: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    dense = np.zeros((n, n))
    for s in range(n - 2):  # the last two states absorb: n-1 the target, n-2 a sink
        successors = rng.choice(n, size=rng.integers(1, 4), replace=False)
        weights = rng.integers(1, 10, size=successors.size)
        dense[s, successors] = weights / weights.sum()
    dense[n - 2, n - 2] = dense[n - 1, n - 1] = 1.0
    return dense


def _brute_force(dense: np.ndarray, target: int, k: int) -> list[float]:
    """Best-first search over all paths: exact top-k probabilities (paths end at the target)."""
    n = dense.shape[0]
    reach = np.zeros(n, dtype=bool)
    reach[target] = True
    for _ in range(n):  # states that can reach the target: only those are expanded
        reach |= (dense > 0) @ reach
    heap: list[tuple[float, tuple[int, ...]]] = [(-1.0, (0,))] if reach[0] else []
    found: list[float] = []
    while heap and len(found) < k:
        neg, path = heapq.heappop(heap)
        if path[-1] == target:
            found.append(-neg)
            continue
        for t in np.flatnonzero(dense[path[-1]]):
            if reach[t]:
                heapq.heappush(heap, (neg * dense[path[-1], t], (*path, int(t))))
    return found


@pytest.mark.parametrize("seed", range(12))
def test_top_paths_match_brute_force_on_random_cyclic_chains(seed: int) -> None:
    n = 8
    dense = _random_chain(seed, n)
    rows = {s: {int(t): float(dense[s, t]) for t in np.flatnonzero(dense[s])} for s in range(n)}
    chain = dtmc(rows, n)
    paths = most_probable_paths(chain.transitions, 0, mask(n, [n - 1]), 6)
    expected = _brute_force(dense, n - 1, 6)
    assert [p.probability for p in paths] == pytest.approx(expected, rel=1e-12)
    for p in paths:  # each path is real: a chain of transitions ending at its first target visit
        assert p.states[0] == 0 and p.states[-1] == n - 1 and (p.states[:-1] != n - 1).all()
        assert p.probability == pytest.approx(float(np.prod(dense[p.states[:-1], p.states[1:]])))
    assert len({tuple(p.states.tolist()) for p in paths}) == len(paths)


@pytest.mark.parametrize("seed", range(12))
def test_breakdown_sums_to_the_checkers_probability(seed: int) -> None:
    n = 9
    dense = _random_chain(100 + seed, n)
    rows = {s: {int(t): float(dense[s, t]) for t in np.flatnonzero(dense[s])} for s in range(n)}
    chain = dtmc(rows, n, labels={"goal": [n - 1]})
    explanation = explain_target(chain, mask(n, [n - 1]), name="goal", top=2)
    exact = check(chain, parse_property('P=? [ F "goal" ]')).value
    assert explanation.probability == pytest.approx(exact, abs=1e-12)
    for grouping in explanation.groupings:
        assert sum(p for _, p in grouping.groups) == pytest.approx(exact, abs=1e-12)
    # Visits against the dense fundamental matrix on the states that can reach the goal.
    inflow = explanation.inflow
    reaches = check(chain, parse_property('P>0 [ F "goal" ]')).values
    can = np.asarray(reaches, dtype=bool) & ~mask(n, [n - 1])
    if can[0]:
        idx = np.flatnonzero(can)
        fundamental = np.linalg.inv(np.eye(idx.size) - dense[np.ix_(idx, idx)])
        visits = fundamental[list(idx).index(0)]
        expected = {int(s): visits[i] for i, s in enumerate(idx)}
        for s, v in zip(inflow.states, inflow.visits, strict=True):
            assert v == pytest.approx(expected[int(s)], rel=1e-10)


def test_explain_rejects_top_zero() -> None:
    with pytest.raises(CheckError, match="--top must be at least 1"):
        explain_target(_loop(), mask(4, [3]), name="bad", top=0)


def test_fold_keeps_the_last_sortie() -> None:
    actions = ["takeoff", "fly", *["inspect", "land", "recharge", "takeoff"] * 10,
               "inspect", "back", "land", ""]
    head, fold, end = fold_path(actions, marker="recharge", tail=3)
    assert list(head) == [0, 1]
    assert fold is not None and fold.first == 2
    assert actions[end.start - 1] != "recharge" or end.start == fold.last + 1
    assert "recharge" not in actions[end.start + 1:]  # the end starts at the last recharge
    assert fold.describe("recharge").startswith("… 9 recharge trips")
    short = fold_path(["a", "b", "c"], tail=2)
    assert short[1] is None and list(short[0]) == [0, 1, 2]


def test_mission_breakdown_against_storm_exact() -> None:
    """P(failure) of a small mission (2,607 states) from the breakdown vs Storm in rationals."""
    pytest.importorskip("stormpy")
    from tests.storm_oracle import run_storm
    from veribattery.analyses.mission_view import DEFAULT_GROUPINGS, MissionView, build_mission
    from veribattery.config import load_config
    from veribattery.mission import mission_files

    small = ("farm.cols=3", "farm.rows=3", "farm.base=[0,0]", "strategy.safe_t=0.1",
             "battery.capacity_ah=6", "battery.max_recharges=15")
    cfg = load_config("", small)
    mission = build_mission(cfg)
    explanation = explain_target(mission.dtmc, mission.dtmc.labels["failure"], name="failure",
                                 describe=MissionView(mission).columns, by=DEFAULT_GROUPINGS)
    storm = run_storm(mission_files(cfg).model, 'P=? [ F "failure" ]')
    expected = storm.values[0][storm.initial[0]]
    assert isinstance(expected, float) and 0.05 < expected < 0.2
    assert explanation.probability == pytest.approx(expected, abs=1e-12)
    for grouping in explanation.groupings:
        assert sum(p for _, p in grouping.groups) == pytest.approx(expected, abs=1e-12)


def test_the_mission_views_columns_are_its_group_keys() -> None:
    """``explain --by`` checks its keys against GROUP_KEYS before the build: they must be
    the columns the view gives, under BS1 and under a strategy's actions."""
    from veribattery.analyses.mission_view import GROUP_KEYS, MissionView, build_mission
    from veribattery.analyses.strategy_view import StrategyView
    from veribattery.config import load_config

    mission = build_mission(load_config("", ("farm.cols=2", "farm.rows=2", "farm.base=[0,0]")))
    states = np.arange(mission.dtmc.num_states)
    chosen = np.full(mission.dtmc.num_states, "", dtype=np.str_)
    for view in (MissionView(mission), StrategyView(mission, chosen)):
        assert tuple(view.columns(states)) == GROUP_KEYS
