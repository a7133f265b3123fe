"""What every refused CLI run looks like, for the tests that check its one line."""

from __future__ import annotations

from click.testing import Result


def one_error(result: Result) -> str:
    """The one ``error:`` line of a bad-input run (exit 2, nothing on stdout)."""
    assert result.exit_code == 2, result.output
    assert result.stdout == ""
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    return lines[0]
