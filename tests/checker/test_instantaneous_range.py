"""``I=k``'s certified interval stays inside the rewards' range, however far k is.

An instantaneous reward is an average of the states' rewards under any strategy. At
k = 2^63 - 1 the rounds' error radius outgrew every bound, and the interval printed was
[-inf, inf] ("0 ± inf"); it is now met with [least reward, most reward].
"""

from __future__ import annotations

import numpy as np

from veribattery import check_prism_file
from veribattery.checker.certify.bounds import Bounds

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
    assert 0.0 <= most.lower <= 1.0 == most.upper  # the exact value 1 inside, nothing above
    assert 0.0 == least.lower <= least.upper <= 1.0  # exact value 0.5^(2^63-1) > 0
    assert most.value == 1.0


def test_bounds_within_a_range_clip_only_what_lies_outside() -> None:
    found = Bounds(np.array([0.5, 2.0, 0.0]), np.array([-np.inf, 1.5, -1.0]),
                   np.array([np.inf, 3.0, 0.25]))
    met = found.within(0.0, 2.0)
    np.testing.assert_array_equal(met.lower, [0.0, 1.5, 0.0])
    np.testing.assert_array_equal(met.upper, [2.0, 2.0, 0.25])
    np.testing.assert_array_equal(met.value, [0.5, 2.0, 0.0])
    assert found.within(0.0, np.inf) is found  # no finite range: nothing to meet
