"""Reward bounds past the product limit, solved one layer at a time (Storm's epochs):
the same values as the product and as the exact ones, within their certified bounds,
on DTMCs (lower bounds) and MDPs (both); ``--exact`` still refuses such a product."""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
from click.testing import CliRunner

from tests.checker.test_conditional import CHAIN
from tests.checker.test_reward_gathered import GATHER_MDP, _gathered
from tests.explore.test_mdp_build import CHOICE
from tests.strategies.models import ROBOT
from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.kernels import reward_layers
from veribattery.checker.kernels.reward_epochs import RewardEpochs
from veribattery.cli import cli
from veribattery.pipeline import check_prism_file


@pytest.fixture
def one_layer_at_a_time(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(reward_layers, "PRODUCT_LIMIT", 0)


def _result(prop: str, model: str) -> tuple[float, float, float]:
    found = check_prism_file(model, props_source=prop).results[0]
    assert found.certified and found.precise
    return float(found.value), float(found.lower), float(found.upper)


def _encloses(prop: str, model: str, exact: Fraction | float) -> None:
    value, lower, upper = _result(prop, model)
    assert Fraction(lower) <= Fraction(exact) <= Fraction(upper)
    assert value == pytest.approx(float(exact), abs=1e-12)


@pytest.mark.usefixtures("one_layer_at_a_time")
@pytest.mark.parametrize("need", [0, 1, 2, 5, 13])
def test_dtmc_lower_bound_against_path_recursion(need: int) -> None:
    _encloses(f'P=? [ F{{"t"}}>={need} "succ" ]', CHAIN, _gathered(0, need))


@pytest.mark.usefixtures("one_layer_at_a_time")
@pytest.mark.parametrize("budget", [0, 1, 3, 7])
def test_mdp_upper_bound_solved_by_hand(budget: int) -> None:
    _encloses(f'Pmax=? [ F{{"r"}}<={budget} "goal" ]', CHOICE, 1 - Fraction(1, 2**budget))
    _encloses(f'Pmin=? [ F{{"r"}}<={budget} "goal" ]', CHOICE, 0)


@pytest.mark.usefixtures("one_layer_at_a_time")
@pytest.mark.parametrize(("prop", "expected"), [
    ('Pmax=? [ F{"r"}>=2 "goal" ]', Fraction(1)),
    ('Pmin=? [ F{"r"}>=2 "goal" ]', Fraction(1, 4)),
    ('Pmax=? [ F{"r"}>=4 "goal" ]', Fraction(1, 2)),
    ('Pmax=? [ F{"r"}>3 "one" ]', Fraction(1, 2)),
    ('Pmin=? [ F{"r"}>=0 "goal" ]', Fraction(1)),
])
def test_mdp_lower_bound_solved_by_hand(prop: str, expected: Fraction) -> None:
    _encloses(prop, GATHER_MDP, expected)


#: Five steps to the goal, each costing 1: within a budget of 4 or less it is out of
#: reach, exactly.
FAR_GOAL = """mdp
module m
  x : [0..5] init 0;
  [a] x<5 -> 0.5:(x'=x+1) + 0.5:(x'=x);
  [b] x<5 -> 0.25:(x'=x+1) + 0.75:(x'=x);
endmodule
rewards "r"
  [a] true : 1;
  [b] true : 1;
endrewards
label "goal" = x=5;
"""


@pytest.mark.usefixtures("one_layer_at_a_time")
@pytest.mark.parametrize("budget", [2, 4, 40])
def test_a_goal_out_of_reach_stays_exactly_zero(budget: int) -> None:
    # The layers' exits read values of 0 from the lower layers: exact products, not
    # [0, 2k ETA] growing with each layer (firewire's `deadline` at delay=36 was
    # 7.2e-322 +- 8.2e-322 after 201 layers, and P>0 on it undecided).
    for bound in ("Pmin", "Pmax"):
        found = _result(f'{bound}=? [ F{{"r"}}<={budget} "goal" ]', FAR_GOAL)
        if budget < 5:
            assert found == (0.0, 0.0, 0.0)
        else:
            assert 0.0 < found[1] <= found[2] < 1.0
    decided = check_prism_file(FAR_GOAL, props_source=f'Pmax>0 [ F{{"r"}}<={budget} "goal" ]')
    assert decided.results[0].value is (budget >= 5)


ROBOT_PROPS = ([f'P{d}=? [ F{{"{r}"}}<={k} "goal" ]' for d in ("min", "max")
                for k in (1, 3, 6) for r in ("steps", "time")]
               + ['Pmax=? [ !"broken" U{"steps"}<=4 "goal" ]']
               + [f'P{d}=? [ F{{"time"}}>={k} "goal" ]' for d in ("min", "max") for k in (2, 5)])


def test_the_product_and_the_layers_meet_on_a_robot(monkeypatch: pytest.MonkeyPatch) -> None:
    """ROBOT's reward bounds, with the product and one layer at a time, also against
    ``--exact`` (the product in rationals)."""
    exact = check_prism_file(ROBOT, props_source=";".join(ROBOT_PROPS), exact=True).results
    monkeypatch.setattr(reward_layers, "EPOCH_LIMIT", 0)  # (no layers: the product)
    product = [_result(p, ROBOT) for p in ROBOT_PROPS]
    monkeypatch.undo()
    monkeypatch.setattr(reward_layers, "PRODUCT_LIMIT", 0)
    layers = [_result(p, ROBOT) for p in ROBOT_PROPS]
    for (value, lower, upper), (_, low, high), known in zip(product, layers, exact,
                                                             strict=True):
        assert low <= Fraction(known.exact) <= high  # type: ignore[attr-defined]
        assert lower <= high and low <= upper
        assert value == pytest.approx(float(known.exact), abs=1e-12)  # type: ignore[attr-defined]


def test_a_chain_layer_by_layer() -> None:
    """A chain 0 -> 1 -> 2 (goal) paying 1 then 2: ``F{r}<=T goal`` holds from 0 iff
    T >= 3, from 1 iff T >= 2; each layer is the chain plus *yes* and *no*."""
    matrix = sp.csr_matrix(np.array([[0, 1.0, 0], [0, 0, 1.0], [0, 0, 1.0]]))
    epochs = RewardEpochs(matrix, np.array([1, 2, 0]), np.ones(3, dtype=bool),
                          np.array([False, False, True]), gather=False)
    seen: list[int] = []

    def solve(rows: sp.csr_matrix, remain: np.ndarray, target: np.ndarray) -> Bounds:
        seen.append(rows.shape[0])
        return _dtmc_until(rows.toarray(), remain, target)

    for top, holds in ((1, [0, 0, 1]), (2, [0, 1, 1]), (3, [1, 1, 1]), (40, [1, 1, 1])):
        found = epochs.bounds(top, solve)
        assert found.lower.tolist() == found.upper.tolist() == holds
    assert set(seen) == {5}  # three states, then yes and no


def _dtmc_until(P: np.ndarray, remain: np.ndarray, target: np.ndarray) -> Bounds:
    """``remain U target`` where every path is absorbed within a few steps (rounds of
    the Bellman equation from 0, exact here: every probability is 0 or 1)."""
    x = np.zeros(P.shape[0])
    for _ in range(P.shape[0] + 1):
        x = np.where(target, 1.0, np.where(remain, P @ x, 0.0))
    return Bounds.exact(x)


def test_exact_mode_still_refuses_a_product_past_the_limit(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(reward_layers, "PRODUCT_LIMIT", 30)
    model = tmp_path / "m.prism"
    model.write_text(CHOICE)
    prop = 'Pmax=? [ F{"r"}<=9 "goal" ]'
    result = CliRunner().invoke(cli, ["prism", str(model), "--property", prop, "--exact"])
    assert result.exit_code == 2
    (line,) = result.output.strip().splitlines()
    assert "a reward bound of 9 makes a product of 60 transitions" in line
    floats = CliRunner().invoke(cli, ["prism", str(model), "--property", prop, "--json"])
    assert floats.exit_code == 0, floats.output
