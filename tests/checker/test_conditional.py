"""Conditional properties (Storm's ``||``): hand-solved chains in exact rationals, errors,
and Storm's conditional operator on a small emitted mission model."""

from __future__ import annotations

from collections.abc import Sequence
from fractions import Fraction
from pathlib import Path

import pytest

from tests.checker.chains import gamblers_ruin
from veribattery.errors import CheckError
from veribattery.lang import parse_model
from veribattery.pipeline import check_model, check_prism_file

CHAIN = """dtmc
module m
  s : [0..4] init 0;
  [a] s=0 -> 0.5:(s'=1) + 0.3:(s'=2) + 0.2:(s'=0);
  [b] s=1 -> 0.6:(s'=3) + 0.4:(s'=0);
  [c] s=2 -> 0.5:(s'=4) + 0.5:(s'=2);
  [] s=3 -> true;
  [] s=4 -> true;
endmodule
rewards "t"
  [a] true : 2;
  [b] true : 3;
  s=2 : 1;
endrewards
label "succ" = s=3;
label "fail" = s=4;
label "done" = s=3|s=4;
"""


def _value(prop: str, model: str = CHAIN) -> float:
    run = check_prism_file(model, props_source=prop)
    return float(run.results[0].value)


def _ruin_given_win(n: int, p: Fraction, start: int) -> tuple[Fraction, Fraction]:
    """P(win) and E[steps · 1{win}] / P(win) of gambler's ruin, by exact rational iteration.

    Independent of the conditioned chain: x = P(F win) and y = E[T·1{win}] solve
    x = P x (x(n) = 1) and y = P y + x - [x at absorbing], by Gauss-Seidel to a fixpoint
    on rationals (a finite tridiagonal system solved exactly by elimination).
    """
    q = 1 - p
    # Tridiagonal elimination for x: x_i = p x_{i+1} + q x_{i-1}, x_0 = 0, x_n = 1.
    x = _solve_tridiagonal(n, p, q, [Fraction(0)] * (n + 1), Fraction(0), Fraction(1))
    # y_i = x_i + p y_{i+1} + q y_{i-1} for 0 < i < n (one step from i counts when it wins).
    y = _solve_tridiagonal(n, p, q, x, Fraction(0), Fraction(0))
    return x[start], y[start] / x[start]


def _solve_tridiagonal(n: int, p: Fraction, q: Fraction, rhs: list[Fraction],
                       left: Fraction, right: Fraction) -> list[Fraction]:
    """v_i = rhs_i + p v_{i+1} + q v_{i-1} on 0 < i < n, v_0 = left, v_n = right."""
    # v_i = a_i + b_i v_{i+1}, forward sweep.
    a, b = [left], [Fraction(0)]
    for i in range(1, n):
        denom = 1 - q * b[i - 1]
        a.append((rhs[i] + q * a[i - 1]) / denom)
        b.append(p / denom)
    v = [Fraction(0)] * (n + 1)
    v[0], v[n] = left, right
    for i in range(n - 1, 0, -1):
        v[i] = a[i] + b[i] * v[i + 1]
    return v


def test_hand_solved_conditional_probability_and_reward() -> None:
    # x0 = P(F succ) = 1/2. Given succ: the chain conditioned on reaching 3 never
    # enters 2; from 0 it goes to 1 w.p. 0.5*x1/x0 with x1 = 0.8 → 0.8, stays w.p. 0.2.
    # From 1 it goes to 3 w.p. 0.6/0.8 = 3/4, back to 0 w.p. 0.4*0.5/0.8 = 1/4.
    # E: e0 = 2 + 0.8 e1 + 0.2 e0, e1 = 3 + 0.25 e0 → e0 = 22/3.
    assert _value('R{"t"}=? [ F "done" || F "succ" ]') == pytest.approx(22 / 3, rel=1e-12)
    # P(F s=1 | F succ) = 1; P(F s=2 | F succ) = 0; P(F succ | F fail) = 0.
    assert _value('P=? [ F s=1 || F "succ" ]') == pytest.approx(1.0, abs=1e-12)
    assert _value('P=? [ F s=2 || F "succ" ]') == pytest.approx(0.0, abs=1e-12)
    assert _value('P=? [ F "succ" || F "fail" ]') == pytest.approx(0.0, abs=1e-12)
    # Bounded objective: P(F<=1 succ ... ) given succ: reach 3 within 2 steps from 0
    # in the conditioned chain is 0.8*0.75 = 0.6.
    assert _value('P=? [ F<=2 "succ" || F "succ" ]') == pytest.approx(0.6, rel=1e-12)


