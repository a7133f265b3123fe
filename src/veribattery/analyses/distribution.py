"""The distribution of mission time: the whole CDF to success and to failure, in one pass.

``P=? [ F{"mt"}<=T "success" ]`` answers one deadline T; a planner wants the whole
curve. :func:`reward_distribution` computes, for any DTMC with integer rewards,
the probability of first reaching *success* (and, separately, *failure*) with a
total reward of exactly each value, by one forward pass over reward levels
(:func:`veribattery.checker.kernels.reward_bounded.absorption_by_level`): exact up to
floating-point rounding, not sampled. The pass stops once the CDF of the time to
success has reached *coverage* of ``P(F success)`` (and likewise for failure) and
every requested horizon has been passed, or as soon as nothing is still under way
(up to rounding); what is cut off is reported as :attr:`Distribution.pending` — the
probability of being still under way after the last level, an upper bound on every
CDF's missing tail.

The reward counted is the one Storm counts for ``F{"r"}<=T``: every step up to and
including the step that enters the success or failure state.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from veribattery._files import staged
from veribattery._types import FloatArray
from veribattery.checker import Workspace, kernels
from veribattery.checker.kernels import reward_bounded
from veribattery.checker.kernels.conditional import conditional_reach_rewards
from veribattery.errors import CheckError, ConfigError, Span
from veribattery.explore.dtmc import DTMC, RewardVectors

__all__ = [
    "Deadline",
    "Distribution",
    "parse_deadline",
    "plot_distribution",
    "reward_distribution",
    "write_csv",
]

#: Quantiles reported of the time to success (given success).
QUANTILES = (0.5, 0.9, 0.99)
#: The forward pass gives up after this many reward levels.
MAX_LEVELS = 1_000_000
#: Absolute slack on coverage: a set whose probability is rounding noise is covered at once.
ROUNDING = 1e-12
_NO_SPAN = Span(0, 0, "")


@dataclass(frozen=True, slots=True)
class Distribution:
    """The reward accumulated until success or failure, level by level.

    :param reward: the reward structure's name.
    :param values: the total reward of each level (0, unit, 2·unit, …).
    :param success: probability of succeeding with exactly that total reward.
    :param failure: probability of failing with exactly that total reward.
    :param p_success: ``P(F success)``, exact (a linear solve), for conditioning.
    :param p_failure: ``P(F failure)``, exact.
    :param pending: probability still under way after the last level (the cut-off).
    :param expected_given_success: ``E[reward to success | F success]``, exact.
    """

    reward: str
    values: FloatArray
    success: FloatArray
    failure: FloatArray
    p_success: float
    p_failure: float
    pending: float
    expected_given_success: float

    @property
    def success_cdf(self) -> FloatArray:
        """``P(success with total reward <= value)`` at each level."""
        return np.asarray(np.cumsum(self.success), dtype=np.float64)

    @property
    def failure_cdf(self) -> FloatArray:
        """``P(failure with total reward <= value)`` at each level."""
        return np.asarray(np.cumsum(self.failure), dtype=np.float64)

    def p_success_within(self, limit: float) -> float:
        """``P(F{r}<=limit success)``; exact if *limit* is at most the last level."""
        upto = int(np.searchsorted(self.values, limit, side="right"))
        return float(self.success[:upto].sum())

    def quantile(self, q: float) -> float:
        """The smallest total reward T with ``P(success within T | success) >= q``.

        :raises CheckError: when success is impossible or the pass stopped before q.
        """
        value = self.quantile_or_none(q)
        if value is None and self.p_success <= 0:
            raise CheckError("success is unreachable, so its quantiles are undefined")
        if value is None:
            raise CheckError(f"the distribution was cut before its {q:.4g} quantile")
        return value

    def quantile_or_none(self, q: float) -> float | None:
        """:meth:`quantile`, or None where it is undefined: success is impossible, or the
        pass stopped (at its *coverage*) before q."""
        if self.p_success <= 0:
            return None
        cdf = self.success_cdf / self.p_success
        # Rounding may leave the last value a hair below the exact 1.
        index = int(np.searchsorted(cdf, q * (1 - 1e-12), side="left"))
        return float(self.values[index]) if index < cdf.size else None


@dataclass(frozen=True, slots=True)
class Deadline:
    """A deadline as the user wrote it and in reward units (minutes for ``mt``)."""

    text: str
    value: float


_UNITS = {"": 1.0, "m": 1.0, "min": 1.0, "h": 60.0}
_DEADLINE = re.compile(r"^\s*(-?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:e[-+]?[0-9]+)?)\s*([a-z]*)\s*$")


def parse_deadline(text: str, working_day_minutes: float = 480.0,
                   option: str = "--deadline") -> Deadline:
    """``4800`` (minutes), ``4800m``/``4800min``, ``80h``, or ``5d`` (working days).

    :param working_day_minutes: the length of a working day ``d``, in minutes.
    :param option: how to name the option in an error.
    :raises ConfigError: for anything else, e.g. an unknown unit.
    """
    match = _DEADLINE.match(text.lower())
    units = {**_UNITS, "d": working_day_minutes}
    if match is None or match.group(2) not in units:
        unit = match.group(2) if match else None
        what = f"unknown unit '{unit}'" if unit else "not a number"
        raise ConfigError(f"{option} '{text}': {what}; give minutes (4800, 4800m), hours "
                          "(80h) or working days (5d)")
    value = float(match.group(1)) * units[match.group(2)]
    if not 0 <= value < math.inf:
        what = "negative" if value < 0 else "beyond the largest number"
        raise ConfigError(f"{option} '{text}': a time cannot be {what}; give minutes (4800, "
                          "4800m), hours (80h) or working days (5d)")
    return Deadline(text, value)


#: The longest working day, in minutes.
MINUTES_PER_DAY = 24 * 60


def parse_deadlines(working_day: str,
                    deadlines: Sequence[str]) -> tuple[float, tuple[Deadline, ...]]:
    """``--working-day`` and the ``--deadline`` options: the day's length in minutes and
    the deadlines.

    :raises ConfigError: on a malformed value or a working day not in (0, 24h].
    """
    day = parse_deadline(working_day, option="--working-day").value
    if day <= 0:
        raise ConfigError(f"--working-day {working_day}: must be longer than 0, e.g. 8h")
    if day > MINUTES_PER_DAY:
        raise ConfigError(f"--working-day {working_day}: a working day is at most 24h "
                          f"({MINUTES_PER_DAY} minutes)")
    return day, tuple(parse_deadline(d, day) for d in deadlines)


def reward_distribution(dtmc: DTMC, reward: str = "mt", success: str = "success",
                        failure: str = "failure", *, coverage: float = 0.999,
                        horizon: float = 0.0, max_levels: int = MAX_LEVELS,
                        workspace: Workspace | None = None,
                        progress: Callable[[int], None] | None = None) -> Distribution:
    """The distribution of reward *reward* accumulated until *success* or *failure*.

    From the (first) initial state of *dtmc*; the reward structure must have
    non-negative integer values.

    :param coverage: continue until this fraction of ``P(F success)`` and of
        ``P(F failure)`` has been absorbed.
    :param horizon: and at least up to this total reward (the largest deadline), unless
        the pending mass has fallen to rounding noise before it.
    :param max_levels: give up (CheckError) after this many levels.
    :param workspace: the checker's caches to share (those a check of *dtmc* filled:
        its linear systems); None: new ones for this distribution.
    :param progress: told the number of reward levels done after each one.
    :raises CheckError: for unknown labels or reward structures, non-integer
        rewards, or a pass that does not reach *coverage* within *max_levels*.
    :raises ConfigError: when *coverage* is not in (0, 1].
    """
    if not 0 < coverage <= 1:  # 0 (or nan) stops at once: no quantile is ever reached
        raise ConfigError(f"coverage must be in (0, 1], got {coverage}")
    workspace = Workspace() if workspace is None else workspace
    structure = _structure(dtmc, reward)
    levels = reward_bounded.integer_rewards(dtmc, structure, _NO_SPAN)
    masks = (_label(dtmc, success), _label(dtmc, failure) & ~_label(dtmc, success))
    everywhere = np.ones(dtmc.num_states, dtype=bool)
    start = int(dtmc.initial[0])
    exact = [float(kernels.until_probs(dtmc.transitions, everywhere, m,
                                       workspace=workspace).value[start]) for m in masks]
    initial = np.zeros(dtmc.num_states)
    initial[start] = 1.0
    masses = reward_bounded.absorption_by_level(
        dtmc.transitions, initial, masks, levels,
        _stop_rule(exact, coverage, horizon, levels, progress), max_levels, workspace=workspace)
    if not _covered(masses.absorbed.sum(axis=1), exact, coverage):
        raise CheckError(f"the distribution did not reach {coverage:g} of its mass within "
                         f"{max_levels:,} reward levels")
    expected = _expected_given(dtmc, structure, masks[0], success, exact[0], workspace)
    return Distribution(reward, masses.rewards, masses.absorbed[0], masses.absorbed[1],
                        exact[0], exact[1], masses.pending, expected)


def _stop_rule(exact: Sequence[float], coverage: float, horizon: float,
               levels: np.ndarray, progress: Callable[[int], None] | None = None
               ) -> reward_bounded.StopRule:
    positive = levels[levels > 0]
    unit = math.gcd(*(int(v) for v in np.unique(positive))) if positive.size else 1

    def stop(level: int, absorbed: FloatArray, pending: float) -> bool:
        if progress is not None:
            progress(level + 1)
        # Once nothing is under way (up to rounding) no later level adds mass: stop even
        # short of the horizon (a deadline of 10^8 minutes ran a million empty levels).
        return pending <= ROUNDING or (
            level * unit >= horizon and _covered(absorbed, exact, coverage))

    return stop


def _covered(absorbed: FloatArray, exact: Sequence[float], coverage: float) -> bool:
    """Each set has *coverage* of its probability (up to rounding, :data:`ROUNDING`)."""
    return all(a >= coverage * e - ROUNDING for a, e in zip(absorbed, exact, strict=True))


def _expected_given(dtmc: DTMC, structure: RewardVectors, success_mask: np.ndarray,
                    success: str, p_success: float, workspace: Workspace) -> float:
    if p_success <= 0:
        return math.nan
    values = conditional_reach_rewards(dtmc, structure, success_mask, success_mask,
                                       f'F "{success}"', _NO_SPAN, workspace=workspace)
    return float(values[int(dtmc.initial[0])])


def _structure(dtmc: DTMC, reward: str) -> RewardVectors:
    try:
        return dtmc.reward(reward)
    except (KeyError, IndexError):
        names = ", ".join(f'"{r.name}"' for r in dtmc.rewards if r.name) or "none"
        raise CheckError(f'the model has no reward structure "{reward}" (it has {names})') \
            from None


def _label(dtmc: DTMC, name: str) -> np.ndarray:
    if name not in dtmc.labels:
        known = ", ".join(f'"{n}"' for n in sorted(dtmc.labels))
        raise CheckError(f'the model has no label "{name}" (known labels: {known})')
    return np.asarray(dtmc.labels[name], dtype=bool)


def write_csv(dist: Distribution, path: str | Path) -> Path:
    """One row per reward level: ``reward, p_success, p_failure, cdf_success, cdf_failure``.

    Written to a temporary file first and renamed, so a failure leaves nothing behind.
    """
    import pandas as pd

    path = Path(path)
    frame = pd.DataFrame({
        dist.reward: dist.values,
        "p_success": dist.success,
        "p_failure": dist.failure,
        "cdf_success": dist.success_cdf,
        "cdf_failure": dist.failure_cdf,
    })
    with staged(path) as temporary:
        frame.to_csv(temporary, index=False)  # shortest round-trip repr
    return path


def plot_distribution(dist: Distribution, deadlines: Sequence[Deadline],
                      path: str | Path) -> Path:
    """The CDFs of the time to success and to failure, with quantiles and deadlines marked.

    The format follows the suffix of *path* (``.png``, ``.pdf``, ``.svg``).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    path = Path(path)
    figure = Figure(figsize=(8, 4.8), layout="constrained")
    FigureCanvasAgg(figure)
    ax = figure.add_subplot()
    ax.step(dist.values, dist.success_cdf, where="post", label="success", color="tab:green")
    ax.step(dist.values, dist.failure_cdf, where="post", label="failure", color="tab:red")
    # Labels in axes-fraction heights: quantiles stacked from the bottom, deadlines
    # from the top, so that labels at equal or near abscissae never overprint.
    where = ax.get_xaxis_transform()
    for i, q in enumerate(QUANTILES):
        value = dist.quantile_or_none(q)
        if value is None:  # success unreachable, or beyond the coverage: no line
            continue
        ax.axvline(value, color="tab:green", linestyle=":", linewidth=1)
        ax.text(value, 0.04 + 0.07 * i, f" {q:.0%} quantile: {value:g}", transform=where,
                fontsize=8, color="tab:green")
    for i, deadline in enumerate(deadlines):
        p = dist.p_success_within(deadline.value)
        ax.axvline(deadline.value, color="tab:blue", linestyle="--", linewidth=1)
        ax.text(deadline.value, 0.93 - 0.07 * i, f" {deadline.text}: P(success) = {p:.4f}",
                transform=where, fontsize=8, color="tab:blue")
    ax.set_xlim(_plot_start(dist), None)
    ax.set_xlabel(f"accumulated reward {dist.reward!r}")
    ax.set_ylabel("probability (cumulative)")
    ax.set_ylim(0, 1.02)
    given = dist.expected_given_success
    ax.set_title(f"P(done with {dist.reward} <= T)   E[{dist.reward} | success] = "
                 + ("undefined (success unreachable)" if math.isnan(given) else f"{given:.6g}"))
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper left")
    with staged(path, suffix=path.suffix) as temporary:
        figure.savefig(temporary, dpi=120)
    return path


def _plot_start(dist: Distribution) -> float:
    """Where the curves leave 0 (less a margin), so the plot is not mostly empty."""
    mass = dist.success + dist.failure
    first = int(np.argmax(np.cumsum(mass) >= 1e-4 * max(float(mass.sum()), 1e-300)))
    span = float(dist.values[-1] - dist.values[first])
    return max(0.0, float(dist.values[first]) - 0.05 * span)
