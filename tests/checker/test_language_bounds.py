"""The property language on the certified engine: every number carries an interval
that holds the exact value (solved by hand with Fractions), and is precise."""

from __future__ import annotations

import json
from fractions import Fraction as Q

import pytest
from click.testing import CliRunner

from tests.checker.test_pctl_language import MODEL
from veribattery.cli import cli
from veribattery.pipeline import check_prism_file

EXACT = [
    ("S=? [ s=3 ]", Q(2, 3) * Q(1, 2)),
    ("S=? [ s=2 ]", Q(2, 3) * Q(1, 8)),
    ('R{"r"}=? [ S ]', Q(2, 3) * (Q(1, 2) * 2)),
    ('R{"r"}=? [ C ]', None),  # infinite: exact
    ('filter(state, R{"r"}=? [ C ], s=1)', Q(0)),
    ("1 - P=? [ F s=1 ]", Q(2, 3)),
    ("P=? [ F s=1 ] + P=? [ F s=2 ]", Q(1)),
    ("P=? [ F s=1 ] * 3", Q(1)),
    ("P=? [ F s=1 ] / P=? [ F s=2 ]", Q(1, 2)),
    ("P=? [ F[1,1] s=2 ]", Q(2, 3)),
    ("P=? [ s<2 W s=1 ]", Q(1, 3)),
    ("filter(sum, P=? [ F s=1 ])", Q(1, 3) + 1),
    ("filter(avg, S=? [ s=3 ])", (Q(2, 3) * Q(1, 2) + 3 * Q(1, 2)) / 5),
    ("filter(max, S=? [ s=3 ], s>1)", Q(1, 2)),
    ("min(P=? [ F s=1 ], 0.5)", Q(1, 3)),
]


@pytest.mark.parametrize(("text", "exact"), EXACT, ids=[c[0] for c in EXACT])
def test_interval_holds_the_exact_value(text: str, exact: Q | None) -> None:
    result = check_prism_file(MODEL, selectors=(text,)).results[0]
    assert result.lower is not None and result.upper is not None
    if exact is None:
        assert result.value == result.lower == result.upper == float("inf")
    else:
        assert Q(result.lower) <= exact <= Q(result.upper)
    assert result.precise


def test_uncertified_function_is_honestly_imprecise() -> None:
    """``log`` gets no enclosure: [-inf, inf], reported imprecise."""
    result = check_prism_file(MODEL, selectors=("log(P=? [ F s=2 ], 2)",)).results[0]
    assert (result.lower, result.upper, result.precise) == (float("-inf"), float("inf"), False)


def test_boundary_of_step_bounded_operator_is_decided_exactly() -> None:
    """P(F<=2 s=1) from s=0 is exactly 1/3 as stored; ``>`` it fails, ``>=`` it holds
    (the float error bar straddles it; the rational retry decides)."""
    third = repr(1 / 3)
    results = check_prism_file(MODEL, selectors=(f"P>{third} [ F<=2 s=1 ]",
                                                 f"P>={third} [ F<=2 s=1 ]")).results
    assert [r.value for r in results] == [False, True]


def test_prism_json_has_bounds_and_range(tmp_path: object) -> None:
    model = MODEL.replace("s : [0..4] init 0;", "s : [0..4];").replace(
        "endmodule", "endmodule\ninit s<2 endinit")
    path = tmp_path / "m.pm"  # type: ignore[operator]
    path.write_text(model)
    out = CliRunner().invoke(cli, ["prism", str(path), "--property", "P=? [ F s=1 ]",
                                   "--json"])
    assert out.exit_code == 0, out.output
    entry = json.loads(out.stdout)["results"][0]
    low, high = entry["range"]  # initial states s=0 (1/3) and s=1 (1)
    assert low == pytest.approx(1 / 3, rel=1e-12) and high == 1.0
    lower, upper = entry["bounds"]  # enclose the whole range
    assert Q(lower) <= Q(1, 3) and upper >= 1.0 and entry["precise"] is True
