"""``veribattery`` run as a user runs it, in a fresh process, after a few lines of
Python that patch the library (a machine short of memory, say), for the failures a
test cannot otherwise bring about."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path


def run_patched(prelude: str, args: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    """``veribattery ARGS`` in *cwd*, after running *prelude*; its output captured."""
    code = f"{prelude}\nfrom veribattery.cli import main\nmain()\n"
    return subprocess.run([sys.executable, "-c", code, *args], cwd=cwd, capture_output=True,
                          text=True, timeout=120)


def last_error_line(done: subprocess.CompletedProcess[str]) -> str:
    """The last line on stderr of a run that must end with status 2 and no traceback."""
    assert done.returncode == 2, done.stderr
    assert "Traceback" not in done.stderr, done.stderr
    return done.stderr.strip().splitlines()[-1]