@pytest.mark.parametrize(("n", "p", "start"), [(4, Fraction(1, 2), 1), (6, Fraction(1, 3), 3),
                                                (9, Fraction(3, 5), 2)])
def test_gamblers_ruin_steps_given_win(n: int, p: Fraction, start: int) -> None:
    from veribattery.checker import check
    from veribattery.lang import parse_property

    dtmc = gamblers_ruin(n, float(p), initial=(start,))
    p_win, steps = _ruin_given_win(n, p, start)
    prop = parse_property('R{"steps"}=? [ F "end" || F "win" ]')
    assert float(check(dtmc, prop).value) == pytest.approx(float(steps), rel=1e-10)
    cond = parse_property('P=? [ F "win" || F "win" ]')
    assert float(check(dtmc, cond).value) == pytest.approx(1.0, rel=1e-12)
    lose = parse_property('P=? [ X "lose" || F "lose" ]')
    expected = (1 - p) / (1 - p_win) if start == 1 else 0
    assert float(check(dtmc, lose).value) == pytest.approx(float(expected), abs=1e-12)


def test_condition_with_probability_zero_is_an_error() -> None:
    with pytest.raises(CheckError, match=r'the condition F "succ" has probability 0'):
        _value('R{"t"}=? [ F "done" || F "succ" ]', CHAIN.replace("init 0", "init 2"))


def test_unbounded_condition_only() -> None:
    run = check_prism_file(CHAIN, props_source='P=? [ F "succ" || F<=3 "succ" ];')
    assert run.results == ()
    assert any("must be F phi" in w for w in run.warnings)


# ---------------------------------------------------------------------------
# Storm's conditional operator on a small mission model
# ---------------------------------------------------------------------------

REPO = Path(__file__).resolve().parents[2]
#: Case 3 on a 2 x 2 farm with at most 2 recharges: 127 states, P(success) = 0.406.
SMALL_MISSION = ("farm.cols=2", "farm.rows=2", "farm.base=[0,0]", "battery.max_recharges=2")

CONDITIONAL_PROPS = (
    'R{"mt"}=? [ F "done" || F "success" ]',
    'R{"rc"}=? [ F "done" || F "success" ]',
    'P=? [ F rc=1 || F "success" ]',
    'P=? [ F rc=1 || F "failure" ]',
    'P=? [ F "success" || F rc=2 ]',
)


def small_mission_storm_exact(tmp_path: Path, props: Sequence[str]) -> tuple[str, list[Fraction]]:
    """SMALL_MISSION's PRISM text and Storm's exact value of each of *props* initially."""
    stormpy = pytest.importorskip("stormpy")
    from veribattery.config import load_config
    from veribattery.render import render_model

    text = render_model(load_config(REPO / "configs/paper/case3.yaml", SMALL_MISSION))
    path = tmp_path / "model.prism"
    path.write_text(text)
    program = stormpy.parse_prism_program(str(path))
    parsed = stormpy.parse_properties(";".join(props), program)
    model = stormpy.build_model[stormpy.Rational](program, parsed)
    init = model.initial_states[0]
    return text, [Fraction(str(stormpy.model_checking(model, p, only_initial_states=True)
                                .get_value_vector()[init])) for p in parsed]


def test_against_storm_on_a_small_mission(tmp_path: Path) -> None:
    text, exact = small_mission_storm_exact(tmp_path, CONDITIONAL_PROPS)
    storm = [float(value) for value in exact]
    from veribattery.lang import parse_properties

    parsed = parse_properties(";".join(CONDITIONAL_PROPS), name="props")
    run = check_model(parse_model(text, name="model"), parsed.properties)
    ours = [float(r.value) for r in run.results]
    assert 0 < storm[4] < 1 and storm[0] > 0  # the conditions are not trivial
    assert ours == pytest.approx(storm, rel=1e-8)


def test_a_mission_that_never_succeeds_gets_nan_with_a_warning() -> None:
    import math

    from veribattery.config import load_config
    from veribattery.mission import check_mission

    report = check_mission(load_config("farm: {cols: 2, rows: 2, base: [0, 0]}\n"
                                       "battery: {capacity_ah: 3}\n"))
    assert report.values["p_success"] == 0.0
    assert math.isnan(float(report.values["exp_mission_time_given_success"]))
    assert math.isnan(float(report.values["exp_recharges_given_success"]))
    assert any('the condition F "success" has probability 0' in w for w in report.warnings)
