"""--exact decides closed comparisons and integers in rationals, as PRISM's exact engine
(prism-tests/functionality/verify/exact/exact-eval-*.prism are its own tests of this).

In doubles ``1/3 = 0.333333333333333333333333`` is true (both round to the same
double) and ``ceil(0.1*3*10)`` is 4; exactly they are false and 3.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner
from gmpy2 import mpq

from tests.checker.test_exact import KNUTH_DIE
from veribattery.cli import cli
from veribattery.errors import ModelError
from veribattery.explore.exact.decided import decided_exactly
from veribattery.lang import parse_property
from veribattery.lang.nodes import Binary, BoolLit, DoubleLit, Expr, Ident, IntLit

THIRD = "1/3 = 0.333333333333333333333333"


def _formula(text: str) -> Expr:
    return parse_property(text).formula


def test_closed_comparisons_and_integers_take_their_exact_values() -> None:
    assert decided_exactly(_formula(THIRD), {}) == BoolLit(False)
    assert decided_exactly(_formula("ceil(p*3*10)"), {"p": mpq(1, 10)}) == IntLit(3)
    assert decided_exactly(_formula(f"({THIRD}) ? 1 : 2"), {}) == IntLit(2)


def test_open_expressions_keep_their_form_around_decided_parts() -> None:
    decided = decided_exactly(_formula(f"s = (({THIRD}) ? 0 : 3)"), {})
    assert decided == Binary("=", Ident("s"), IntLit(3))


def test_a_closed_double_keeps_its_exact_value_as_its_text() -> None:
    third = decided_exactly(_formula("1/3 + 0*s"), {})
    assert isinstance(third, Binary) and isinstance(third.left, DoubleLit)
    assert (third.left.value, third.left.text) == (1 / 3, "1/3")


def test_a_closed_number_without_an_exact_value_is_an_error() -> None:
    with pytest.raises(ModelError, match="non-integer exponent"):
        decided_exactly(_formula("s > pow(2, 0.5)"), {})


def test_a_long_open_chain_is_walked_once() -> None:
    chain = " + ".join(["s"] * 5000)
    decided = decided_exactly(_formula(f"{chain} > ceil(0.1*3*10)"), {})
    assert isinstance(decided, Binary) and decided.right == IntLit(3)


_MODELS = {
    # a constant's comparison decides a probability (0 exactly: s=1 is unreachable)
    "constant": ("const double p = (" + THIRD + " ? 1/2 : 0);",
                 "[] s=0 -> p:(s'=1) + 1-p:(s'=2);", "init 0", 0),
    # an int constant decides an update's target
    "int constant": ("const int n = (" + THIRD + " ? 1 : 2);",
                     "[] s=0 -> 1/2:(s'=n) + 1/2:(s'=2);", "init 0", 0),
    # an update's target, inline
    "update": ("", "[] s=0 -> 1/2:(s'=(" + THIRD + " ? 1 : 2)) + 1/2:(s'=2);", "init 0", 0),
    # a guard
    "guard": ("", "[] s=(" + THIRD + " ? 0 : 3) -> (s'=1);\n[] s=0 -> (s'=2);", "init 0", 0),
    # an initial value
    "init": ("", "[] s=0 -> true;", "init (" + THIRD + " ? 1 : 2)", 0),
    # a constant computed from a decimal given on the command line
    "ceil": ("const double q; const int k = ceil(q*3*10);",
             "[] s=0 -> 1/2:(s'=(k=3 ? 1 : 2)) + 1/2:(s'=2);", "init 0", mpq(1, 2)),
    # a probability written as a closed expression keeps its exact value (1/3, not the
    # double nearest it: the state s=1 gets 1/3 and s=2 gets 2/3 exactly)
    "probability": ("const double r = 1/3;", "[] s=0 -> r*1:(s'=1) + 1-r:(s'=2);", "init 0",
                    mpq(1, 3)),
}


@pytest.mark.parametrize("case", sorted(_MODELS))
@pytest.mark.parametrize("kind", ["dtmc", "mdp"])
def test_exact_mode_decides_the_model_exactly(tmp_path: Path, case: str, kind: str) -> None:
    constants, commands, init, expected = _MODELS[case]
    model = tmp_path / "m.prism"
    model.write_text(f"{kind}\n{constants}\nmodule M\n  s : [0..3] {init};\n  {commands}\n"
                     "  [] s>=1 -> true;\nendmodule\n")
    query = "P=? [ F s=1 ]" if kind == "dtmc" else "Pmax=? [ F s=1 ]"
    given = ["--const", "q=0.1"] if "const double q" in constants else []
    result = CliRunner().invoke(cli, ["prism", str(model), "--property", query, *given,
                                      "--exact", "--json"])
    assert result.exit_code == 0, result.stderr
    assert json.loads(result.stdout)["results"][0]["exact"] == str(expected)


@pytest.mark.parametrize("kind", ["dtmc", "mdp"])
def test_exact_mode_decides_a_property_exactly(tmp_path: Path, kind: str) -> None:
    model = tmp_path / "m.prism"
    model.write_text(f"{kind}\nmodule M\n  s : [0..1];\n  [a] s=0 -> (s'=1);\nendmodule\n"
                     f'rewards "r"\n  [a] s=(({THIRD}) ? 1 : 0) : 2;\nendrewards\n')
    reward = "R=? [ F s>0 ]" if kind == "dtmc" else "Rmax=? [ F s>0 ]"
    result = CliRunner().invoke(cli, ["prism", str(model), "--property", f"({THIRD})",
                                      "--property", reward, "--exact", "--json"])
    assert result.exit_code == 0, result.stderr
    first, second = json.loads(result.stdout)["results"]
    assert first["value"] is False
    assert second["exact"] == "2"  # the reward's guard is s=0 exactly


# prism-tests/functionality/language/power.prism's properties, on Knuth's die, with
# --exact: numbers over state variables and over P=? queries, in every state.


@pytest.mark.parametrize(("prop", "expected"), [
    ("s+1", "1"),
    ("round(1+P=?[F<=1 d=6])", "1"),
    ("(2*(s+1))^(d+3)", "8"),
    ("(0.5*round(P=?[F true]))^(d+2)", "1/4"),
    ("(2*(s+1))^(d-1.0)", "1/2"),
    ("P=? [ F s=7 & d=6 ] * 6 + 1/3", "4/3"),
    ("filter(max, P=? [ F d=6 ] * (d+1), s=7)", "7"),
])
@pytest.mark.parametrize("kind", ["dtmc", "mdp"])
def test_exact_numbers_over_states_and_queries(tmp_path: Path, prop: str, expected: str,
                                               kind: str) -> None:
    model = tmp_path / "die.prism"
    model.write_text(KNUTH_DIE.replace("dtmc", kind))
    if kind == "mdp":
        prop = prop.replace("P=?", "Pmax=?")
    result = CliRunner().invoke(cli, ["prism", str(model), "--property", prop, "--exact",
                                      "--json"])
    assert result.exit_code == 0, result.stderr
    assert json.loads(result.stdout)["results"][0]["exact"] == expected


def test_a_predicate_without_an_exact_value_is_decided_in_doubles(tmp_path: Path) -> None:
    # floor(log(d+1, 2)) = 2 for d in 3..6: log has no exact value, the predicate is
    # decided in doubles (documented); a number without one is an error.
    model = tmp_path / "die.prism"
    model.write_text(KNUTH_DIE)
    result = CliRunner().invoke(cli, ["prism", str(model), "--property",
                                      "P=? [ F s=7 & floor(log(d+1, 2))=2 ]", "--property",
                                      "log(d+2, 2)", "--exact", "--json"])
    assert result.exit_code == 2 and "log" in result.stderr
    result = CliRunner().invoke(cli, ["prism", str(model), "--property",
                                      "P=? [ F s=7 & floor(log(d+1, 2))=2 ]", "--exact",
                                      "--json"])
    assert json.loads(result.stdout)["results"][0]["exact"] == "2/3"


_THIRD_CHAIN = ("dtmc\nconst double q;\nmodule m\n  s : [0..2];\n"
                "  [] s=0 -> 1/3:(s'=1) + 2/3:(s'=2);\n  [] s>0 -> true;\nendmodule\n")


def test_a_constant_is_read_as_its_exact_value() -> None:
    decided = decided_exactly(_formula("s < q"), {"q": mpq(1, 3)})
    assert isinstance(decided, Binary) and isinstance(decided.right, DoubleLit)
    assert decided.right.text == "1/3"


@pytest.mark.parametrize("kind", ["dtmc", "mdp"])
@pytest.mark.parametrize("exact", [False, True])
def test_a_bound_given_as_a_constant_is_exact(tmp_path: Path, kind: str, exact: bool) -> None:
    # P [ F s=1 ] is exactly 1/3 = q: P<=q holds, P<q does not (in floats, the interval
    # straddles q and the bound is settled in exact arithmetic).
    model = tmp_path / "m.prism"
    model.write_text(_THIRD_CHAIN.replace("dtmc", kind))
    args = ["prism", str(model), "--property", "P<=q [ F s=1 ]", "--property",
            "P<q [ F s=1 ]", "--const", "q=1/3", "--json", *(["--exact"] if exact else [])]
    result = CliRunner().invoke(cli, args)
    assert result.exit_code == 0, result.stderr
    assert [r["value"] for r in json.loads(result.stdout)["results"]] == [True, False]


def test_a_constant_in_arithmetic_over_a_query_is_exact(tmp_path: Path) -> None:
    model = tmp_path / "m.prism"
    model.write_text(_THIRD_CHAIN)
    result = CliRunner().invoke(cli, ["prism", str(model), "--property", "P=? [ F s=1 ] - q",
                                      "--const", "q=1/3", "--exact", "--json"])
    assert result.exit_code == 0, result.stderr
    assert json.loads(result.stdout)["results"][0]["exact"] == "0"  # not 1/3 - its double


#: Module b is a renamed with p1=p2: its branch probabilities and its guard read p2 (the
#: decision had replaced p1 in a first, and b's copy read p1's value: Storm's coin2_2
#: with p1=0.4, p2=0.6 gave Pmin 0.7456 for 0.1278, its team3 120/49 for 114/49).
_RENAMED = """{kind}
const double p1;
const double p2;
module a
  x : [0..2];
  [] x=0 & p1 < 1/2 -> p1:(x'=1) + 1-p1:(x'=2);
  [] x=0 & p1 >= 1/2 -> 1/4:(x'=1) + 3/4:(x'=2);
  [] x>0 -> true;
endmodule
module b = a [x=y, p1=p2] endmodule
"""


@pytest.mark.parametrize("kind", ["dtmc", "mdp"])
@pytest.mark.parametrize("exact", [False, True])
def test_a_renamed_constant_is_read_in_the_renamed_module(tmp_path: Path, kind: str,
                                                          exact: bool) -> None:
    model = tmp_path / "m.prism"
    model.write_text(_RENAMED.format(kind=kind))
    op = "P" if kind == "dtmc" else "Pmax"
    args = ["prism", str(model), "--property", f"{op}=? [ F x=1 ]", "--property",
            f"{op}=? [ F y=1 ]", "--property", f"{op}=? [ F x=1 & y=1 ]",
            "--const", "p1=1/3,p2=3/5", "--json", *(["--exact"] if exact else [])]
    result = CliRunner().invoke(cli, args)
    assert result.exit_code == 0, result.stderr
    found = json.loads(result.stdout)["results"]
    expected = [mpq(1, 3), mpq(1, 4), mpq(1, 12)]  # (b: p2 >= 1/2, so 1/4 to y=1)
    if exact:
        assert [mpq(r["exact"]) for r in found] == expected
    else:
        assert [r["value"] for r in found] == pytest.approx([float(e) for e in expected])
