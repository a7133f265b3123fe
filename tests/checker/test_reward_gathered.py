"""Lower reward bounds, Storm's ``F{"r"}>=B phi``: reach *phi* once at least B of reward
is gathered. On DTMCs against a path recursion in exact rationals (float and
``--exact``), on MDPs against values solved by hand, both against Storm; the product
they share; and the forms outside the language."""

from __future__ import annotations

from fractions import Fraction
from functools import cache
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
from click.testing import CliRunner

from tests.checker.test_conditional import CHAIN
from tests.checker.test_reward_bounded import REWARD, ROWS
from tests.explore.test_mdp_build import CHOICE
from veribattery.checker.kernels import reward_layers
from veribattery.cli import cli
from veribattery.lang import parse_property
from veribattery.pipeline import check_prism_file

#: CHAIN's probability of ever reaching "succ" (s=3): x0 = 0.3 + 0.4 x0, x1 = 0.6 + 0.4 x0;
#: s=2 and s=4 never do.
REACH = {0: Fraction(1, 2), 1: Fraction(4, 5), 2: Fraction(0), 3: Fraction(1), 4: Fraction(0)}

#: s0: [a] pays 1 (its state reward) and goes to s1 or s2 by halves; [b] pays 2 (state
#: and action) and goes to s1; s1 returns to s0 or ends in the goal s3, by halves; s2
#: ends in the goal for free.
GATHER_MDP = """mdp
module m
  s : [0..3] init 0;
  [a] s=0 -> 0.5:(s'=1) + 0.5:(s'=2);
  [b] s=0 -> (s'=1);
  [] s=1 -> 0.5:(s'=0) + 0.5:(s'=3);
  [] s=2 -> (s'=3);
  [] s=3 -> (s'=3);
endmodule
rewards "r"
  s=0 : 1;
  [b] true : 1;
endrewards
label "goal" = s=3;
label "one" = s=1;
"""


@cache
def _gathered(state: int, need: int) -> Fraction:
    """P(reach "succ" with at least *need* of reward "t" gathered), by recursion over path
    prefixes: once nothing more is needed it is plain reachability (REACH); before,
    every state that can still reach "succ" pays a positive reward, so it ends."""
    if need <= 0:
        return REACH[state]
    if state in (3, 4):  # absorbing, paying nothing
        return Fraction(0)
    return sum((p * _gathered(t, need - REWARD[state]) for t, p in ROWS[state].items()),
               Fraction(0))


def _value(prop: str, model: str = CHAIN, *, exact: bool = False) -> float:
    return float(check_prism_file(model, props_source=prop, exact=exact).results[0].value)


@pytest.mark.parametrize("need", [0, 1, 2, 3, 5, 8, 13])
def test_dtmc_against_path_recursion(need: int) -> None:
    expected = float(_gathered(0, need))
    assert _value(f'P=? [ F{{"t"}}>={need} "succ" ]') == pytest.approx(expected, abs=1e-12)
    if need:
        assert _value(f'P=? [ F{{"t"}}>{need - 1} "succ" ]') == pytest.approx(expected,
                                                                          abs=1e-12)
    assert _value(f'P=? [ F^{{rew{{"t"}}>={need}}} "succ" ]') == pytest.approx(expected,
                                                                           abs=1e-12)
    assert _value(f'P=? [ F{{"t"}}>={need} "succ" ]', exact=True) == pytest.approx(
        expected, rel=1e-15)


def test_a_target_met_early_is_passed_through() -> None:
    # s=0 holds at the start with nothing gathered; the path must come back to it with
    # at least 2: [a] pays 2 and returns with 0.2 + 0.5 * 0.4 (via s=1), else never.
    assert _value('P=? [ F{"t"}>=2 s=0 ]') == pytest.approx(0.4, abs=1e-12)
    assert _value('P=? [ F{"t"}>=0 s=0 ]') == 1.0


def test_a_fractional_bound_is_rounded_up() -> None:
    assert _value('P=? [ F{"t"}>=4.5 "succ" ]') == _value('P=? [ F{"t"}>=5 "succ" ]')
    assert _value('P=? [ F{"t"}>4.5 "succ" ]') == _value('P=? [ F{"t"}>=5 "succ" ]')


@pytest.mark.parametrize(("prop", "expected"), [
    ('Pmax=? [ F{"r"}>=2 "goal" ]', 1.0),  # [b], then the goal surely
    ('Pmin=? [ F{"r"}>=2 "goal" ]', 0.25),  # [a]: s1, back to s0, [a] again
    ('Pmax=? [ F{"r"}>=4 "goal" ]', 0.5),  # [b], back, [b]
    ('Pmax=? [ F{"r"}>3 "one" ]', 0.5),  # s1 passed with 2, reached again with 4
    ('Pmin=? [ F{"r"}>=0 "goal" ]', 1.0),
])
def test_mdp_solved_by_hand(prop: str, expected: float) -> None:
    assert _value(prop, GATHER_MDP) == pytest.approx(expected, abs=1e-12)


