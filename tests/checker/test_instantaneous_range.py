"""``I=k``'s certified interval stays near the rewards' range, however far k is.

An instantaneous reward is a weighted sum of the states' rewards under any strategy,
the weights ``M^k 1``. At k = 2^63 - 1 the rounds' error radius outgrew every bound,
and the interval printed was [-inf, inf] ("0 ± inf"); it is now met with the rewards'
range scaled by the row sums' k-th powers (rows of doubles need not sum to 1 exactly:
0.1 + 0.9 exceeds it by 2^-55, and a clip to the plain range once excluded the exact
value, as the hypothesis test in test_certified.py found).
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import scipy.sparse as sp

from veribattery import check_prism_file
from veribattery.checker import kernels
from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.certify.horizon import power_range

#: From x=0 the action ``b`` stays forever (reward 1 each step); ``a`` may move on to
#: x=3 (reward 0). The most reward at step k is 1 (``b`` always), the least 0.5^k.
STAY_OR_GO = """mdp
module m
  x : [0..3] init 0;
  [a] x<3 -> 0.5 : (x'=x+1) + 0.5 : (x'=x);
  [b] x<3 -> true;
  [] x=3 -> true;
endmodule
rewards "r" x<3 : 1; endrewards
"""

LAST_STEP = 2**63 - 1


def test_a_far_bound_keeps_the_interval_within_the_rewards() -> None:
    run = check_prism_file(STAY_OR_GO, selectors=(f'R{{"r"}}max=? [ I={LAST_STEP} ]',
                                                   f'R{{"r"}}min=? [ I={LAST_STEP} ]'))
    most, least = run.results
    assert most.lower is not None and most.upper is not None
    assert least.lower is not None and least.upper is not None
    # exact values 1 and 0.5^(2^63-1) > 0; the rows' sums (1 to within 2^-63 as far as
    # extended precision tells) allow (1 + 2^-63)^(2^63-1), about e, above the range
    assert 0.0 <= most.lower <= 1.0 <= most.upper <= 3.0
    assert 0.0 == least.lower <= least.upper <= 3.0
    assert most.value == 1.0


def test_rows_above_one_in_their_doubles_keep_the_exact_value_inside() -> None:
    # 0.1 + 0.9 is 1 + 2^-55 exactly: one step from state 0 gives more than the most reward
    P = sp.csr_matrix(np.array([[0.1, 0.9], [0.0, 1.0]]))
    found = kernels.instantaneous_rewards(P, np.array([1.0, 1.0]), 1)
    exact = Fraction(0.1) + Fraction(0.9)
    assert exact > 1
    assert Fraction(found.lower[0]) <= exact <= Fraction(found.upper[0])


def test_power_range_against_exact_powers() -> None:
    P = sp.csr_matrix(np.array([[0.1, 0.9], [0.25, 0.25]]))
    sums = [Fraction(0.1) + Fraction(0.9), Fraction(1, 2)]
    for k in (1, 2, 7):
        low, high = power_range(P, 1.0, 2.0, k)
        assert Fraction(low) <= min(sums) ** k and 2 * max(sums) ** k <= Fraction(high)
        assert high <= 2.0 * (1 + 1e-12) and low >= 0.5**k * (1 - 1e-12)  # and not wider
        low, high = power_range(P, -3.0, -1.0, k)  # negative rewards: the powers swap
        assert Fraction(low) <= -3 * max(sums) ** k and -min(sums) ** k <= Fraction(high)
    assert power_range(P, 0.0, 0.0, 10**18) == (0.0, 0.0)


def test_bounds_within_a_range_clip_only_what_lies_outside() -> None:
    found = Bounds(np.array([0.5, 2.0, 0.0]), np.array([-np.inf, 1.5, -1.0]),
                   np.array([np.inf, 3.0, 0.25]))
    met = found.within(0.0, 2.0)
    np.testing.assert_array_equal(met.lower, [0.0, 1.5, 0.0])
    np.testing.assert_array_equal(met.upper, [2.0, 2.0, 0.25])
    np.testing.assert_array_equal(met.value, [0.5, 2.0, 0.0])
    assert found.within(0.0, np.inf) is found  # no finite range: nothing to meet
