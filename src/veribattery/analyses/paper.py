"""The seed paper's published figures, kept as data with their source."""

from __future__ import annotations

from dataclasses import dataclass

#: Zhao et al., "Towards Integrating Formal Verification of Autonomous Robots with
#: Battery Prognostics and Health Management", SEFM 2019, Table 3 (11 Ah new battery).
SOURCE = "Zhao et al., SEFM 2019, Table 3"


@dataclass(frozen=True, slots=True)
class Table3Row:
    """One row of the paper's Table 3: the case's parameters and PRISM's results."""

    case: str
    config: str
    safe_t: float
    p_wsp_c: float
    states: int
    transitions: int
    p_success: float
    exp_mission_time: float
    exp_recharges: float


TABLE3: tuple[Table3Row, ...] = (
    Table3Row("#1", "configs/paper/case1.yaml", 0.30, 0.1, 108_688, 163_076, 1.0, 4700.20, 42.65),
    Table3Row("#2", "configs/paper/case2.yaml", 0.25, 0.1, 117_765, 177_278, 0.91, 3885.95, 34.59),
    Table3Row("#3", "configs/paper/case3.yaml", 0.30, 0.3, 108_688, 163_076, 1.0, 7482.86, 72.16),
    Table3Row("#4", "configs/paper/case4.yaml", 0.25, 0.3, 117_765, 177_278, 0.89, 5621.66, 53.07),
)
