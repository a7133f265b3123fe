"""Reward-bounded reachability ``F{"r"}<=T``: closed forms, a top-down path recursion in
exact rationals, errors, and Storm (exact) on a hand chain and a small emitted mission."""

from __future__ import annotations

from fractions import Fraction
from functools import cache
from pathlib import Path

import numpy as np
import pytest

from tests.checker.chains import dtmc, mask
from tests.checker.test_conditional import CHAIN, REPO, SMALL_MISSION
from veribattery.checker import Workspace, check
from veribattery.checker.kernels.reward_bounded import reward_bounded_until_probs
from veribattery.errors import CheckError
from veribattery.lang import parse_model, parse_properties, parse_property
from veribattery.pipeline import check_model, check_prism_file

# CHAIN as exact rows: the reward of the step leaving each state ("t": 2, 3, 1, 0, 0).
ROWS = {0: {1: Fraction(1, 2), 2: Fraction(3, 10), 0: Fraction(1, 5)},
        1: {3: Fraction(3, 5), 0: Fraction(2, 5)}, 2: {4: Fraction(1, 2), 2: Fraction(1, 2)},
        3: {3: Fraction(1)}, 4: {4: Fraction(1)}}
REWARD = {0: 2, 1: 3, 2: 1, 3: 0, 4: 0}


@cache
def _paths(state: int, budget: int, target: int) -> Fraction:
    """P(reach *target* with total reward <= budget), by recursion over path prefixes.

    Terminates because every non-target state of CHAIN that can reach a target has a
    positive reward (the absorbing non-targets are cut off as unreachable).
    """
    if state == target:
        return Fraction(1)
    if state in (3, 4) or budget - REWARD[state] < 0:
        return Fraction(0)
    return sum((p * _paths(t, budget - REWARD[state], target) for t, p in ROWS[state].items()),
               Fraction(0))


def _value(prop: str, model: str = CHAIN) -> float:
    return float(check_prism_file(model, props_source=prop).results[0].value)


@pytest.mark.parametrize("bound", [0, 4, 5, 6, 7, 9, 12, 20, 33])
def test_hand_chain_against_path_recursion(bound: int) -> None:
    for label, target in (("succ", 3), ("fail", 4)):
        expected = float(_paths(0, bound, target))
        assert _value(f'P=? [ F{{"t"}}<={bound} "{label}" ]') == pytest.approx(expected,
                                                                              abs=1e-14)


def test_the_step_into_the_target_counts() -> None:
    # 0 -> 1 -> 3 costs 2 + 3 = 5: excluded at 4, included at 5 (as in Storm).
    assert _value('P=? [ F{"t"}<=4 "succ" ]') == 0.0
    assert _value('P=? [ F{"t"}<=5 "succ" ]') == pytest.approx(0.3, abs=1e-15)
    assert _value('P=? [ F{"t"}<6 "succ" ]') == pytest.approx(0.3, abs=1e-15)
    assert _value('P=? [ F{"t"}<5 "succ" ]') == 0.0
    assert _value('P=? [ F{"t"}<=5.7 "succ" ]') == pytest.approx(0.3, abs=1e-15)
    # Until: leaving through s=0 only, so 0 -> 1 -> 3 is excluded (1 is not s=0).
    assert _value('P=? [ s=0 U{"t"}<=50 s=1 ]') == pytest.approx(0.5 / 0.8, abs=1e-12)


def test_zero_reward_loops_close_on_their_level() -> None:
    # s0 loops with reward 0 (w.p. 1/2) or goes to s1; s1 costs 1 and wins w.p. 1/3 or
    # returns to s0. So a_k = 1/3 + 2/3 a_{k-1}, a_0 = 0: P = 1 - (2/3)^k.
    chain = dtmc({0: {0: 0.5, 1: 0.5}, 1: {2: 1 / 3, 0: 2 / 3}}, 3, labels={"goal": [2]},
                 rewards={"r": ([0.0, 1.0, 0.0], [0.0, 0.0, 0.0])})
    for k in (0, 1, 2, 7, 30):
        value = check(chain, parse_property(f'P=? [ F{{"r"}}<={k} "goal" ]')).value
        assert float(value) == pytest.approx(1 - (2 / 3) ** k, abs=1e-13)


def test_kernel_values_in_every_state() -> None:
    P = dtmc({0: {1: 1.0}, 1: {2: 0.5, 0: 0.5}}, 3).transitions
    workspace = Workspace()
    values = reward_bounded_until_probs(P, mask(3, [0, 1, 2]), mask(3, [2]),
                                        np.array([1, 1, 0]), 3, workspace=workspace)
    # From 1: win now (cost 1) w.p. 1/2, or 1 -> 0 -> 1 -> 2 (cost 3) w.p. 1/4.
    assert values.tolist() == pytest.approx([0.5, 0.75, 1.0], abs=1e-15)
    assert reward_bounded_until_probs(P, mask(3, [0, 1, 2]), mask(3, [2]), np.array([1, 1, 0]),
                                      -1, workspace=workspace).tolist() == [0, 0, 0]


