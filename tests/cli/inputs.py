"""Inputs the CLI tests share: the paper's baseline config and a tiny farm to check fast."""

from __future__ import annotations

from pathlib import Path

from tests.sweep.helpers import SMALL_FARM

REPO = Path(__file__).resolve().parents[2]
CASE1 = str(REPO / "configs" / "paper" / "case1.yaml")
EXAMPLES = REPO / "examples" / "phm"
#: ``--set`` options for a 3x3-turbine farm in 0.5 Ah units (~2,500 states).
SMALL = tuple(arg for item in SMALL_FARM for arg in ("--set", item))
#: ``--set`` options for a 3x2-turbine farm at 6 Ah for ``synthesize`` (1,431 MDP states).
SYNTHESIS = tuple(arg for item in ("farm.cols=3", "farm.rows=2", "farm.base=[0,0]",
                                   "battery.capacity_ah=6", "battery.max_recharges=8")
                  for arg in ("--set", item))
