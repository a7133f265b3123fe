"""Path forms the float checker had and ``--exact`` refused or mishandled: ``U=k``/``F=k``
(PRISM's exact step, "step bound '=' is not allowed"), the co-safe reward ``R [ a U b ]``
("not supported in exact arithmetic"), Storm's ``T=?`` (QVBS's haddad-monmege) and
negative rewards (refused in floats, answered
with --exact). Found by running the peer suites with ``--exact``."""

from __future__ import annotations

import math
from fractions import Fraction

import pytest

from tests.checker.test_exact import KNUTH_DIE, exact_run
from tests.checker.test_pctl_language import MODEL
from veribattery.errors import VeribatteryError
from veribattery.pipeline import check_prism_file

CASES = [
    # test_pctl_language's chain: s=0 -> 1 (1/3) | 2 (2/3); 2 -> 3; 3 -> 2 (1/4) | 4 (3/4); 4 -> 3
    (MODEL, "P=? [ F=2 s=3 ]", Fraction(2, 3)),
    (MODEL, "P=? [ F=3 s=3 ]", Fraction(0)),
    (MODEL, "P=? [ s!=1 U=2 s=3 ]", Fraction(2, 3)),
    (MODEL, "P=? [ G=2 s>=2 ]", Fraction(2, 3)),
    (MODEL, "P=? [ F[1,3] s=4 ]", Fraction(1, 2)),
    (MODEL, "T=? [ F s=1 | s=4 ]", Fraction(25, 9)),  # (Storm's T=?: "no reward structure")
    # Knuth's die: from s=1 the walk never meets s=2, so s!=2 U s=7 is sure there
    (KNUTH_DIE, 'filter(state, R{"coin"}=? [ s!=2 U s=7 ], s=1)', Fraction(8, 3)),
    (KNUTH_DIE, 'R{"coin"}=? [ s<7 U s=7 ]', Fraction(11, 3)),
    (KNUTH_DIE, 'R{"coin"}=? [ s!=2 U s=7 ]', None),  # (not sure from s=0: infinite)
]


@pytest.mark.parametrize(("model", "text", "expected"), CASES,
                         ids=[case[1] for case in CASES])
def test_exact_and_float_agree_with_the_hand_solution(model: str, text: str,
                                                      expected: Fraction | None) -> None:
    (exact,) = exact_run(model, text)
    (found,) = check_prism_file(model, selectors=(text,)).results
    assert exact.exact == expected
    if expected is None:
        assert math.isinf(exact.value) and math.isinf(found.value)
    else:
        assert found.value == pytest.approx(float(expected), abs=1e-12)


def test_negative_rewards_are_refused_with_exact_too() -> None:
    model = KNUTH_DIE.replace("s<7 : 1;", "s<7 : -1;")
    for exact in (False, True):
        with pytest.raises(VeribatteryError, match="negative rewards"):
            check_prism_file(model, selectors=('R{"coin"}=? [ F s=7 ]',), exact=exact)
