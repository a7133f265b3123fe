"""Storm's conditional formulas on an MDP, and multi(...) with --exact: refused in one line
(exit 2), never misread (its reward-bounded ones are checked:
tests/checker/mdp/test_reward_bounded_mdp.py)."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from veribattery.cli import cli
from veribattery.lang import parse_properties
from veribattery.lang.nodes import Conditional, ProbOp

MODEL = """mdp
module m
 s : [0..2] init 0;
 [a] s=0 -> 0.5:(s'=1) + 0.5:(s'=2);
 [b] s=0 -> (s'=2);
 [] s>0 -> true;
endmodule
rewards "r" true : 1; endrewards
"""


def test_a_conditional_keeps_its_direction() -> None:
    (prop,) = parse_properties('Pmin=? [ F s=1 || F s>0 ]').properties
    assert isinstance(prop.formula, ProbOp) and isinstance(prop.formula.path, Conditional)
    assert prop.formula.direction == "min"


_CONDITIONAL = "conditional probabilities (Storm's 'path || F condition') are not supported on MDPs"


@pytest.mark.parametrize(("formula", "exact", "says"), [
    ('Pmax=? [ F s=1 || F s>0 ]', False, _CONDITIONAL),
    ('Pmax=? [ F s=1 || F s>0 ]', True, _CONDITIONAL),
    ('multi(Pmax=? [ F s=1 ], P>=0.1 [ F s=2 ])', True, "multi(...) has no exact MDP kernel: "
                                                       "check it without --exact"),
])
def test_storm_path_formulas_are_refused_on_one_line(tmp_path: Path, formula: str, exact: bool,
                                                     says: str) -> None:
    model = tmp_path / "m.nm"
    model.write_text(MODEL)
    result = CliRunner().invoke(cli, ["prism", str(model), "--property", formula,
                                      *(["--exact"] if exact else [])])
    assert result.exit_code == 2
    (line,) = result.output.strip().splitlines()
    assert line.startswith("error: <property>:1:") and says in line