def test_non_integer_rewards_are_an_error() -> None:
    model = CHAIN.replace("[b] true : 3;", "[b] true : 2.5;")
    with pytest.raises(CheckError, match=r'reward structure "t" gives 2.5 in state \(s=1\)'):
        _value('P=? [ F{"t"}<=5 "succ" ]', model)


def test_unknown_reward_structure_is_an_error() -> None:
    from veribattery.errors import PrismSemanticError

    with pytest.raises(PrismSemanticError, match='unknown reward structure "nope"'):
        _value('P=? [ F{"nope"}<=5 "succ" ]')


# ---------------------------------------------------------------------------
# Storm (exact)
# ---------------------------------------------------------------------------


def _storm(text: str, props: list[str], tmp_path: Path) -> list[float]:
    pytest.importorskip("stormpy")
    from tests.storm_oracle import storm_initial_values

    return storm_initial_values(text, props, tmp_path)


def _ours(text: str, props: list[str]) -> list[float]:
    parsed = parse_properties(";".join(props), name="props")
    run = check_model(parse_model(text, name="model"), parsed.properties)
    return [float(r.value) for r in run.results]


def test_hand_chain_against_storm(tmp_path: Path) -> None:
    props = [f'P=? [ F{{"t"}}<={t} "{label}" ]' for t in (0, 5, 6, 11, 40)
             for label in ("succ", "fail")] + ['P=? [ s<2 U{"t"}<=9 "succ" ]']
    assert _ours(CHAIN, props) == pytest.approx(_storm(CHAIN, props, tmp_path), abs=1e-12)


def test_small_mission_against_storm(tmp_path: Path) -> None:
    from veribattery.config import load_config
    from veribattery.render import render_model

    text = render_model(load_config(REPO / "configs/paper/case3.yaml", SMALL_MISSION))
    props = [f'P=? [ F{{"mt"}}<={t} "success" ]' for t in (100, 240, 246, 250, 400)]
    props += ['P=? [ F{"mt"}<=235 "failure" ]', 'P=? [ F{"rc"}<=1 "success" ]']
    storm = _storm(text, props, tmp_path)
    assert storm[2] > 0  # some success within the bounds checked
    assert _ours(text, props) == pytest.approx(storm, rel=1e-8, abs=1e-12)


# ---------------------------------------------------------------------------
# Storm's bound lists: F^{rew{"r"}<=T}, F^{steps<=k} (the QVBS property files' spelling)
# ---------------------------------------------------------------------------


@pytest.mark.parametrize(("storm", "ours"), [
    ('P=? [ F^{rew{"t"}<=5} "succ" ]', 'P=? [ F{"t"}<=5 "succ" ]'),
    ('P=? [ F^{{"t"}<6} "fail" ]', 'P=? [ F{"t"}<6 "fail" ]'),
    ('P=? [ s=0 U^{rew{"t"}<=50} s=1 ]', 'P=? [ s=0 U{"t"}<=50 s=1 ]'),
    ('P=? [ F^{steps<=3} "succ" ]', 'P=? [ F<=3 "succ" ]'),
    ('P=? [ F^{time<=3} "succ" ]', 'P=? [ F<=3 "succ" ]'),
    ('P=? [ F^{<=3} "succ" ]', 'P=? [ F<=3 "succ" ]'),
    ('P=? [ F^{steps[2,4]} "succ" ]', 'P=? [ F[2,4] "succ" ]'),
    ('P=? [ s<2 U^{steps<=4} "succ" ]', 'P=? [ s<2 U<=4 "succ" ]'),
])
def test_storm_bound_lists_read_as_the_bounds_they_spell(storm: str, ours: str) -> None:
    assert parse_property(storm).formula == parse_property(ours).formula
    assert _value(storm) == _value(ours)


@pytest.mark.parametrize(("prop", "message"), [
    ('P=? [ F^{rew{"t"}<=5, steps<=3} "succ" ]', "several bounds in one ^{...}"),
    ('P=? [ F^{rew{"t"}[2,4]} "succ" ]', "a reward bound must be one of <=T, <T, >=B, >B"),
])
def test_storm_bound_lists_outside_the_language(prop: str, message: str) -> None:
    assert message in str(parse_property(prop).unsupported)


def test_storm_bound_list_with_an_unknown_reference_is_a_syntax_error() -> None:
    from veribattery.errors import PrismSyntaxError

    with pytest.raises(PrismSyntaxError, match=r"1:10: unknown bound reference 'cost' "
                                               r'\(expected rew\{"name"\}, steps or time\)'):
        parse_property('P=? [ F^{cost<=5} "succ" ]')


def test_storm_bound_lists_against_storm(tmp_path: Path) -> None:
    props = ['P=? [ F^{rew{"t"}<=6} "succ" ]', 'P=? [ s<2 U^{rew{"t"}<=9} "succ" ]',
             'P=? [ F^{steps<=4} "fail" ]']
    assert _ours(CHAIN, props) == pytest.approx(_storm(CHAIN, props, tmp_path), abs=1e-12)
