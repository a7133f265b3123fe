"""Answers PRISM prints that the issue counts as bad input: an infeasible numerical
``multi(...)`` (NaN) and an ``Rmin [ F phi ]`` whose target no strategy reaches
(Infinity). The value is shown as PRISM shows it, then one ``error:`` line naming the
property's file, line and column; exit status 2; no strategy file is written."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from click.testing import CliRunner

from veribattery.cli import cli

# From s=0: [a] reaches s=1 or s=2 (1/2 each), [b] reaches s=2; s=3 is never reached.
MODEL = """mdp
module m
 s : [0..3] init 0;
 [a] s=0 -> 0.5:(s'=1) + 0.5:(s'=2);
 [b] s=0 -> (s'=2);
 [] s=1 | s=2 -> true;
 [] s=3 -> (s'=0);
endmodule
rewards "r" true : 1; endrewards
"""

PROPS = """// line 1 is a comment
Rmin=? [ F s=1 ]
Rmin=? [ F s=3 ]
multi(Pmax=? [ F s=1 ], P>=0.6 [ F s=1 ])
R>=2 [ F s=3 ]
"""


def _run(tmp_path: Path, *args: str) -> tuple[int, str, str]:
    model, props = tmp_path / "m.nm", tmp_path / "m.props"
    model.write_text(MODEL)
    props.write_text(PROPS)
    result = CliRunner().invoke(cli, ["prism", str(model), "--props", str(props), *args])
    return result.exit_code, result.stdout, result.stderr


def test_a_reachable_target_with_infinite_rmin_is_an_answer(tmp_path: Path) -> None:
    # s=1 is reached with probability 1/2 at most: Rmin is Infinity, and that is the answer
    code, out, err = _run(tmp_path, "--property", "1", "--json")
    assert code == 0 and err == ""
    assert json.loads(out)["results"][0]["value"] == "Infinity"


@pytest.mark.parametrize(("index", "line", "shown", "says"), [
    ("2", 3, "Infinity", "no strategy reaches the target (s = 3) from the initial state"),
    ("4", 5, True, "no strategy reaches the target (s = 3) from the initial state"),
    ("3", 4, "NaN", "undefined (NaN): multi(...) has no strategy that meets its bounded "
                    "objectives"),
])
def test_ill_posed_properties_show_the_value_then_exit_2(tmp_path: Path, index: str, line: int,
                                                          shown: object, says: str) -> None:
    code, out, err = _run(tmp_path, "--property", index, "--json")
    assert code == 2
    value = json.loads(out)["results"][0]["value"]
    assert value == shown or (shown == "NaN" and math.isnan(float(value)))
    (message,) = err.strip().splitlines()
    assert message.startswith(f"error: {tmp_path / 'm.props'}:{line}:1: ")
    assert says in message


def test_one_error_line_per_ill_posed_property_and_no_strategy_file(tmp_path: Path) -> None:
    strategy = tmp_path / "s.txt"
    code, out, err = _run(tmp_path, "--export-strategy", str(strategy))
    assert code == 2
    assert "Rmin=? [ F s=1 ]" in out  # every result is still shown
    assert [m.split(":")[2] for m in err.strip().splitlines()] == ["3", "4", "5"]
    assert not strategy.exists()


def test_exact_mode_reports_an_unreachable_rmin_target_too(tmp_path: Path) -> None:
    code, out, err = _run(tmp_path, "--property", "2", "--exact", "--json")
    assert code == 2 and json.loads(out)["results"][0]["value"] == "Infinity"
    assert "no strategy reaches the target (s = 3)" in err


# ---------------------------------------------------------------------------
# Rewards refused: negative ones (at the property), infinite or NaN ones
# (at the model's reward item), in every kind of reward property
# ---------------------------------------------------------------------------

NEGATIVE = """mdp
module m
  s : [0..1] init 0;
  [a] s=0 -> (s'=1);
  [a] s=1 -> (s'=1);
endmodule
rewards "r"
  s=0 : -1;
endrewards
"""


@pytest.mark.parametrize(("prop", "mode"), [
    ('Rmin=? [ F s=1 ]', ()), ('Rmax=? [ C ]', ()), ('Rmax=? [ C<=3 ]', ()),
    ('Rmin=? [ I=0 ]', ()), ('Rmin=? [ F s=1 ]', ("--exact",)),
    ('multi(R{"r"}max=? [ C ], P>=0.5 [ F s=1 ])', ()),
    ('Pmax=? [ F{"r"}<=2 s=1 ]', ()),
])
def test_negative_rewards_are_one_line(prop: str, mode: tuple[str, ...],
                                       tmp_path: Path) -> None:
    model = tmp_path / "m.nm"
    model.write_text(NEGATIVE)
    result = CliRunner().invoke(cli, ["prism", str(model), "--property", prop, *mode])
    assert result.exit_code == 2, result.output
    (line,) = result.output.strip().splitlines()
    assert line.startswith("error: <property>:1:")
    assert line.endswith('the reward structure "r" has negative rewards: veribattery checks '
                         "nonnegative rewards only")


@pytest.mark.parametrize("value", ["0/0", "1/0"])
def test_a_reward_that_is_not_finite_names_the_model_line(value: str, tmp_path: Path) -> None:
    model = tmp_path / "m.nm"
    model.write_text(NEGATIVE.replace("s=0 : -1;", f"[a] true : {value};"))
    result = CliRunner().invoke(cli, ["prism", str(model), "--property",
                                      'multi(R{"r"}max=? [ C ])'])
    assert result.exit_code == 2, result.output
    (line,) = result.output.strip().splitlines()
    assert line.startswith(f"error: {model}:8:14: reward structure \"r\" is not finite at "
                           "state (s=0): ")
