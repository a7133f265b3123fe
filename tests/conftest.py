"""Shared test fixtures: where the peer suites live, and the CLI runner."""

from __future__ import annotations

import functools
import importlib.util
import os
from pathlib import Path
from types import ModuleType

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("VERIBATTERY_SHARED", REPO.parent / "shared")).resolve()
PEER_TESTS = SHARED / "peer-tests"


def require_shared() -> Path:
    """The peer-tests folder, or a visible skip when ../shared is not beside the repo."""
    if not PEER_TESTS.is_dir():
        pytest.skip(f"peer suites not found at {PEER_TESTS} (../shared is absent)")
    return PEER_TESTS


@functools.cache
def peer_harness() -> ModuleType:
    """The suites' own harness (prism_suite.py), loaded once as a module."""
    path = require_shared() / "prism_suite.py"
    spec = importlib.util.spec_from_file_location("prism_suite", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(autouse=True)
def _piped_width(monkeypatch: pytest.MonkeyPatch) -> None:
    """CLI output laid out as when piped with no ``$COLUMNS``: 80 columns, whatever the
    terminal that runs the tests (the pseudo-terminal tests set their own width)."""
    monkeypatch.delenv("COLUMNS", raising=False)
