"""A sweep's warnings, each given once with the points concerned, and its summary line."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

from veribattery.mission import CAP_CONSEQUENCE, RECHARGE_CAP_WARN_AT
from veribattery.sweep.grid import Point, yaml_text
from veribattery.sweep.tasks import PointResult

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["counted", "summary_line", "sweep_warnings"]

#: How many points a warning names before it says "and N more".
_NAMED = 4


def sweep_warnings(
    results: Sequence[tuple[Point, PointResult]], frame: pd.DataFrame, points: Sequence[Point]
) -> tuple[str, ...]:
    """Model warnings once each (with the points concerned), then the recharge cap's.

    The recharge-cap warning follows the model spec: only points where P[F rc=RC_MAX]
    >= 1e-9 count, and the largest probability is named.
    """
    by_text: dict[str, list[Point]] = {}
    for point, result in results:
        for warning in result.warnings:
            by_text.setdefault(warning, []).append(point)
    lines = [f"{text} ({_where(found, len(points))})" if points[0] else text
             for text, found in by_text.items()]
    cap = _recharge_cap(frame, points)
    return (*lines, *cap)


def _recharge_cap(frame: pd.DataFrame, points: Sequence[Point]) -> tuple[str, ...]:
    per_point = frame.drop_duplicates("point").set_index("point")["recharge_cap_probability"]
    cut = per_point[per_point.astype(float) >= RECHARGE_CAP_WARN_AT]
    if cut.empty:
        return ()
    worst = int(cut.astype(float).idxmax())
    where = _where([points[int(i)] for i in cut.index], len(points))
    return (
        f"the recharge cap (battery.max_recharges) is reached with probability up to "
        f"{float(cut[worst]):.6g} (at {_describe(points[worst])}); {where}; {CAP_CONSEQUENCE}",
    )


def _where(found: Sequence[Point], total: int) -> str:
    named = "; ".join(_describe(p) for p in found[:_NAMED])
    more = f" and {len(found) - _NAMED} more" if len(found) > _NAMED else ""
    return f"at {len(found)} of {total} points: {named}{more}"


def _describe(point: Point) -> str:
    return ", ".join(f"{key}={yaml_text(value)}" for key, value in point.items())


def summary_line(frame: pd.DataFrame) -> str:
    """``604 points: 601 checked, 3 failed; requirement p_success >= 0.99 fails at 12
    points`` (with several failing: ``requirements fail: A at 12 points, B at 1 point``)."""
    total = frame["point"].nunique()
    failed = int(frame.attrs.get("failed", 0))
    text = f"{counted(total)}: {total - failed} checked, {failed} failed"
    failing = _failing(frame)
    if len(failing) == 1:
        (requirement, count), = failing.items()
        return f"{text}; requirement {requirement} fails at {counted(count)}"
    if failing:
        each = ", ".join(f"{req} at {counted(count)}" for req, count in failing.items())
        return f"{text}; requirements fail: {each}"
    return text + ("; every requirement holds" if frame["holds"].notna().any() else "")


def _failing(frame: pd.DataFrame) -> dict[str, int]:
    """Each requirement that fails somewhere (as the rows give it: a property's
    requirements joined by ``and``), with the number of points where it fails."""
    rows = frame[frame["holds"].eq(False).fillna(False)]
    counts = rows.groupby("requirement", sort=False)["point"].nunique()
    return {str(requirement): int(count) for requirement, count in counts.items()}


def counted(count: int, noun: str = "point") -> str:
    """``1 point``, ``2 points``: *count* of *noun*, plural but for one."""
    return f"{count} {noun}{'' if count == 1 else 's'}"
