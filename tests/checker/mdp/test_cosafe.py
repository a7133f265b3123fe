"""Co-safe reward paths on MDPs, solved by hand: ``R [ a U b ]`` and ``R [ X b ]``."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from click.testing import CliRunner

from veribattery.cli import cli
from veribattery.lang import parse_model, parse_properties
from veribattery.pipeline.mdp import check_mdp_model

# s=0: a (reward 1) to s=1 or s=2 (1/2 each); b (reward 4) to s=3.
# s=1 (state reward 2) and s=2 (free) move to s=3, which absorbs.
#   R [ F s=3 ]:       a costs 1 + 1/2 * 2 = 2, b costs 4.
#   R [ s!=2 U s=3 ]:  a fails with probability 1/2 (s=2 is neither): infinite; b 4.
#   R [ X s=3 ]:       only b surely lands in s=3 at once: 4; a is infinite.
MODEL = """mdp
module m
  s : [0..3] init 0;
  [a] s=0 -> 0.5:(s'=1) + 0.5:(s'=2);
  [b] s=0 -> (s'=3);
  [] s=1 | s=2 -> (s'=3);
  [] s=3 -> true;
endmodule
rewards "r"
  [a] true : 1;
  [b] true : 4;
  s=1 : 2;
endrewards
"""


@pytest.mark.parametrize(("formula", "expected"), [
    ("Rmin=? [ F s=3 ]", 2.0),
    ("Rmax=? [ F s=3 ]", 4.0),
    ("Rmin=? [ s!=2 U s=3 ]", 4.0),
    ("Rmax=? [ s!=2 U s=3 ]", math.inf),
    ("Rmin=? [ true U s=3 ]", 2.0),
    ("Rmin=? [ s=0 U s=3 ]", 4.0),  # s=1 and s=2 both fail
    ("Rmin=? [ X s=3 ]", 4.0),
    ("Rmax=? [ X s=3 ]", math.inf),
    ("filter(state, Rmin=? [ X s=3 ], s=1)", 2.0),
    ("filter(state, Rmin=? [ s!=2 U s=3 ], s=2)", math.inf),  # a trap from the start
    ("filter(state, Rmax=? [ s!=2 U s=3 ], s=3)", 0.0),  # the target itself
])
def test_cosafe_rewards(formula: str, expected: float) -> None:
    props = parse_properties(formula + "\n", name="t.props")
    run = check_mdp_model(parse_model(MODEL, name="t.prism"), props.properties,
                          props_file=props)
    assert run.results[0].value == pytest.approx(expected, abs=1e-9)


@pytest.mark.parametrize(("formula", "expected"), [
    ("Rmin=? [ s!=2 U s=3 ]", "4"),
    ("Rmax=? [ s!=2 U s=3 ]", "Infinity"),
    ("Rmin=? [ s=0 U s=3 ]", "4"),
    ("Rmin=? [ true U s=3 ]", "2"),
    ("filter(state, Rmin=? [ s!=2 U s=3 ], s=2)", "Infinity"),
    ("filter(state, Rmax=? [ s!=2 U s=3 ], s=1)", "2"),
])
def test_cosafe_until_in_exact_arithmetic(tmp_path: Path, formula: str, expected: str) -> None:
    # (with --exact it was "this reward formula has no exact MDP kernel": PRISM's
    # mdps/rewards/cosafe/robot.nm, entry 9)
    model = tmp_path / "m.nm"
    model.write_text(MODEL)
    result = CliRunner().invoke(cli, ["prism", str(model), "--property", formula, "--exact",
                                      "--json"])
    assert result.exit_code == 0, result.stderr
    found = json.loads(result.stdout)["results"][0]
    assert found.get("exact", found["value"]) == expected
