"""Values beyond the double range: certified as ``inf`` in ``[largest double, inf]``.

An expected reward of 2e308 (a reward of 1e308 per step, two steps expected) has no
double. Its float result is ``inf``, enclosed soundly from the largest double up,
and reported imprecise (it is no infinity); under ``--exact`` the rational is exact
and only its float shadow overflows. A probability of 1e-320 (subnormal) makes an
expected number of steps of 1e320. Hand-solved: from x=0, each step reaches x=1
with probability 1/2 (or *a*), so the expected number of steps is 2 (or 1/a).
"""

from __future__ import annotations

import math
import sys
from fractions import Fraction

import numpy as np
import pytest
from gmpy2 import mpq

from veribattery._numbers import nearest_float
from veribattery.checker.certify.bounds import Bounds, rational_bounds
from veribattery.checker.exact import ExactCheckResult
from veribattery.checker.result import CheckResult
from veribattery.pipeline import check_prism_file

MAX = sys.float_info.max

BIG_REWARD = """dtmc
module m
  x : [0..1] init 0;
  [] x=0 -> 0.5:(x'=1) + 0.5:(x'=0);
  [] x=1 -> (x'=1);
endmodule
rewards
  true : 1e308;
endrewards
"""

TINY_PROBABILITY = """dtmc
const double a = 1e-320;
module m
  x : [0..1] init 0;
  [] x=0 -> a:(x'=1) + 1-a:(x'=0);
  [] x=1 -> (x'=1);
endmodule
rewards
  true : 1;
endrewards
"""

#: Three components: the first two move with probability 1e-320 (one step of 1 - 1e-320
#: is 1 in doubles), which the stationary solves find singular.
STIFF_STEADY_STATE = """dtmc
const double a = 1e-320;
module S
  x : [0..1] init 0;
  [] true -> 0.5 : (x'=0) + 0.5 : (x'=1);
endmodule
module C1
  y : [0..1] init 0;
  [] (y=0) & (x=0) -> a:(y'=1) + 1-a : (y'=0);
  [] (y=1) & (x=1) -> 0.41:(y'=0) + 0.59 : (y'=1);
endmodule
module C2
  z : [0..1] init 0;
  [] (z=0) & (y=0) -> a:(z'=1) + 1-a : (z'=0);
  [] (z=1) & (y=1) -> 0.41:(z'=0) + 0.59 : (z'=1);
endmodule
"""


def _one(model: str, prop: str, exact: bool = False) -> CheckResult:
    run = check_prism_file(model, selectors=(prop,), exact=exact)
    (result,) = run.results
    return result


def _beyond(result: CheckResult) -> None:
    """*result* is a finite value above the largest double: inf in [MAX, inf], imprecise."""
    assert (result.value, result.lower, result.upper) == (math.inf, MAX, math.inf)
    assert not result.precise


@pytest.mark.parametrize(
    ("value", "expected"),
    [
        (Fraction(2) * 10**308, (math.inf, MAX, math.inf)),
        (-Fraction(2) * 10**308, (-math.inf, -math.inf, -MAX)),
        (mpq(2) * mpq(10) ** 308, (math.inf, MAX, math.inf)),
        (Fraction(MAX), (MAX, MAX, MAX)),  # a double is its own enclosure
        (Fraction(1, 2), (0.5, 0.5, 0.5)),
    ],
)
def test_rational_bounds(value: Fraction, expected: tuple[float, float, float]) -> None:
    found = rational_bounds([value])
    assert (float(found.value[0]), float(found.lower[0]), float(found.upper[0])) == expected


@pytest.mark.parametrize("value", [Fraction(1, 3), Fraction(2, 3), Fraction(1, 10**320),
                                   Fraction(10**300, 3), mpq(1, 3)])
def test_rational_bounds_of_no_double_are_neighbours(value: Fraction) -> None:
    found = rational_bounds([value])
    lower, upper = float(found.lower[0]), float(found.upper[0])
    assert Fraction(lower) < value < Fraction(upper)
    assert math.nextafter(lower, math.inf) == upper
    assert float(found.value[0]) in (lower, upper)


def test_nearest_float_overflows_to_signed_infinity() -> None:
    assert nearest_float(mpq(10) ** 400) == math.inf
    assert nearest_float(-Fraction(10) ** 400) == -math.inf
    assert nearest_float(Fraction(1, 10**400)) == 0.0


def test_an_infinity_from_a_finite_bound_is_not_precise() -> None:
    inf = np.array([math.inf])
    assert not Bounds(inf, np.array([MAX]), inf).precise_states()[0]
    assert Bounds.exact(inf).precise_states()[0]  # an infinite reward is exactly that


@pytest.mark.parametrize(("model", "prop"), [(BIG_REWARD, "R=? [ F x=1 ]"),
                                             (TINY_PROBABILITY, "R=? [ F x=1 ]")])
def test_float_reward_beyond_doubles(model: str, prop: str) -> None:
    _beyond(_one(model, prop))


