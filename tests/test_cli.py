"""Moved: the CLI tests live in tests/cli/ (this one in tests/cli/test_contracts.py).

Kept only for ``from tests.test_cli import DIE`` in tests/cli/test_terminal.py; delete
this file once that import reads ``from tests.cli.test_contracts import DIE``.
"""

from __future__ import annotations

from tests.cli.test_contracts import DIE

__all__ = ["DIE"]
