"""BA3's step approximation of a discharge curve, and Eq. 2's consumption table from it.

The curve is resampled on a uniform SOC grid; the three voltage levels and the two SOC
thresholds are chosen together to minimise the squared error between the curve and the
step function over that grid (for given thresholds the best levels are the segment
means, so the search is over threshold pairs only, all of them, with prefix sums).
Levels follow the spec: **high** for ``SOC > high``, **medium** for
``low <= SOC <= high``, **low** for ``SOC < low``.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from veribattery._types import FloatArray
from veribattery.config.battery import round_half_up
from veribattery.phm.data import DischargeCurve, PhmDataError

__all__ = ["Eq2Inputs", "SocGridError", "StepFit", "eq2_table", "fit_steps", "resample",
           "step_error"]

LEVELS = ("low", "medium", "high")
WINDS = ("low_wind", "high_wind")
#: The most SOC grid points a fit searches (its arrays are m x m: 2,000 take 32 MB each;
#: 1e-320 as a step overflowed, 0.0001 took 25 s and gigabytes).
MAX_GRID = 2000


class SocGridError(PhmDataError):
    """The SOC grid does not suit the curve's SOC range: more points than the search
    takes (*too_fine*), or fewer than 3. The step, the range or (Coulomb counting) the
    capacity may be at fault: the caller, who knows which was given, may say so.

    :ivar lowest: the curve's lowest SOC; :ivar highest: its highest.
    :ivar step: the SOC grid's step.
    :ivar too_fine: True for too many points, False for too few.
    """

    def __init__(self, curve: DischargeCurve, step: Fraction, too_fine: bool) -> None:
        self.lowest, self.highest = float(curve.soc.min()), float(curve.soc.max())
        self.step, self.too_fine = step, too_fine
        span = f"the SOC range {self.lowest:.3g}..{self.highest:.3g}"
        super().__init__(
            f"{curve.source}: a SOC step of {float(step):g} puts more than {MAX_GRID:,} grid "
            f"points on {span}; give a coarser step, e.g. 0.01" if too_fine else
            f"{curve.source}: {span} spans fewer than 3 points of the {float(step):g} SOC "
            "grid; log a longer discharge")


def resample(curve: DischargeCurve, step: Fraction) -> tuple[FloatArray, FloatArray, int]:
    """The curve on the multiples of *step* inside its SOC range, ascending.

    :returns: (soc grid, voltage, the grid index of its first point, in units of step).
    :raises SocGridError: when the grid has more than :data:`MAX_GRID` or fewer than 3
        points in the curve's SOC range.
    """
    lowest, highest = float(curve.soc.min()), float(curve.soc.max())
    if (highest - lowest) / float(step) > MAX_GRID:  # the best pair is searched in m x m
        raise SocGridError(curve, step, too_fine=True)
    first = int(np.ceil(lowest / float(step) - 1e-9))
    last = int(np.floor(highest / float(step) + 1e-9))
    if last - first < 2:
        raise SocGridError(curve, step, too_fine=False)
    # Each grid point is the float nearest the exact k·step, so it compares with the
    # thresholds (also exact multiples of step) as the rationals do.
    soc = np.array([float(k * step) for k in range(first, last + 1)])
    order = np.argsort(curve.soc, kind="stable")
    return soc, np.interp(soc, curve.soc[order], curve.voltage_v[order]), first


def step_error(voltage: FloatArray, i: int, j: int) -> tuple[tuple[float, float, float], float]:
    """Best levels and squared error when grid points ``[0, i)`` are low, ``[i, j]``
    medium and ``(j, end]`` high (0 < i <= j < last index)."""
    segments = (voltage[:i], voltage[i : j + 1], voltage[j + 1 :])
    means = tuple(float(s.mean()) for s in segments)
    sse = sum(float(((s - m) ** 2).sum()) for s, m in zip(segments, means, strict=True))
    return (means[0], means[1], means[2]), sse


def _best_pair(voltage: FloatArray) -> tuple[int, int]:
    """Indices (i, j) minimising :func:`step_error`, over all pairs at once."""
    m = len(voltage)
    s1 = np.concatenate(([0.0], np.cumsum(voltage)))
    s2 = np.concatenate(([0.0], np.cumsum(voltage**2)))

    def sse(a: FloatArray, b: FloatArray) -> FloatArray:
        total, count = s1[b] - s1[a], b - a
        result: FloatArray = s2[b] - s2[a] - total**2 / count
        return result

    i = np.arange(1, m - 1)[:, None]
    j = np.arange(1, m - 1)[None, :]
    ii, jj = np.broadcast_arrays(i, np.maximum(j, i))
    cost = sse(np.zeros_like(ii), ii) + sse(ii, jj + 1) + sse(jj + 1, np.full_like(jj, m))
    cost = np.where(j >= i, cost, np.inf)
    flat = int(np.argmin(cost))
    return int(ii.flat[flat]), int(jj.flat[flat])


@dataclass(frozen=True, slots=True)
class StepFit:
    """Thresholds, levels and the approximation error.

    :ivar low: SOC below which the voltage is low (exact, on the grid).
    :ivar high: SOC above which the voltage is high.
    :ivar voltages: the low, medium and high level, V.
    :ivar rms_v: root-mean-square error over the SOC grid, V.
    :ivar max_v: largest absolute error on the grid, V.
    :ivar soc: the SOC grid; :ivar voltage: the curve on it.
    """

    low: Fraction
    high: Fraction
    voltages: tuple[float, float, float]
    rms_v: float
    max_v: float
    soc: FloatArray
    voltage: FloatArray

    def step(self, soc: FloatArray) -> FloatArray:
        """The step function at *soc*."""
        v0, v1, v2 = self.voltages
        result: FloatArray = np.where(soc > float(self.high), v2,
                                      np.where(soc < float(self.low), v0, v1))
        return result


def fit_steps(curve: DischargeCurve, step: Fraction = Fraction(1, 100)) -> StepFit:
    """The step approximation with the least squared error on the *step* SOC grid."""
    soc, voltage, first = resample(curve, step)
    i, j = _best_pair(voltage)
    return _step_fit(soc, voltage, first, step, i, j)


def fixed_steps(curve: DischargeCurve, low: Fraction, high: Fraction,
                step: Fraction = Fraction(1, 100)) -> StepFit:
    """The best levels for given thresholds (e.g. the paper's 0.25 / 0.75), and the error."""
    soc, voltage, first = resample(curve, step)
    i = int(np.searchsorted(soc, float(low) - 1e-12))
    j = int(np.searchsorted(soc, float(high) + 1e-12)) - 1
    if not 0 < i <= j < len(soc) - 1:
        raise PhmDataError(f"{curve.source}: thresholds {low}/{high} leave a level empty "
                           "on this curve's SOC range")
    return _step_fit(soc, voltage, first, step, i, j)


def _step_fit(soc: FloatArray, voltage: FloatArray, first: int, step: Fraction,
              i: int, j: int) -> StepFit:
    levels, sse = step_error(voltage, i, j)
    fit = StepFit((first + i) * step, (first + j) * step, levels, 0.0, 0.0, soc, voltage)
    errors = voltage - fit.step(soc)
    return StepFit(fit.low, fit.high, levels, float(np.sqrt(sse / len(soc))),
                   float(np.abs(errors).max()), soc, voltage)


@dataclass(frozen=True, slots=True)
class Eq2Inputs:
    """Eq. 2's inputs besides the voltages: energy, flight time per wind, action times."""

    energy_wh: Fraction
    flight_time_h: tuple[Fraction, Fraction]
    action_time_h: dict[str, Fraction]


def eq2_table(inputs: Eq2Inputs, voltages: tuple[Fraction, Fraction, Fraction],
              resolution: Fraction) -> dict[str, tuple[tuple[int, int, int], ...]]:
    """Eq. 2, ``C = E_spec·t / (V·T)``, in units: action → ``[wind][level]``, rounded half up."""
    return {
        action: tuple(
            tuple(round_half_up(inputs.energy_wh * t / (v * flight) / resolution)
                  for v in voltages)  # type: ignore[misc]
            for flight in inputs.flight_time_h
        )
        for action, t in inputs.action_time_h.items()
    }
