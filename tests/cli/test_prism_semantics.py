"""``veribattery prism`` on corners of PRISM's semantics met in PRISM's own regression
tests (prism-tests/): a boolean variable's value, CTL on MDPs."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from veribattery.cli import cli

_FLAG = """{kind}
const bool flag;
module Boolean
  b : bool init flag;
endmodule
"""

# prism-tests/functionality/verify/ltss/lec9ctl1.prism (an LTS: no type, so an MDP).
_LTS = """
module M
s:[0..3];
[] s=0 -> (s'=1);
[] s=0 -> (s'=2);
[] s=1 -> (s'=1);
[] s=1 -> (s'=3);
[] s=2 -> (s'=1);
[] s=3 -> (s'=3);
endmodule
label "a" = s=0 | s=1;
label "b" = s=0 | s=3;
"""


def _values(tmp_path: Path, model: str, *args: str) -> list[object]:
    path = tmp_path / "m.prism"
    path.write_text(model)
    result = CliRunner().invoke(cli, ["prism", str(path), *args, "--json"])
    assert result.exit_code == 0, result.stderr
    return [r["value"] for r in json.loads(result.stdout)["results"]]


@pytest.mark.parametrize("kind", ["dtmc", "mdp"])
@pytest.mark.parametrize("flag", [True, False])
def test_a_boolean_variable_is_reported_as_a_boolean(tmp_path: Path, kind: str,
                                                     flag: bool) -> None:
    # prism-tests/bugfixes/boolean-constant-issue-232.prism: the value of "b" is a boolean,
    # though the state table stores it as 0/1.
    model, const = _FLAG.format(kind=kind), f"flag={str(flag).lower()}"
    values = _values(tmp_path, model, "--const", const,
                     "--property", "b", "--property", "b ? 2 : 3", "--property", "!b")
    assert values == [flag, 2 if flag else 3, not flag]
    assert isinstance(values[0], bool)
    assert _values(tmp_path, model, "--const", const, "--property", "b", "--exact") == [flag]


# By hand on the graph: s=0 -> {1, 2}; s=1 -> {1, 3}; s=2 -> {1}; s=3 -> {3}.
@pytest.mark.parametrize(("formula", "states"), [
    ('A [ X "a" ]', {2}),                # every successor in a={0,1}: only s=2 (-> 1)
    ('E [ X !"b" ]', {0, 1, 2}),         # some successor outside b={0,3}
    ('E [ F s=3 ]', {0, 1, 2, 3}),
    ('A [ F s=3 ]', {3}),                # s=1 may loop forever
    ('E [ G "a" ]', {0, 1}),             # s=1's self-loop stays in a
    ('A [ G !"b" ]', set()),             # from 1 and 2, a path reaches 3 (in b)
    ('E [ "a" U s=2 ]', {0, 2}),
    ('A [ "a" U s=3 ]', {3}),
    ('E [ s<2 W s=3 ]', {0, 1, 3}),
    ('A [ s=3 R s!=2 ]', {1, 3}),
])
@pytest.mark.parametrize("exact", [False, True])
def test_ctl_on_an_mdp_quantifies_over_every_choice_and_branch(
        tmp_path: Path, formula: str, states: set[int], exact: bool) -> None:
    expected = " | ".join(f"s={s}" for s in sorted(states)) or "false"
    prop = f"filter(forall, ({formula}) <=> ({expected}))"
    args = ("--exact",) if exact else ()
    assert _values(tmp_path, _LTS, "--property", prop, *args) == [True]
    # The same graph as a DTMC (each state's choices as equally likely branches).
    chain = "dtmc\n" + _LTS.replace("[] s=0 -> (s'=1);\n[] s=0 -> (s'=2);",
                                     "[] s=0 -> 0.5:(s'=1) + 0.5:(s'=2);").replace(
        "[] s=1 -> (s'=1);\n[] s=1 -> (s'=3);", "[] s=1 -> 0.5:(s'=1) + 0.5:(s'=3);")
    assert _values(tmp_path, chain, "--property", prop, *args) == [True]


_COIN = """dtmc
module M
s:[0..2];
[] s=0 -> 1/3:(s'=1) + 2/3:(s'=2);
[] s>0 -> true;
endmodule
"""


def _exact_results(tmp_path: Path, model: str, *props: str) -> list[dict[str, object]]:
    path = tmp_path / "m.prism"
    path.write_text(model)
    args = [a for p in props for a in ("--property", p)]
    result = CliRunner().invoke(cli, ["prism", str(path), *args, "--exact", "--json"])
    assert result.exit_code == 0, result.stderr
    return list(json.loads(result.stdout)["results"])


@pytest.mark.parametrize("kind", ["dtmc", "mdp"])
def test_exact_filters_reduce_exact_values(tmp_path: Path, kind: str) -> None:
    # P [ F s=1 ] is 1/3, 1, 0 in s=0, 1, 2 (on the MDP: one choice per state, Pmax).
    model = _COIN if kind == "dtmc" else _COIN.replace("dtmc", "mdp")
    query = "P=? [ F s=1 ]" if kind == "dtmc" else "Pmax=? [ F s=1 ]"
    results = _exact_results(
        tmp_path, model, f"filter(sum, {query})", f"filter(avg, {query})",
        f"filter(min, {query}, s<2)", f"filter(forall, {query.replace('=?', '>=1/3')}, s<2)",
        f"filter(exists, {query.replace('=?', '>1/3')}, s=0)", "filter(count, s>0)")
    assert [r.get("exact") for r in results[:3]] == ["4/3", "4/9", "1/3"]
    assert [r["value"] for r in results[3:]] == [True, False, 2]
