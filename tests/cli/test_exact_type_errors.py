"""Type errors in properties are errors with --exact as without it.

``--exact`` replaces each closed sub-expression by the literal of its exact value before
the properties are resolved; that used to happen before their types were checked, so
``true + 1`` was answered 2, ``!3`` false (0), and ``- true`` ended in numpy's TypeError
traceback. Each is now the type error the float engine reports (exit 2, one line).
"""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from veribattery.cli import cli

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


@pytest.mark.parametrize("model", ["prism/dice.pm", "mdp/robot.nm"])
@pytest.mark.parametrize(("formula", "says"), [
    ("true + 1", "<property>:1:1: type error: operator '+' cannot be applied to bool and int"),
    ("!3", "<property>:1:1: type error: '!' needs a bool, not int"),
    ("- true", "<property>:1:1: type error: unary '-' needs a number, not bool"),
    ("2 * (1 > true)", "<property>:1:6: type error: operator '>' cannot be applied to int and "
                       "bool"),
])
@pytest.mark.parametrize("exact", [False, True])
def test_a_closed_property_of_the_wrong_type_is_a_type_error(
        model: str, formula: str, says: str, exact: bool) -> None:
    result = CliRunner().invoke(cli, ["prism", str(EXAMPLES / model), "--property", formula,
                                      *(["--exact"] if exact else [])])
    assert result.exit_code == 2
    assert result.output.strip().splitlines() == [f"error: {says}"]
