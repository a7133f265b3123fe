"""``veribattery prism MDP --exact`` and bounds the certified interval cannot decide.

The models are solved by hand. CHOICE: in s=0 action [a] reaches s=1 with 1/3,
[b] with 1/6 (else s=2); [a] earns 1/3, [b] 1/7. So Pmax(F s=1) = 1/3,
Pmin = 1/6, Rmin(F s>0) = 1/7, Rmax(C) = 1/3. LOOP (a DTMC and an MDP): s=0
moves to s=1 with 2/9, to s=2 with 4/9 and stays with 1/3, so P(F s=1) = 1/3
exactly; written with ``pow(4, 0.5)`` it has no exact rational form.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from veribattery.checker import UndecidedResult
from veribattery.cli import cli
from veribattery.pipeline import check_prism_file

CHOICE = """mdp
module m
  s : [0..2] init 0;
  [a] s=0 -> 1/3:(s'=1) + 2/3:(s'=2);
  [b] s=0 -> 1/6:(s'=1) + 5/6:(s'=2);
  [] s>0 -> true;
endmodule
rewards "r"
  [a] true : 1/3;
  [b] true : 1/7;
endrewards
"""

LOOP = """{kind}
const double p = {p};
module m
  s : [0..2] init 0;
  [] s=0 -> p:(s'=1) + 2*p:(s'=2) + (1-3*p):(s'=0);
  [] s>0 -> true;
endmodule
"""


def _json(model: str, tmp_path: Path, *args: str) -> tuple[int, list[dict[str, object]]]:
    path = tmp_path / "m.prism"
    path.write_text(model)
    result = CliRunner().invoke(cli, ["prism", str(path), "--json", *args])
    results = json.loads(result.stdout)["results"] if result.exit_code == 0 else []
    return result.exit_code, results


@pytest.mark.parametrize(("prop", "exact"), [
    ("Pmax=? [ F s=1 ]", "1/3"),
    ("Pmin=? [ F s=1 ]", "1/6"),
    ("Pmin=? [ G s!=1 ]", "2/3"),
    ("Pmax=? [ X s=1 ]", "1/3"),
    ("Pmax=? [ F<=1 s=1 ]", "1/3"),
    ("Pmin=? [ F<1 s=1 ]", "0"),
    ("Rmin=? [ F s>0 ]", "1/7"),
    ("Rmax=? [ C ]", "1/3"),
    ("Rmax=? [ C<=1 ]", "1/3"),
    ("Rmin=? [ I=1 ]", "0"),
    ("Rmax=? [ F s=1 ]", "Infinity"),  # s=2 never reaches s=1
])
def test_exact_mdp_values(prop: str, exact: str, tmp_path: Path) -> None:
    code, results = _json(CHOICE, tmp_path, "--exact", "--property", prop)
    assert code == 0
    assert results[0]["exact"] == exact


@pytest.mark.parametrize(("prop", "holds"), [
    ("P>=1/6 [ F s=1 ]", True), ("P>1/6 [ F s=1 ]", False),
    ("Pmax>=1/3 [ F s=1 ]", True), ("Pmax>1/3 [ F s=1 ]", False),
    ("P<=1/3 [ F s=1 ]", True), ("P<1/3 [ F s=1 ]", False),
    ("R<=1/3 [ C ]", True), ("Rmin<1/7 [ F s>0 ]", False),
])
def test_bounds_at_the_value_decided_in_both_modes(prop: str, holds: bool,
                                                   tmp_path: Path) -> None:
    """Exactly at the bound: ``--exact`` decides it, and so does the float mode (its
    certified interval straddles the bound, and the bound is settled exactly)."""
    for mode in ((), ("--exact",)):
        code, results = _json(CHOICE, tmp_path, *mode, "--property", prop)
        assert code == 0
        assert results[0]["value"] is holds, mode


@pytest.mark.parametrize("kind", ["dtmc", "mdp"])
@pytest.mark.parametrize(("prop", "holds"), [
    ("P>=1/3 [ F s=1 ]", True), ("P>1/3 [ F s=1 ]", False), ("P<1/3 [ F s=1 ]", False),
    ("Pmax>=1/3 [ F s=1 ]", True), ("Pmax>1/3 [ F s=1 ]", False),
])
def test_undecided_bound_is_settled_exactly(kind: str, prop: str, holds: bool) -> None:
    if kind == "dtmc":
        prop = prop.replace("Pmax", "P")
    run = check_prism_file(LOOP.format(kind=kind, p="2/9"), selectors=(prop,))
    assert run.results[0].value is holds


@pytest.mark.parametrize("kind", ["dtmc", "mdp"])
def test_bound_without_exact_form_is_undecided(kind: str, tmp_path: Path) -> None:
    """``pow(4, 0.5)/9`` is 2/9, but has no exact rational evaluation: the straddled
    bound stays undecided -- reported, exit status 0, never an input error."""
    model = LOOP.format(kind=kind, p="pow(4, 0.5)/9")
    run = check_prism_file(model, selectors=("P>1/3 [ F s=1 ]",))
    assert isinstance(run.results[0], UndecidedResult)
    assert "no exact rational value" in run.results[0].reason
    assert any("undecided" in w for w in run.warnings)
    code, results = _json(model, tmp_path, "--property", "P>1/3 [ F s=1 ]")
    assert code == 0
    assert results[0]["value"] is None and "straddles" in str(results[0]["undecided"])
    assert "np.float64" not in str(results[0]["undecided"])  # plain floats in the message
    path = tmp_path / "m.prism"
    table = CliRunner().invoke(cli, ["prism", str(path), "--property", "P>1/3 [ F s=1 ]"])
    assert table.exit_code == 0 and "undecided" in table.stdout


def test_decided_bounds_leave_the_run_unchanged() -> None:
    """A bound the float interval decides is not re-checked (no exact-mode warning)."""
    run = check_prism_file(CHOICE, selectors=("Pmax>0.3 [ F s=1 ]",))
    assert run.results[0].value is True and run.warnings == ()


@pytest.mark.parametrize(("prop", "exact"), [
    ("filter(max, Pmax=? [ F s=2 ])", "1"),  # s=2 is there already
    ("filter(min, Pmax=? [ F s=2 ], s>0)", "0"),  # s=1 stays
    ("filter(sum, Pmax=? [ F s=2 ])", "11/6"),  # 5/6 + 0 + 1
    ("filter(avg, Pmax=? [ F s=2 ])", "11/18"),
    ("Pmax=? [ F s=2 {s=0} ]", "5/6"),
    ("filter(first, Rmin=? [ C ])", "1/7"),
    ("filter(max, Rmax=? [ F s=1 ])", "Infinity"),
])
def test_exact_mdp_filters(prop: str, exact: str, tmp_path: Path) -> None:
    code, results = _json(CHOICE, tmp_path, "--exact", "--property", prop)
    assert code == 0
    assert results[0]["exact"] == exact


@pytest.mark.parametrize(("prop", "value"), [
    ("1 - Pmax=? [ F s=1 ]", "2/3"),
    ("Pmax=? [ F s=1 ] + Pmin=? [ F s=1 ]", "1/2"),
    ("Pmax=? [ F s=1 ] / Pmin=? [ F s>0 ]", "1/3"),  # Pmin(F s>0) = 1 in every state
    ("1/3 < Pmax=? [ F s=1 ]", False),  # 1/3 as written, not the double below it
    ("Pmax=? [ F s=1 ] * 3 = 1", True),
    ("3.14", "157/50"),  # a literal as written
    ("filter(sum, s/2)", "3/2"),  # 0 + 1/2 + 1
])
def test_exact_mdp_arithmetic_over_queries(prop: str, value: object, tmp_path: Path) -> None:
    code, results = _json(CHOICE, tmp_path, "--exact", "--property", prop)
    assert code == 0
    assert results[0].get("exact", results[0]["value"]) == value


def test_float_comparison_at_the_value_is_settled_exactly() -> None:
    run = check_prism_file(CHOICE, selectors=("1/3 < Pmax=? [ F s=1 ]",
                                              "Pmax=? [ F s=1 ] >= 1/3"))
    assert [r.value for r in run.results] == [False, True]


def test_exact_mdp_boolean_filter_and_bool_variable(tmp_path: Path) -> None:
    """A bool variable as a target, and filters over state sets (3 steps, reward 1 each)."""
    model = """mdp
module w
  t : [0..3] init 0;
  goal : bool init false;
  [tick] t<3 & !goal -> (t'=t+1);
  [reach] t=3 & !goal -> (goal'=true) & (t'=0);
  [loop] goal -> true;
endmodule
rewards "r"
  !goal : 1;
endrewards
"""
    props = ("Rmin=? [ F goal ]", "filter(forall, Pmin>=1 [ F goal ])",
             "filter(count, Pmax<1 [ G !goal ])")
    code, results = _json(model, tmp_path, "--exact", *(a for p in props
                                                         for a in ("--property", p)))
    assert code == 0
    assert [r.get("exact", r["value"]) for r in results] == ["4", True, 5]


@pytest.mark.parametrize(("prop", "message"), [
    ("Pmax=? [ F filter(forall, s>0) ]", "filter(...) is answered at the top"),
    ("Rmax=? [ F s=1 ] + 1", "an infinite expected reward has no exact arithmetic"),
    ("Pmax=? [ F s=1 ] / Pmin=? [ F s=0 ]", "division by zero"),
    ("P=? [ F s=1 ]", "P=? on an MDP has no single value"),
])
def test_exact_mdp_refusals_are_one_line(prop: str, message: str, tmp_path: Path) -> None:
    path = tmp_path / "m.prism"
    path.write_text(CHOICE)
    result = CliRunner().invoke(cli, ["prism", str(path), "--exact", "--property", prop])
    assert result.exit_code == 2
    assert message in result.stderr and len(result.stderr.strip().splitlines()) == 1


def test_several_initial_states_give_the_lowest_and_the_range(tmp_path: Path) -> None:
    """From s=0 Pmax(F s=1) is 1/3, from s=2 it is 0; Rmin(F s=2) is 0 from s=2 and
    infinite from s=0 (both choices may end in s=1): the lowest, and the range."""
    model = CHOICE.replace("s : [0..2] init 0;", "s : [0..2];").replace(
        "endmodule", "endmodule\ninit s=0 | s=2 endinit")
    props = ("Pmax=? [ F s=1 ]", "Rmin=? [ F s=2 ]")
    args = [a for p in props for a in ("--property", p)]
    code, exact = _json(model, tmp_path, "--exact", *args)
    assert code == 0
    assert [(r["exact"], r["range"]) for r in exact] == [
        ("0", [0.0, 1 / 3]), ("0", [0.0, "Infinity"])]
    code, floats = _json(model, tmp_path, *args)
    assert [r["range"] for r in floats] == [r["range"] for r in exact]
