"""Numbers beyond the engine's ints and doubles through ``veribattery prism``: a bad
number is one ``error:`` line naming where it was written, exit 2; a value beyond the
doubles is printed as what it is certified to be. (Configs: tests/config/test_bad_configs.py;
the values themselves: tests/checker/test_beyond_doubles.py.)"""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from tests.checker.test_beyond_doubles import BIG_REWARD
from veribattery.cli import cli

TINY = "dtmc\nmodule m\n  x : [0..1] init 0;\n  [] x=0 -> (x'=1);\nendmodule\n"
RANGE = ("is out of the int range -2^63..2^63-1 (ints are 64-bit here; PRISM's are 32-bit): "
         "use a smaller int, or a double such as 1e19")

#: A model with a constant for --const ranges.
CONST_P = ("dtmc\nconst double p;\nmodule m\n  x : [0..1] init 0;\n"
           "  [] x=0 -> p:(x'=1) + (1-p):(x'=0);\nendmodule\n")

CASES = [
    ("literal-in-property", TINY, ["--property", "P=? [ F x=9223372036854775808 ]"],
     f"<property>:1:11: 9223372036854775808 {RANGE}"),
    ("folded-in-exact-property", TINY, ["--property", "P=? [ F x=pow(2,62)*4 ]", "--exact"],
     f"<property>:1:11: 18446744073709551616 {RANGE}"),
    ("literal-in-label", TINY + 'label "a" = x=10000000000000000000000;\n',
     ["--property", "P=? [ F x=1 ]"], f"{{model}}:6:15: 10000000000000000000000 {RANGE}"),
    ("const-option", TINY.replace("dtmc", "dtmc\nconst int N;") + 'label "a" = x=N;\n',
     ["--const", "N=99999999999999999999", "--property", 'P=? [ F "a" ]'],
     f"constant 'N' (--const N=99999999999999999999): 99999999999999999999 {RANGE}"),
    # Python writes no int of more than 4,300 digits: these were tracebacks.
    ("literal-of-5000-digits", TINY.replace("dtmc", f"dtmc\nconst int N = {'9' * 5000};"),
     ["--property", "P=? [ F x=1 ]"], f"{{model}}:2:15: <5,000 digits> {RANGE}"),
    ("reward-index-of-5000-digits", TINY, ["--property", f"R{{{'9' * 5000}}}=? [ F x=1 ]"],
     f"<property>:1:2: <5,000 digits> {RANGE}"),
    # A range's numbers are read within a size rule (10^5000 is a traceback, 10^99999999
    # minutes of CPU), and a count of hundreds of digits is shown short.
    ("const-range-exponent", CONST_P, ["--const", "p=0:1e-5000:1", "--property", "P=? [ F x=1 ]"],
     "--const p=0:1e-5000:1: 1e-5000 is out of range: a number must be 0 or between 1e-400 "
     "and 1e400 in size, with at most 400 significant digits"),
    ("const-range-count", CONST_P, ["--const", "p=0:1e-400:1", "--property", "P=? [ F x=1 ]"],
     "--const p=0:1e-400:1 has about 10^400 values; at most 10,000 are checked"),
    ("variable-range", TINY.replace("[0..1]", "[0..10000000000000000000000]"),
     ["--property", "P=? [ F x=1 ]"],
     "{model}:3:3: variable 'x' has the range [0..10000000000000000000000], too wide for the "
     "64-bit ints states are stored in: its bounds must lie in -2^63..2^63-1, and it must "
     "hold fewer than 2^63 values"),
]


@pytest.mark.parametrize(("name", "model", "args", "message"), CASES, ids=[c[0] for c in CASES])
def test_one_line_and_exit_2(tmp_path: Path, name: str, model: str, args: list[str],
                             message: str) -> None:
    path = tmp_path / "m.pm"
    path.write_text(model)
    result = CliRunner().invoke(cli, ["prism", str(path), *args])
    assert result.exit_code == 2, result.output
    assert result.stdout == ""
    assert result.stderr == f"error: {message.replace('{model}', str(path))}\n"


def _run(tmp_path: Path, model: str, *args: str) -> tuple[int, str, str]:
    path = tmp_path / "m.pm"
    path.write_text(model)
    result = CliRunner().invoke(cli, ["prism", str(path), *args])
    return result.exit_code, result.stdout, result.stderr


def test_float_value_beyond_doubles_is_a_lower_bound(tmp_path: Path) -> None:
    code, out, err = _run(tmp_path, BIG_REWARD, "--property", "R=? [ F x=1 ]")
    assert code == 0
    assert "R=? [ F x=1 ]  ≥ 1.79769313486e+308\n" in out
    assert err.endswith("warning: R=? [ F x=1 ]: imprecise result, certified interval "
                        "[1.7976931348623157e+308, inf] is wider than 1e-9 relative / "
                        "1e-12 absolute\n")


def test_exact_value_beyond_doubles(tmp_path: Path) -> None:
    code, out, err = _run(tmp_path, BIG_REWARD, "--property", "R=? [ F x=1 ]", "--exact")
    assert code == 0
    assert "R=? [ F x=1 ]  ≈ 2e+308 (p/q: 309 digits)\n" in out
    assert err == ""  # the exact value is the answer: its float's enclosure is no warning


def test_exact_json_has_every_digit(tmp_path: Path) -> None:
    code, out, _ = _run(tmp_path, BIG_REWARD, "--property", "R=? [ C<=3 ]", "--exact",
                        "--format", "json")
    assert code == 0
    assert ('"value": "Infinity", "exact": "3' + "0" * 308 + '", "bounds": '
            '[1.7976931348623157e+308, "Infinity"], "precise": false') in out
