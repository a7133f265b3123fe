"""Reward-bounded reachability on MDPs, ``Pmin``/``Pmax`` of ``F{"r"}<=T``: solved by
hand, against QVBS's exact results on firewire, against Storm, and its refusals."""

from __future__ import annotations

import json
from fractions import Fraction
from pathlib import Path

import pytest
from click.testing import CliRunner

from tests.explore.test_mdp_build import CHOICE
from tests.strategies.models import ROBOT
from veribattery.checker.exact import ExactCheckResult
from veribattery.cli import cli
from veribattery.errors import CheckError
from veribattery.pipeline import check_prism_file

REPO = Path(__file__).resolve().parents[3]

#: s0: [a] (cost 1) reaches the goal s2 or s1 by halves, s1 returns for free; [b]
#: gives up (s3). The goal's own state reward (5) is never paid: it is not left.
MODEL = CHOICE


def _value(prop: str, model: str = MODEL) -> float:
    return float(check_prism_file(model, props_source=prop).results[0].value)


@pytest.mark.parametrize("budget", [0, 1, 2, 3, 7])
def test_hand_solved(budget: int) -> None:
    # k paid [a] steps reach the goal with 1 - 2^-k; the free return costs nothing.
    expected = 1 - 0.5**budget
    assert _value(f'Pmax=? [ F{{"r"}}<={budget} "goal" ]') == pytest.approx(expected,
                                                                            abs=1e-12)
    assert _value(f'Pmax=? [ F{{"r"}}<{budget + 1} "goal" ]') == pytest.approx(expected,
                                                                              abs=1e-12)
    assert _value(f'Pmax=? [ s<3 U^{{rew{{"r"}}<={budget}}} s=2 ]') == pytest.approx(
        expected, abs=1e-12)
    assert _value(f'Pmin=? [ F{{"r"}}<={budget} "goal" ]') == 0.0  # [b]


def test_a_state_in_the_goal_needs_no_budget() -> None:
    assert _value('Pmax=? [ F{"r"}<=0 s=0 ]') == 1.0  # reached before any step


@pytest.mark.parametrize(("deadline", "expected"), [(200, 0.5), (400, 0.78125)])
def test_firewire_deadline_as_qvbs_records_it(deadline: int, expected: float) -> None:
    """QVBS's exact results (Storm, exact engine) for firewire.false, delay 3."""
    folder = REPO / "bench/qcomp/firewire"
    run = check_prism_file(folder / "firewire.false.prism",
                           props_source=folder / "firewire.false.props",
                           selectors=("deadline",),
                           constants={"delay": "3", "deadline": str(deadline)})
    assert float(run.results[0].value) == pytest.approx(expected, rel=1e-9)


def test_non_integer_rewards_are_an_error() -> None:
    with pytest.raises(CheckError, match=r'reward structure "r" gives 1.5 to a choice of '
                                         r"state \(s=0\)"):
        _value('Pmax=? [ F{"r"}<=3 "goal" ]', MODEL.replace(": 1;", ": 1.5;"))


def test_no_strategy_is_exported(tmp_path: Path) -> None:
    model = tmp_path / "m.nm"
    model.write_text(MODEL)
    result = CliRunner().invoke(cli, ["prism", str(model), "--property",
                                      'Pmax=? [ F{"r"}<=3 "goal" ]', "--export-strategy",
                                      str(tmp_path / "s.txt")])
    assert result.exit_code == 2
    assert "the objective is reward-bounded" in result.output
    assert not (tmp_path / "s.txt").exists()


@pytest.mark.parametrize(("prop", "holds"), [
    ('Pmax>=0.875 [ F{"r"}<=3 "goal" ]', True), ('Pmax>0.875 [ F{"r"}<=3 "goal" ]', False),
])
def test_a_bound_its_interval_straddles_is_decided_exactly(prop: str, holds: bool,
                                                          tmp_path: Path) -> None:
    """0.875 exactly: the float interval cannot decide, the exact product can."""
    model = tmp_path / "m.nm"
    model.write_text(MODEL)
    result = CliRunner().invoke(cli, ["prism", str(model), "--property", prop, "--json"])
    assert result.exit_code == 0, result.output
    (answer,) = json.loads(result.stdout)["results"]
    assert answer["value"] is holds
    assert "decided in exact arithmetic" in result.stderr


@pytest.mark.parametrize(("prop", "value"), [
    ('Pmax=? [ F{"r"}<=3 "goal" ]', Fraction(7, 8)),
    ('Pmin=? [ F{"r"}<=3 "goal" ]', Fraction(0)),
    ('Pmax=? [ F{"r"}>=2 "goal" ]', Fraction(1)),  # the goal's deadlock loop pays 5
    ('Pmax=? [ F{"r"}>=2 s=1 ]', Fraction(1, 4)),  # [a] twice, to s1 both times
])
def test_exact_mode(prop: str, value: Fraction) -> None:
    (result,) = check_prism_file(MODEL, props_source=prop, exact=True).results
    assert isinstance(result, ExactCheckResult)
    assert result.exact == value


def test_exact_mode_needs_integer_rewards_exactly() -> None:
    # 1 + 2^-40 passes the float check's tolerance, not the exact one
    with pytest.raises(CheckError, match=r'structure "r" gives 1 to a choice of state \(s=0\)'):
        check_prism_file(MODEL.replace(": 1;", ": 1 + 1/1099511627776;"),
                         props_source='Pmax=? [ F{"r"}<=3 "goal" ]', exact=True)


# ---------------------------------------------------------------------------
# Storm
# ---------------------------------------------------------------------------


def _storm(text: str, props: list[str], tmp_path: Path) -> list[float]:
    pytest.importorskip("stormpy")
    from tests.storm_oracle import storm_initial_values

    return storm_initial_values(text, props, tmp_path)


@pytest.mark.parametrize(("text", "props"), [
    (MODEL, [f'P{d}=? [ F{{"r"}}<={k} "goal" ]' for d in ("min", "max") for k in (0, 2, 5)]),
    (ROBOT, [f'P{d}=? [ F{{"{r}"}}<={k} "goal" ]' for d in ("min", "max") for k in (1, 3, 6)
             for r in ("steps", "time")]
     + ['Pmax=? [ !"broken" U{"steps"}<=4 "goal" ]']
     + [f'P{d}=? [ F{{"time"}}>={k} "goal" ]' for d in ("min", "max") for k in (2, 5)]),
], ids=["hand", "robot"])
def test_against_storm(text: str, props: list[str], tmp_path: Path) -> None:
    """Storm's exact values, to 1e-6 in float and to the last bit in ``--exact``."""
    storm = _storm(text, props, tmp_path)
    ours = [_value(p, text) for p in props]
    assert ours == pytest.approx(storm, rel=1e-6, abs=1e-9)
    exact = check_prism_file(text, props_source=";".join(props), exact=True).results
    assert [float(r.exact) for r in exact if isinstance(r, ExactCheckResult)] == storm
