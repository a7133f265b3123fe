"""The MDP builder and the MDP path of ``veribattery prism``: choices kept apart,
sizes as Storm counts them, values solved by hand."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from veribattery.cli import cli
from veribattery.explore.build.mdp import build_mdp
from veribattery.lang import flatten_model, parse_model

#: s0 offers [a] (to s1 or s2 by halves) and [b] (to s3); s1 returns; s2 and s3 deadlock.
CHOICE = """mdp
module m
  s : [0..3] init 0;
  [a] s=0 -> 0.5:(s'=1) + 0.5:(s'=2);
  [b] s=0 -> (s'=3);
  [] s=1 -> (s'=0);
endmodule
rewards "r"
  [a] true : 1;
  s=2 : 5;
endrewards
label "goal" = s=2;
"""

#: Two modules synchronising on [go], each with two enabled commands: four choices.
SYNC = """mdp
module p
  x : [0..2] init 0;
  [go] x=0 -> (x'=1);
  [go] x=0 -> (x'=2);
endmodule
module q
  y : [0..2] init 0;
  [go] y=0 -> 0.5:(y'=1) + 0.5:(y'=2);
  [go] y=0 -> (y'=2);
endmodule
"""

#: Three modules synchronising on [go] with several commands each, most combinations
#: enabled nowhere together (and a guard that is always true in the middle module): the
#: builder walks the combinations as a tree of prefixes and must keep exactly Storm's.
SYNC3 = """mdp
module p
  x : [0..3] init 0;
  [go] x=0 -> (x'=1);
  [go] x=1 -> (x'=2);
  [go] x=2 -> (x'=3);
  [go] x=3 -> (x'=0);
endmodule
module q
  y : [0..3] init 0;
  [go] y=x -> 0.5:(y'=mod(y+1,4)) + 0.5:(y'=y);
  [go] y!=x -> (y'=mod(y+2,4));
  [go] true -> (y'=0);
endmodule
module r
  z : [0..1] init 0;
  [go] z=0 & x<2 -> (z'=1);
  [go] z=1 -> (z'=0);
  [go] x=3 -> true;
endmodule
"""


def test_each_enabled_command_is_a_choice() -> None:
    built = build_mdp(flatten_model(parse_model(CHOICE)))
    assert built.states.tolist() == [[0], [1], [2], [3]]
    assert built.row_groups.tolist() == [0, 2, 3, 4, 5]
    assert built.transitions.toarray().tolist() == [
        [0, 0.5, 0.5, 0], [0, 0, 0, 1], [1, 0, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
    assert [built.actions[a] for a in built.choice_actions] == ["a", "b", "", "", ""]
    assert built.deadlocks == 2
    assert built.labels["deadlock"].tolist() == [False, False, True, True]
    (r,) = built.rewards
    assert r.state.tolist() == [0, 0, 5, 0]
    assert r.choice.tolist() == [1, 0, 0, 0, 0]  # [a] only; no reward on deadlock loops


def test_synchronised_combinations_are_choices() -> None:
    built = build_mdp(flatten_model(parse_model(SYNC)))
    assert built.row_groups[1] - built.row_groups[0] == 4
    first = built.transitions.toarray()[:4]
    assert sorted(np.count_nonzero(first, axis=1).tolist()) == [1, 1, 2, 2]


@pytest.mark.parametrize("source", [CHOICE, SYNC, SYNC3], ids=["choice", "sync", "sync3"])
def test_sizes_as_storm_counts_them(source: str, tmp_path: Path) -> None:
    stormpy = pytest.importorskip("stormpy")
    path = tmp_path / "m.nm"
    path.write_text(source)
    model = stormpy.build_model(stormpy.parse_prism_program(str(path)))
    built = build_mdp(flatten_model(parse_model(source)))
    assert built.states.shape[0] == model.nr_states
    assert built.transitions.shape[0] == model.nr_choices
    assert built.transitions.nnz == model.nr_transitions


@pytest.mark.parametrize(("prop", "expected"), [
    ('Pmax=? [ F "goal" ]', 1.0),  # [a] forever reaches s2 almost surely
    ('Pmin=? [ F "goal" ]', 0.0),  # [b] at once
    ('Pmax=? [ X s=3 ]', 1.0),
    ('Pmax=? [ F<=1 "goal" ]', 0.5),
    ('Pmax=? [ F<=3 "goal" ]', 0.75),
    ('Pmin=? [ G s!=2 ]', 0.0),  # = 1 - Pmax(F s=2)
    ('R{"r"}max=? [ C<=3 ]', 6.5),  # 1 + 0.5*(0 + 1) + 0.5*(5 + 5)
    ('Rmin=? [ F s=3 ]', 0.0),
    ('Rmax=? [ F s=3 ]', math.inf),  # [a] may never reach s3
    ('R{"r"}max=? [ I=1 ]', 2.5),
    ('Tmin=? [ F s=2 ]', 3.0),  # [a]: E = 1 + 0.5 (1 + E), Storm's expected steps
    ('Tmax=? [ F s=2 ]', math.inf),  # [b] never reaches s2
    ('Pmax=? [ F^{steps<=3} "goal" ]', 0.75),  # Storm's spelling of F<=3
    ('Pmax>=0.9 [ F "goal" ]', True),
    ('P>=0.9 [ F "goal" ]', False),  # every strategy: Pmin = 0
])
def test_prism_values(prop: str, expected: object, tmp_path: Path) -> None:
    model = tmp_path / "m.nm"
    model.write_text(CHOICE)
    result = CliRunner().invoke(cli, ["prism", str(model), "--property", prop, "--json"])
    assert result.exit_code == 0, result.output
    document = json.loads(result.stdout)
    assert document["model"]["choices"] == 5
    value = document["results"][0]["value"]
    if isinstance(expected, bool):
        assert value is expected
    elif math.isinf(float(expected)):  # type: ignore[arg-type]
        assert value in ("Infinity", math.inf)
    else:
        assert value == pytest.approx(expected, abs=1e-9)


@pytest.mark.parametrize(("prop", "message"), [
    ('P=? [ F "goal" ]', "P=? on an MDP has no single value"),
    ('R=? [ F s=3 ]', "R=? on an MDP has no single value"),
    ('T=? [ F s=2 ]', "T=? on an MDP has no single value: use Tmin=? or Tmax=?"),
    ('multi(Pmax=? [ F s=2 ], Pmax=? [ F s=3 ])', "Pareto queries"),
])
def test_refused_with_one_line(prop: str, message: str, tmp_path: Path) -> None:
    model = tmp_path / "m.nm"
    model.write_text(CHOICE)
    result = CliRunner().invoke(cli, ["prism", str(model), "--property", prop, "--json"])
    assert result.exit_code == 2
    assert message in result.output


@pytest.mark.parametrize("exact", [False, True])
@pytest.mark.parametrize("prop", ['P=? [ F "goal" ]', 'filter(max, R=? [ F s=3 ])'])
def test_an_operator_without_objective_is_refused_before_the_build(
        prop: str, exact: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    # A large MDP would be explored in full before the refusal otherwise.
    from veribattery.errors import CheckError
    from veribattery.pipeline import check_prism_file

    def no_build(*_: object, **__: object) -> None:
        raise AssertionError("the MDP was built")

    monkeypatch.setattr("veribattery.pipeline.mdp.build_mdp", no_build)
    monkeypatch.setattr("veribattery.explore.exact.mdp.build_exact_mdp", no_build,
                        raising=False)
    with pytest.raises(CheckError, match="on an MDP has no single value"):
        check_prism_file(CHOICE, props_source=prop, exact=exact)


def test_exact_checks_mdps(tmp_path: Path) -> None:
    """Repeating [a] reaches s=2 surely, after 2 [a] steps on average; [b] never does."""
    model = tmp_path / "m.nm"
    model.write_text(CHOICE)
    props = ['Pmax=? [ F s=2 ]', 'Pmin=? [ F s=2 ]', 'Rmin=? [ F s=2 ]', 'Rmax=? [ F s=2 ]',
             'Tmin=? [ F s=2 ]', 'Tmax=? [ F s=2 ]']
    args = [a for p in props for a in ("--property", p)]
    result = CliRunner().invoke(cli, ["prism", str(model), *args, "--exact", "--json"])
    assert result.exit_code == 0, result.output
    exact = [r["exact"] for r in json.loads(result.stdout)["results"]]
    assert exact == ["1", "0", "2", "Infinity", "3", "Infinity"]


#: x up to 120: its square (14,400) does not fit the int8 the state table is kept in.
WIDE_SQUARES = """mdp
module m
  x : [0..120] init 0;
  [inc] x<120 -> (x'=x+1);
  [jump] x<100 -> 0.5:(x'=120) + 0.5:(x'=x);
endmodule
rewards "sq"
  true : x*x;
endrewards
label "far" = x*x >= 14400;
"""


def test_state_table_is_narrow_and_read_wide() -> None:
    built = build_mdp(flatten_model(parse_model(WIDE_SQUARES)))
    assert built.states.dtype == np.int8
    wide = built.wide()
    assert wide.states.dtype == np.int64
    assert np.array_equal(wide.states, built.states)
    x = wide.states[:, 0]
    assert sorted(x.tolist()) == list(range(121))
    # Labels and rewards are evaluated on int64 rows: 120 * 120 in int8 would be 64.
    assert np.flatnonzero(built.labels["far"]).tolist() == np.flatnonzero(x == 120).tolist()
    assert np.array_equal(built.rewards[0].state, (x * x).astype(np.float64))


@pytest.mark.parametrize(("prop", "expected"), [
    ("Pmax=? [ X x*x>=14400 ]", 0.5),  # [jump] from x=0
    ("Pmin=? [ X x*x>=14400 ]", 0.0),  # [inc]
    ('R{"sq"}max=? [ I=1 ]', 0.5 * 14400 + 0.5 * 0),
])
def test_properties_read_the_narrow_table_wide(prop: str, expected: float,
                                                tmp_path: Path) -> None:
    model = tmp_path / "m.nm"
    model.write_text(WIDE_SQUARES)
    for exact in ([], ["--exact"]):
        result = CliRunner().invoke(cli, ["prism", str(model), "--property", prop, "--json",
                                          *exact])
        assert result.exit_code == 0, result.output
        assert json.loads(result.stdout)["results"][0]["value"] == pytest.approx(expected)
