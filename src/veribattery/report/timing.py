"""Mission time: ``distribution``'s exact CDF, its quantiles, and working-day deadlines.

The distribution is :func:`~veribattery.analyses.distribution.reward_distribution`
over the ``mt`` reward with ``distribution``'s defaults, on the DTMC the verdict was
checked on. Without deadlines from the user, the report asks about the whole working
days the mission can end in: each P(success within D) is then a value the
distribution already holds, equal to ``distribution --deadline Nd``'s.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from veribattery.analyses.distribution import (
    QUANTILES,
    Deadline,
    Distribution,
    parse_deadline,
    reward_distribution,
)
from veribattery.checker import Workspace
from veribattery.errors import CheckError
from veribattery.explore.dtmc import DTMC
from veribattery.report.data import DeadlineRow, MissionTime

__all__ = ["MOST_DEADLINES", "mission_time"]

#: At most this many working-day deadlines are chosen when none are given.
MOST_DEADLINES = 8
#: A working day is chosen from where this share of P(success) has ended.
_FIRST_MASS = 1e-3


def mission_time(dtmc: DTMC, deadlines: Sequence[Deadline], working_day: float,
                 coverage: float, workspace: Workspace | None = None) -> MissionTime:
    """The distribution of ``mt`` to success and failure, and P(success) by each deadline.

    :param deadlines: as the user gave them (empty: whole working days, chosen here).
    :param working_day: minutes in a working day ``d``.
    :param coverage: continue until this share of P(success) and P(failure) is absorbed.
    :param workspace: the checker's caches of the check of *dtmc* (see
        :func:`~veribattery.analyses.distribution.reward_distribution`).
    """
    horizon = max((d.value for d in deadlines), default=0.0)
    dist = reward_distribution(dtmc, "mt", coverage=coverage, horizon=horizon,
                               workspace=workspace)
    chosen = tuple(deadlines) or _working_days(dist, working_day)
    return MissionTime(
        p_success=dist.p_success, p_failure=dist.p_failure,
        expected_given_success=dist.expected_given_success,
        quantiles=_quantiles(dist),
        deadlines=tuple(_deadline(dist, d, working_day) for d in chosen),
        working_day_minutes=working_day, levels=int(dist.values.size),
        last_level=float(dist.values[-1]), pending=dist.pending, coverage=coverage,
        minutes=dist.values, success_cdf=dist.success_cdf, failure_cdf=dist.failure_cdf,
    )


def _quantiles(dist: Distribution) -> tuple[tuple[float, float], ...]:
    """The quantiles ``distribution`` reports (none when success is impossible)."""
    try:
        return tuple((q, dist.quantile(q)) for q in QUANTILES)
    except CheckError:
        return ()


def _working_days(dist: Distribution, day: float) -> tuple[Deadline, ...]:
    """Whole working days from where successes begin to the last level computed, at most
    :data:`MOST_DEADLINES` of them (evenly spaced)."""
    cdf = dist.success_cdf
    if dist.p_success <= 0 or day <= 0:
        return ()
    index = min(int(np.searchsorted(cdf, _FIRST_MASS * dist.p_success)), cdf.size - 1)
    start = float(dist.values[index])
    first = max(1, math.ceil(start / day))
    last = math.floor(float(dist.values[-1]) / day)
    if last < first:
        return ()
    step = math.ceil((last - first + 1) / MOST_DEADLINES)
    return tuple(parse_deadline(f"{n}d", day) for n in range(first, last + 1, step))


def _deadline(dist: Distribution, deadline: Deadline, day: float) -> DeadlineRow:
    upto = int(np.searchsorted(dist.values, deadline.value, side="right"))
    over = dist.p_success_within(deadline.value) + float(dist.failure[:upto].sum())
    return DeadlineRow(deadline.text, deadline.value, deadline.value / day,
                       dist.p_success_within(deadline.value), over)
