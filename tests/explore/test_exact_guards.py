"""``--exact`` decides guards, assignments, labels and reward guards in rationals.

In doubles ``3*0.1`` is 0.30000000000000004, so ``x*0.1 <= 0.3`` is false at
``x = 3`` and ``x*0.1 = 0.3`` never holds; of the numbers as written both hold
at ``x = 3``. The expected state spaces and values below are derived by hand
from that one fact.
"""

from __future__ import annotations

from fractions import Fraction

import pytest
from click.testing import CliRunner

from veribattery.checker.exact import ExactCheckResult
from veribattery.cli import cli
from veribattery.explore.exact.program import needs_exact
from veribattery.lang import parse_property
from veribattery.pipeline import check_prism_file

#: x counts up (each step with probability 1/2) while x*step <= 0.3; y records
#: ceil(x*step*10) of the state left; "edge" and the reward hold where x*step = 0.3.
MODEL = """dtmc
const double step = 0.1;
module m
  x : [0..10] init 0;
  y : [0..10] init 0;
  [] x*step <= 0.3 -> 0.5 : (x'=x+1) & (y'=ceil(x*step*10)) + 0.5 : (x'=x);
  [] x*step > 0.3 -> true;
endmodule
label "edge" = x*step = 0.3;
rewards "edge"
  x*step = 0.3 : 1;
endrewards
"""

PROPERTIES = ('P=? [ F x=4 ]', 'P=? [ F "edge" ]', 'P=? [ F y=4 ]', 'R{"edge"}=? [ C<=4 ]')


def _run(exact: bool) -> tuple[int, list[object]]:
    run = check_prism_file(MODEL, selectors=PROPERTIES, exact=exact)
    values = [r.exact if isinstance(r, ExactCheckResult) else r.value for r in run.results]
    return run.dtmc.num_states, values


def test_float_build_rounds_the_guard() -> None:
    """The float path (and Storm, see below): x stops at 3, "edge" never holds."""
    states, (reach4, edge, y4, reward) = _run(exact=False)
    assert states == 4  # x = 0..3, y = ceil(x*0.1*10) = x except 4 at x = 3 (not reached)
    assert (reach4, edge, y4, reward) == (0.0, 0.0, 0.0, 0.0)


def test_exact_build_decides_the_guard_exactly() -> None:
    """Exactly: x reaches 4 (x*step <= 0.3 at x = 3), y = 3 there, "edge" holds at x = 3."""
    states, (reach4, edge, y4, reward) = _run(exact=True)
    assert states == 5  # (x, y) = (0,0) (1,0) (2,1) (3,2) (4,3)
    assert reach4 == Fraction(1)
    assert edge == Fraction(1)
    assert y4 == Fraction(0)  # ceil(3/10*10) = 3 exactly, never 4
    assert reward == Fraction(1, 8)  # in x = 3 at step 3 (three successes), counted by C<=4


def test_storm_exact_decides_guards_in_doubles(tmp_path) -> None:
    """Storm's exact engine rounds guards like our float path: 4 states, not 5.

    Recorded here so that a change on either side shows: our ``--exact`` follows
    the numbers as written (PRISM's ``-exact`` semantics and issue 9), not Storm.
    """
    stormpy = pytest.importorskip("stormpy")
    path = tmp_path / "m.prism"
    path.write_text(MODEL)
    program = stormpy.parse_prism_program(str(path))
    props = stormpy.parse_properties("P=? [ F x=4 ]", program)
    built = stormpy.build_model[stormpy.Rational](program, options=stormpy.BuilderOptions(props))
    assert built.nr_states == _run(exact=False)[0] == 4


@pytest.mark.parametrize(
    ("text", "rounds"),
    [("x*0.1 <= 0.3", True), ("x/2 > 1", True), ("pow(x, 2) > 3", True),
     ("2*x + 1 >= 3 & !(x = 4)", False), ("x >= 3", False),
     # a floor or ceiling of a bounded integer quotient is exact in doubles ...
     ("floor(110*(500 - x)/500) > 3", False), ("ceil(x/3) = 1", False),
     # ... but not of a double, nor of an unbounded operand, nor a bare quotient
     ("floor(x/0.5) > 1", True), ("floor(y/3) > 1", True), ("floor(x/3) + x/3 > 1", True)],
)
def test_which_expressions_are_decided_exactly(text: str, rounds: bool) -> None:
    expr = parse_property(f"P=? [ F {text} ]").formula.path.operand  # type: ignore[attr-defined]
    assert needs_exact(expr, {"x": (0, 10)}) is rounds


def test_log_in_a_guard_under_exact_is_one_line_exit_2(tmp_path) -> None:
    path = tmp_path / "m.pm"
    path.write_text("dtmc\nmodule m\n  s : [0..1] init 0;\n  [] log(8, 2) > s -> (s'=1);\n"
                    "  [] s=1 -> true;\nendmodule\n")
    result = CliRunner().invoke(cli, ["prism", str(path), "--property", "P=? [ F s=1 ]",
                                      "--exact"])
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and f"{path}:4:" in lines[0] and "log" in lines[0], lines
    assert result.stdout == ""