# ---------------------------------------------------------------------------
# The product
# ---------------------------------------------------------------------------


def test_layers_gather_down_to_zero_and_spend_into_spent() -> None:
    # two states, costs 2 and 0: row 0 goes to both, row 1 stays
    matrix = sp.csr_matrix(np.array([[0.5, 0.5], [0.0, 1.0]]))
    costs = np.array([2, 0])
    gather = reward_layers.layered_rows(matrix, costs, 2, gather=True).toarray()
    # state k*2 + s; from layer 2 row 0 needs max(0, 2-2) = 0 more
    assert gather.shape == (6, 6)
    assert gather[4].tolist() == [0.5, 0.5, 0, 0, 0, 0]
    assert gather[2].tolist() == [0.5, 0.5, 0, 0, 0, 0]  # layer 1 stops at 0
    assert gather[5].tolist() == [0, 0, 0, 0, 0, 1.0]  # cost 0: the same layer
    spend = reward_layers.layered_rows(matrix, costs, 2, gather=False).toarray()
    assert spend.shape == (7, 7)
    assert spend[4].tolist() == [0.5, 0.5, 0, 0, 0, 0, 0]  # budget 2 - 2 = 0
    assert spend[2].tolist() == [0, 0, 0, 0, 0, 0, 1.0]  # budget 1 - 2: spent
    assert spend[6].tolist() == [0, 0, 0, 0, 0, 0, 1.0]  # spent is absorbing
    groups = reward_layers.layered_groups(np.array([0, 2, 3]), 1, gather=False)
    assert groups.tolist() == [0, 2, 3, 5, 6, 7]


@pytest.mark.parametrize(("text", "prop", "size"), [
    (CHAIN, 'P=? [ F{"t"}>=9 "succ" ]', 90),  # 10 layers of 9 transitions
    (CHOICE, 'Pmax=? [ F{"r"}<=9 "goal" ]', 60),  # 10 layers of 6, upper bounds alike
], ids=["dtmc-gather", "mdp-spend"])
def test_a_product_too_large_is_one_line(text: str, prop: str, size: int, tmp_path: Path,
                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """Past both limits: too large a product, too many layers to solve one at a time."""
    monkeypatch.setattr(reward_layers, "PRODUCT_LIMIT", 30)
    monkeypatch.setattr(reward_layers, "EPOCH_LIMIT", 9)
    model = tmp_path / "m.prism"
    model.write_text(text)
    result = CliRunner().invoke(cli, ["prism", str(model), "--property", prop])
    assert result.exit_code == 2
    (line,) = result.output.strip().splitlines()
    assert (f"a reward bound of 9 makes a product of {size} transitions on this model (at "
            "most 30) and 10 layers to solve one at a time (at most 9): use a smaller "
            "bound") in line


# ---------------------------------------------------------------------------
# Outside the language
# ---------------------------------------------------------------------------


@pytest.mark.parametrize(("prop", "message"), [
    ('P=? [ s<2 U{"t"}>=3 "succ" ]', "a lower reward bound (>=B, >B) is supported on F only"),
    ('P=? [ s<2 U^{rew{"t"}>3} "succ" ]', "is supported on F only"),
    ('P=? [ F^{rew{"t"}[2,4]} "succ" ]', "a reward bound must be one of <=T, <T, >=B, >B"),
])
def test_forms_outside_the_language(prop: str, message: str) -> None:
    assert message in str(parse_property(prop).unsupported)


def test_until_from_true_is_f() -> None:
    assert (parse_property('P=? [ true U{"t"}>=3 "succ" ]').formula
            == parse_property('P=? [ F{"t"}>=3 "succ" ]').formula)


# ---------------------------------------------------------------------------
# Storm (exact)
# ---------------------------------------------------------------------------


def _storm(text: str, props: list[str], tmp_path: Path) -> list[float]:
    pytest.importorskip("stormpy")
    from tests.storm_oracle import storm_initial_values

    return storm_initial_values(text, props, tmp_path)


def test_dtmc_against_storm(tmp_path: Path) -> None:
    props = [f'P=? [ F{{"t"}}>={b} "{label}" ]' for b in (0, 3, 6, 11)
             for label in ("succ", "fail", "done")] + ['P=? [ F^{rew{"t"}>4} s=0 ]']
    ours = [_value(p) for p in props]
    assert ours == pytest.approx(_storm(CHAIN, props, tmp_path), abs=1e-12)


def test_mdp_against_storm(tmp_path: Path) -> None:
    props = [f'P{d}=? [ F{{"r"}}>={b} "{label}" ]' for d in ("min", "max")
             for b in (1, 3, 6) for label in ("goal", "one")]
    ours = [_value(p, GATHER_MDP) for p in props]
    assert ours == pytest.approx(_storm(GATHER_MDP, props, tmp_path), abs=1e-9)
