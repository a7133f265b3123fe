"""The sweep fixtures."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from tests.sweep.helpers import SMALL_FARM, four_axes
from veribattery.sweep import run_sweep


@pytest.fixture(scope="session")
def serial_frame() -> pd.DataFrame:
    """The four-point sweep checked in this process: the reference for every executor."""
    return run_sweep("", four_axes(), SMALL_FARM)


@pytest.fixture
def config(tmp_path: Path) -> str:
    """A mission config file (the baseline with its safety threshold written out)."""
    path = tmp_path / "mission.yaml"
    path.write_text("strategy:\n  safe_t: 0.3\n")
    return str(path)