def test_float_cumulative_reward_beyond_doubles_is_bounded_soundly() -> None:
    result = _one(BIG_REWARD, "R=? [ C<=3 ]")  # exactly 3e308
    # the sums only rise: the first step's 1e308 bounds the rest below
    assert (result.value, result.upper) == (math.inf, math.inf)
    assert result.lower == pytest.approx(1e308, rel=1e-12) and result.lower <= 1e308
    assert not result.precise


def test_tiny_probability_is_reached_surely() -> None:
    result = _one(TINY_PROBABILITY, "P=? [ F x=1 ]")
    assert (result.value, result.lower, result.upper) == (1.0, 1.0, 1.0)


def test_steady_state_of_stiff_components_is_sound() -> None:
    """No warning (pytest turns them into errors), and a point value inside its interval."""
    result = _one(STIFF_STEADY_STATE, "S=? [ x=0 ]")
    assert result.lower is not None and result.upper is not None
    assert 0.0 <= result.lower <= result.value <= result.upper
    assert 0.0 < result.value < 1.0


@pytest.mark.parametrize(
    ("model", "prop", "exact"),
    [
        (BIG_REWARD, "R=? [ F x=1 ]", Fraction(2 * 10**308)),
        (BIG_REWARD, "R=? [ C<=3 ]", Fraction(3 * 10**308)),
        (TINY_PROBABILITY, "R=? [ F x=1 ]", Fraction(10**320)),
        (BIG_REWARD.replace("dtmc", "mdp"), "Rmax=? [ F x=1 ]", Fraction(2 * 10**308)),
        (BIG_REWARD.replace("dtmc", "mdp"), "Rmin=? [ C<=3 ]", Fraction(3 * 10**308)),
        # a closed sub-expression beyond the doubles: its double is inf, its text exact
        # (float(mpq) raised OverflowError before)
        (BIG_REWARD, "P=? [ F x=1 ] * 1e308^2", Fraction(10**616)),
        (BIG_REWARD.replace("dtmc", "mdp"), "Pmax=? [ X x=1 ] * 1e308^2",
         Fraction(10**616, 2)),
    ],
)
def test_exact_value_beyond_doubles(model: str, prop: str, exact: Fraction) -> None:
    result = _one(model, prop, exact=True)
    assert isinstance(result, ExactCheckResult)
    assert result.exact == exact
    _beyond(result)


@pytest.mark.parametrize("model", [BIG_REWARD, BIG_REWARD.replace("dtmc", "mdp")])
def test_a_state_compared_with_a_closed_value_beyond_the_doubles(model: str) -> None:
    assert _one(model, "x < 1e308^2", exact=True).value is True
    assert _one(model, "A [ F x=1e308^2 ]", exact=True).value is False


def test_an_exact_value_below_the_doubles() -> None:
    result = _one(BIG_REWARD, "P=? [ X x=1 ] * (-1e308^2)", exact=True)
    assert isinstance(result, ExactCheckResult) and result.exact == -Fraction(10**616, 2)
    assert (result.value, result.lower, result.upper) == (-math.inf, -math.inf, -MAX)


def test_exact_probability_below_the_doubles_smallest() -> None:
    result = _one(TINY_PROBABILITY, "P=? [ X x=1 ]", exact=True)
    assert isinstance(result, ExactCheckResult)
    assert result.exact == Fraction(1, 10**320)
    assert result.lower is not None and result.upper is not None
    assert Fraction(result.lower) <= result.exact <= Fraction(result.upper)


@pytest.mark.parametrize("prop", ["Rmax=? [ F x=1 ]", "Rmin=? [ F x=1 ]"])
def test_mdp_float_reward_beyond_doubles(prop: str) -> None:
    _beyond(_one(BIG_REWARD.replace("dtmc", "mdp"), prop))


@pytest.mark.parametrize("prop", ["Rmax=? [ C<=3 ]", "Rmin=? [ C<=3 ]"])
def test_mdp_float_cumulative_reward_has_no_nan_bound(prop: str) -> None:
    result = _one(BIG_REWARD.replace("dtmc", "mdp"), prop)
    assert (result.value, result.lower, result.upper) == (math.inf, 0.0, math.inf)


ONE_STEP_REWARD = BIG_REWARD.replace("0.5:(x'=1) + 0.5:(x'=0)", "(x'=1)").replace(
    "true : 1e308", "x=0 : 1e308")


@pytest.mark.parametrize("prop", ["R=? [ F x=1 ] + R=? [ F x=1 ]", "R=? [ F x=1 ] * 10",
                                  "R=? [ F x=1 ] - (-1e308)", "R=? [ F x=1 ] / 1e-10"])
def test_expressions_overflowing_the_doubles(prop: str) -> None:
    """1e308 (exactly, one step) doubled or multiplied is finite: no [inf, inf] claim."""
    _beyond(_one(ONE_STEP_REWARD, prop))


def test_negated_sum_beyond_the_doubles() -> None:
    result = _one(ONE_STEP_REWARD, "-R=? [ F x=1 ] - R=? [ F x=1 ]")
    assert (result.value, result.lower, result.upper) == (-math.inf, -math.inf, -MAX)
