"""Shared test fixtures: where the peer suites live, and the CLI runner."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("VERIBATTERY_SHARED", REPO.parent / "shared")).resolve()
PEER_TESTS = SHARED / "peer-tests"


def require_shared() -> Path:
    """The peer-tests folder, or a visible skip when ../shared is not beside the repo."""
    if not PEER_TESTS.is_dir():
        pytest.skip(f"peer suites not found at {PEER_TESTS} (../shared is absent)")
    return PEER_TESTS
