"""The sweep fixtures."""

from __future__ import annotations

import pandas as pd
import pytest

from tests.sweep.helpers import SMALL_FARM, four_axes
from veribattery.sweep import run_sweep


@pytest.fixture(scope="session")
def serial_frame() -> pd.DataFrame:
    """The four-point sweep checked in this process: the reference for every executor."""
    return run_sweep("", four_axes(), SMALL_FARM)
