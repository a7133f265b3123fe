"""Dim notes and timings off a terminal: echoed as is, exactly what rich would print."""

from __future__ import annotations

import io

import pytest
from rich.console import Console

from veribattery.cli.explain import FAILURE_NOTES
from veribattery.cli.output import EXACT_NOTE, print_dim
from veribattery.cli.tables import fit_text

TEXTS = [
    "Time: parse 0.001s, build 0.002s, check 0.015s",
    fit_text(EXACT_NOTE, 80),
    *(fit_text(note, 80) for _, note in FAILURE_NOTES),
    fit_text("† conditional: the expectation given the condition after || (e.g. given "
             "success)", 40),
]


@pytest.mark.parametrize("text", TEXTS)
def test_a_dim_line_off_a_terminal_is_what_rich_prints(
    text: str, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    for name in ("FORCE_TERMINAL", "TTY_COMPATIBLE", "FORCE_COLOR"):
        monkeypatch.delenv(name, raising=False)
    # The CLI's stdout console off a terminal (cli/output.py: soft wrap in pipes).
    rich = io.StringIO()
    Console(file=rich, highlight=False, emoji=False, soft_wrap=True).print(
        text, style="dim", markup=False)
    print_dim(text)
    echoed = capsys.readouterr().out
    assert echoed == rich.getvalue() == text + "\n"
