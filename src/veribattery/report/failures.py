"""Where failures come from: ``explain``'s exact breakdown and most probable paths, told.

The breakdown and the paths are those of ``veribattery explain`` (the same call,
:func:`~veribattery.analyses.explain.explain_target` with the mission view and the
default groupings); this module adds the farm cells for the heat map, each path's
mission time (the model's ``mt`` reward along it) and the steps in words.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence

import numpy as np

from veribattery.analyses.explain import Explanation, Grouping, explain_target
from veribattery.analyses.folding import Fold
from veribattery.analyses.mission_view import DEFAULT_GROUPINGS, MissionView
from veribattery.analyses.paths import ProbablePath
from veribattery.report.data import FailurePath, Failures, GroupRow, GroupTable, PathStep

__all__ = ["TITLES", "explain_failures", "failures_of"]

#: Headings of the default groupings.
TITLES = {
    ("k", "cell"): "by route cell",
    ("state", "action"): "by drone state and action",
    ("wind",): "by wind",
    ("level",): "by voltage level",
    ("recharges",): "by recharges so far",
}

#: Each action in words; ``{cell}``, ``{next}`` and ``{of}`` are filled from the step.
_EVENTS = {
    "takeoff": "takes off from the base",
    "fly": "flies to cell {cell}",
    "inspect": "inspects turbine {next} of {of} at cell {cell}",
    "next": "moves on to the next cell",
    "back": "flies back to the base",
    "backnext": "flies back to the base, cell {cell} done",
    "land": "lands at the base",
    "recharge": "recharges (the battery fades a little)",
    "wait": "waits at the base for low wind",
    "finish": "finishes the mission",
    "infeasible": "cannot start: even a full battery cannot do the next inspection",
}


def explain_failures(view: MissionView, top: int) -> Explanation:
    """``explain``'s analysis of the mission *view* shows: the default groupings, *top* paths."""
    dtmc = view.dtmc
    return explain_target(dtmc, dtmc.labels["failure"], name="failure", describe=view.columns,
                          by=DEFAULT_GROUPINGS, top=top)


def failures_of(view: MissionView, explanation: Explanation) -> Failures:
    """The report's view of *explanation*: tables with shares, cells, paths in words."""
    total = explanation.probability
    tables = tuple(_table(g, total) for g in explanation.groupings)
    minutes = np.asarray(view.dtmc.reward("mt").total, dtype=np.float64)
    paths = tuple(_path(rank, p, view.steps(p.states), minutes)
                  for rank, p in enumerate(explanation.paths, 1))
    cells, after = _by_cell(explanation.groupings)
    return Failures(total, int(explanation.inflow.states.size), tables, cells, after, paths)


def _table(grouping: Grouping, total: float) -> GroupTable:
    rows = tuple(GroupRow(values, p, p / total if total > 0 else 0.0)
                 for values, p in grouping.groups)
    return GroupTable(grouping.keys, TITLES.get(grouping.keys, "by " + ", ".join(grouping.keys)),
                      rows)


def _by_cell(groupings: Sequence[Grouping]
             ) -> tuple[tuple[tuple[tuple[int, int], float], ...], float]:
    """P(failure) per farm cell, and after the last cell (route cell ``done``), from the
    grouping that names cells (none: nothing)."""
    grouping = next((g for g in groupings if "cell" in g.keys), None)
    if grouping is None:
        return (), 0.0
    at = grouping.keys.index("cell")
    sums: dict[tuple[int, int], float] = {}
    after = 0.0
    for values, p in grouping.groups:
        cell = str(values[at])
        if cell.startswith("["):
            x, y = (int(v) for v in cell.strip("[]").split(","))
            sums[(x, y)] = sums.get((x, y), 0.0) + p
        else:
            after += p
    return tuple(sorted(sums.items())), after


def _path(rank: int, path: ProbablePath, rows: Sequence[Mapping[str, object]],
          minutes_per_step: np.ndarray) -> FailurePath:
    """One path: its steps with mission time and words, the final sortie, the story."""
    spent = np.concatenate([[0.0], np.cumsum(minutes_per_step[path.states[:-1]])])
    steps = tuple(_step(row, float(t)) for row, t in zip(rows, spent, strict=True))
    actions = [s.action for s in steps]
    start = max((i for i, a in enumerate(actions) if a == "recharge"), default=-1) + 1
    folded = ""
    if start > 0:
        counts = tuple(Counter(actions[:start]).most_common())
        folded = Fold(0, start - 1, counts).describe("recharge").strip("… ")
    return FailurePath(rank, path.probability, path.probability_text, steps, start, folded,
                       _story(steps, start))


def _step(row: Mapping[str, object], minutes: float) -> PathStep:
    action = str(row["action"])
    return PathStep(
        step=int(str(row["step"])), minutes=minutes, action=action, state=str(row["state"]),
        cell=str(row["cell"]), turbines=str(row["turbines"]), wind=str(row["wind"]),
        charge_ah=float(str(row["charge_ah"])), soc=float(str(row["soc"])),
        level=str(row["level"]), rc=int(str(row["rc"])), event=_event(action, row),
    )


def _event(action: str, row: Mapping[str, object]) -> str:
    """The step in words (empty for the last state, where the path ends)."""
    if not action:
        return "the mission has failed"
    if action.startswith("oob"):
        cut = action.removeprefix("oob (").removesuffix(")")
        if cut == "recharge cap":
            return "the recharge cap is reached with cells left: the mission is cut"
        return f"runs out of battery: cannot pay for the {_noun(cut)}"
    done, _, of = str(row["turbines"]).partition("/")
    text = _EVENTS.get(action, action)
    return text.format(cell=row["cell"], next=int(done) + 1, of=of)


def _noun(action: str) -> str:
    """An intended action as the thing the battery must pay for."""
    return {"takeoff": "take-off", "fly": "flight out", "land": "landing",
            "inspect": "inspection", "back": "flight back", "next": "flight to the next cell",
            "backnext": "flight back"}.get(action, action)


def _story(steps: Sequence[PathStep], start: int) -> str:
    """What happens on the path, as the paper's Fig. 7 tells it: the trips before, the
    final sortie's inspections and wind, and the step that runs out."""
    if len(steps) < 2:
        return "The mission fails at once."
    last = steps[-2]
    trips = sum(1 for s in steps[:start] if s.action == "recharge")
    before = f"After {trips} recharge trips, the final sortie" if trips else "The sortie"
    first = steps[start]
    sortie = steps[start:-1]
    inspected = sorted({s.cell for s in sortie if s.action == "inspect"})
    high = [s for s in sortie if s.wind == "high"]
    parts = [f"{before} starts at step {first.step} with {first.charge_ah:.1f} Ah "
             f"({first.soc:.0%})"]
    if inspected:
        parts.append(f"inspects at {', '.join(inspected)}")
    if high:
        parts.append(f"the wind is high from step {high[0].step}")
    end = (f"at step {last.step}, with {last.charge_ah:.1f} Ah left in {last.wind} wind at "
           f"{last.level} voltage, it {last.event}")
    return "; ".join(parts) + "; " + end + "."
