"""Run ``veribattery`` as a user does: in a pseudo-terminal of a given width.

The standard library's :mod:`pty` is enough: the command gets a real terminal on
stdin, stdout and stderr (so rich draws its live progress and colours), with the
window size set, and what it writes is read back as the screen shows it.
"""

from __future__ import annotations

import fcntl
import os
import pty
import re
import select
import struct
import subprocess
import sys
import termios
import time
from dataclasses import dataclass
from pathlib import Path

#: CSI and OSC escape sequences (colours, cursor moves, erase-line, hide cursor).
_ESCAPES = re.compile(r"\x1b\[[0-?]*[ -/]*[@-~]|\x1b\][^\x07]*\x07|\x1b[=>]")
#: Longest a command may take here before the test fails (generous: CI is loaded).
TIMEOUT_S = 300


@dataclass(frozen=True)
class Screen:
    """What a terminal run left: its exit status and the text lines as displayed."""

    status: int
    lines: tuple[str, ...]
    #: Everything written, escapes removed, including what a transient spinner drew
    #: and then erased.
    drawn: str = ""

    @property
    def text(self) -> str:
        return "\n".join(self.lines)

    @property
    def widest(self) -> int:
        return max(map(len, self.lines), default=0)


def run_in_terminal(args: list[str], columns: int, cwd: Path,
                    env: dict[str, str] | None = None) -> Screen:
    """``veribattery ARGS`` in a *columns*-wide pseudo-terminal; the screen it leaves."""
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 50, columns, 0, 0))
    environment = {**os.environ, "TERM": "xterm-256color", **(env or {})}
    environment.pop("COLUMNS", None)
    environment.pop("LINES", None)
    process = subprocess.Popen(
        [sys.executable, "-c", "from veribattery.cli import main; main()", *args],
        stdin=slave, stdout=slave, stderr=slave, cwd=cwd, env=environment,
        start_new_session=True)
    os.close(slave)
    raw = _read_all(master, process)
    os.close(master)
    text = raw.decode("utf-8", "replace")
    return Screen(process.wait(), tuple(_displayed(text)), _ESCAPES.sub("", text))


def _read_all(master: int, process: subprocess.Popen[bytes]) -> bytes:
    chunks: list[bytes] = []
    deadline = time.monotonic() + TIMEOUT_S
    while time.monotonic() < deadline:
        ready, _, _ = select.select([master], [], [], 0.2)
        if ready:
            try:
                chunk = os.read(master, 65536)
            except OSError:  # EIO: the command closed the terminal
                break
            if not chunk:
                break
            chunks.append(chunk)
        elif process.poll() is not None:
            break
    else:
        process.kill()
        raise AssertionError(f"no exit within {TIMEOUT_S} s")
    return b"".join(chunks)


def _displayed(text: str) -> list[str]:
    """Lines as they stay on screen: an erase-line or carriage return redraws a line,
    and a cursor-up (rich's transient progress) moves back over lines it clears."""
    lines: list[str] = [""]
    for token in re.split(r"(\x1b\[[0-9]*A|\x1b\[2K|\r\n|\n|\r)", text):
        if token in ("\n", "\r\n"):
            lines.append("")
        elif token in ("\r", "\x1b[2K"):
            lines[-1] = ""
        elif token.startswith("\x1b[") and token.endswith("A"):
            count = int(token[2:-1] or 1)
            del lines[max(len(lines) - count, 1):]
            lines[-1] = ""
        else:
            lines[-1] += _ESCAPES.sub("", token)
    while lines and not lines[-1].strip():
        lines.pop()
    return [line.rstrip() for line in lines]
