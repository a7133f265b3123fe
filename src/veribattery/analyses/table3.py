"""Reproduce the seed paper's Table 3: four strategy/environment cases at 11 Ah."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from veribattery.analyses.paper import TABLE3, Table3Row
from veribattery.config import load_config
from veribattery.mission import MissionReport, check_mission

QUANTITIES = ("p_success", "exp_mission_time", "exp_recharges")


@dataclass(frozen=True, slots=True)
class Table3Comparison:
    """One case: the paper's row beside veribattery's report."""

    paper: Table3Row
    report: MissionReport

    def ours(self, quantity: str) -> float:
        """veribattery's value of *quantity* for this case."""
        return float(self.report.values[quantity])

    def relative_difference(self, quantity: str) -> float:
        """(ours - paper) / paper."""
        paper = float(getattr(self.paper, quantity))
        return (self.ours(quantity) - paper) / paper

    def lines(self) -> list[tuple[str, str, str, str]]:
        """Rows of (quantity, paper, ours, relative difference) as display text."""
        dtmc = self.report.run.dtmc
        rows = [
            ("states", f"{self.paper.states:,}", f"{dtmc.num_states:,}", "—"),
            ("transitions", f"{self.paper.transitions:,}", f"{dtmc.num_transitions:,}", "—"),
        ]
        for quantity in QUANTITIES:
            rows.append((quantity, f"{getattr(self.paper, quantity):g}",
                         f"{self.ours(quantity):.6g}",
                         f"{self.relative_difference(quantity):+.2%}"))
        return rows

    def as_dict(self) -> dict[str, object]:
        """JSON-ready form."""
        return {
            "case": self.paper.case,
            "safe_t": self.paper.safe_t,
            "p_wsp_c": self.paper.p_wsp_c,
            "states": self.report.run.dtmc.num_states,
            "transitions": self.report.run.dtmc.num_transitions,
            "paper": {q: getattr(self.paper, q) for q in QUANTITIES},
            "ours": {q: self.ours(q) for q in QUANTITIES},
            "relative_difference": {q: self.relative_difference(q) for q in QUANTITIES},
        }


def case_overrides(row: Table3Row) -> tuple[str, ...]:
    """The ``--set`` overrides that turn the baseline into *row*'s case."""
    return (f"strategy.safe_t={row.safe_t}", f"environment.p_wsp_c={row.p_wsp_c}")


def reproduce_table3(progress: Callable[[str], None] | None = None) -> list[Table3Comparison]:
    """Check the four cases of Table 3 (11 Ah, the paper's defaults otherwise)."""
    comparisons = []
    for row in TABLE3:
        if progress is not None:
            progress(f"checking case {row.case} (safe_t={row.safe_t}, p_wsp_c={row.p_wsp_c})…")
        report = check_mission(load_config("", case_overrides(row)))
        comparisons.append(Table3Comparison(row, report))
    return comparisons
