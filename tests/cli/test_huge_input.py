"""Input that ran for minutes: a number with an exponent of millions (``Fraction`` built
10^99999999 digit by digit) and a YAML alias bomb (nine aliases of nine aliases ... walked
as 9^9 values). Each is refused at once, in one line, exit 2.

The CLI runs in a process of its own, with a time limit: a hang fails the test instead
of stopping the suite.
"""

from __future__ import annotations

import itertools
import subprocess
import sys
from pathlib import Path

import pytest

#: Far more than the refusal takes (well under a second, plus the interpreter's start).
LIMIT_S = 60
TINY = "farm: {cols: 2, rows: 2, base: [0, 0]}\nbattery: {capacity_ah: 6, max_recharges: 5}\n"
#: Nine levels of nine aliases: 9^9 values from nine lines (level g passes a million).
_LEVELS = "abcdefghi"
BOMB = f"a: &a [{', '.join(['x'] * 9)}]\n" + "".join(
    f"{name}: &{name} [{', '.join([f'*{below}'] * 9)}]\n"
    for below, name in itertools.pairwise(_LEVELS))
SIZE_RULE = ("is out of range: a number must be 0 or between 1e-400 and 1e400 in size, "
             "with at most 400 significant digits")

CASES = [
    ("capacity", ["check", "{config}", "--set", "battery.capacity_ah=1e99999999"],
     f"error: --set battery.capacity_ah: 1e99999999 {SIZE_RULE}"),
    ("probability", ["check", "{config}", "--set", "environment.p_wsp_c=1e-1000000"],
     f"error: --set environment.p_wsp_c: 1e-1000000 {SIZE_RULE}"),
    ("requirement", ["check", "{config}", "--set", "requirements=['p_success > 1e-99999999']"],
     f"error: --set requirements[0]: bound 1e-99999999 {SIZE_RULE}"),
    ("vary-stop", ["sweep", "{config}", "-j", "1", "--vary", "farm.cols=2:1e99999999:1"],
     f"error: --vary 'farm.cols=2:1e99999999:1': 1e99999999 {SIZE_RULE}"),
    ("alias-bomb", ["check", "{bomb}"],
     "error: {bomb}:7:4: YAML aliases expand 'g' to more than 1,000,000 values: write the "
     "values out, or use fewer aliases"),
]


@pytest.mark.parametrize(("args", "expected"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_refused_at_once(tmp_path: Path, args: list[str], expected: str) -> None:
    files = {"config": tmp_path / "tiny.yaml", "bomb": tmp_path / "bomb.yaml"}
    files["config"].write_text(TINY)
    files["bomb"].write_text(BOMB)
    argv = [arg.format(**files) for arg in args]
    done = subprocess.run([sys.executable, "-c", "from veribattery.cli import main; main()",
                           *argv], capture_output=True, text=True, timeout=LIMIT_S,
                          cwd=tmp_path, check=False)
    assert done.returncode == 2, done.stderr
    assert done.stdout == ""
    assert done.stderr == expected.format(**files) + "\n"
