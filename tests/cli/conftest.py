"""Fixtures the CLI tests share with the library tests they were grouped away from."""

from __future__ import annotations

# The sweep commands' tests use the sweep tests' mission config: one definition, two folders.
from tests.sweep.conftest import config

__all__ = ["config"]
