"""Capacity fade per cycle: linear, exponential and two-phase "knee" fits, chosen by AIC.

Each model gives capacity ``C(n)`` at cycle ``n``. The model's BA1 parameter at cycle
``N`` is the *relative* loss per cycle there, ``fade(N) = -C'(N) / C(N)``, so that the
model's ``cap(rc) = C(N)·(1 - fade·rc)`` continues the fitted curve from ``N`` (to first
order). Its confidence interval comes from the fit's covariance by the delta method.

scipy is imported inside the functions that fit, so the CLI starts fast.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from veribattery._types import FloatArray
from veribattery.phm.data import CycleLog, PhmDataError

__all__ = ["FadeFit", "FadeReport", "choose", "fit_all", "fit_exponential", "fit_knee",
           "fit_linear"]

Curve = Callable[..., FloatArray]
#: Two-sided confidence level of the reported intervals.
CONFIDENCE = 0.95


def _linear(n: FloatArray, a: float, b: float) -> FloatArray:
    return a - b * n


def _exponential(n: FloatArray, a: float, k: float) -> FloatArray:
    return a * np.exp(-k * n)


def _knee(n: FloatArray, a: float, b1: float, b2: float, nk: float) -> FloatArray:
    return a - b1 * np.minimum(n, nk) - b2 * np.maximum(n - nk, 0.0)


@dataclass(frozen=True, slots=True)
class FadeFit:
    """One fitted fade model.

    :ivar name: ``linear``, ``exponential`` or ``knee``.
    :ivar formula: the model, for people.
    :ivar params: parameter name → fitted value.
    :ivar covariance: covariance of the parameters (order of *params*).
    :ivar residuals: measured minus fitted capacity at each logged cycle, Ah.
    :ivar aic: Akaike's information criterion ``n·ln(SSE/n) + 2k``.
    """

    name: str
    formula: str
    params: dict[str, float]
    covariance: FloatArray
    residuals: FloatArray
    aic: float

    @property
    def dof(self) -> int:
        """Residual degrees of freedom."""
        return len(self.residuals) - len(self.params)

    @property
    def rmse(self) -> float:
        """Root-mean-square residual, Ah."""
        return float(np.sqrt(np.mean(self.residuals**2)))

    def capacity(self, cycle: FloatArray | float) -> FloatArray:
        """Fitted capacity at *cycle*, Ah."""
        return _CURVES[self.name](np.asarray(cycle, dtype=np.float64), *self.params.values())

    def loss_per_cycle(self, cycle: float) -> float:
        """``-C'(cycle)``: Ah lost per cycle at *cycle*."""
        return _slope(_CURVES[self.name], np.array(list(self.params.values())), cycle)

    def relative_fade(self, cycle: float) -> float:
        """``-C'(cycle) / C(cycle)``: the model's ``fade_per_recharge`` at *cycle*."""
        return _relative(_CURVES[self.name], np.array(list(self.params.values())), cycle)

    def fade_interval(self, cycle: float) -> tuple[float, float]:
        """95% confidence interval of :meth:`relative_fade` (delta method, t quantile)."""
        from scipy import stats

        theta = np.array(list(self.params.values()))
        grad = _gradient(lambda p: _relative(_CURVES[self.name], p, cycle), theta)
        spread = math.sqrt(max(float(grad @ self.covariance @ grad), 0.0))
        t = float(stats.t.ppf(0.5 + CONFIDENCE / 2, max(self.dof, 1)))
        centre = self.relative_fade(cycle)
        return (centre - t * spread, centre + t * spread)


def _slope(curve: Curve, theta: FloatArray, cycle: float) -> float:
    """``-C'(cycle)`` by a central difference (exact for the piecewise-linear models)."""
    h = 1e-3
    ahead, behind = curve(np.array([cycle + h, cycle - h]), *theta)
    return -float(ahead - behind) / (2 * h)


def _relative(curve: Curve, theta: FloatArray, cycle: float) -> float:
    capacity = float(curve(np.array([cycle]), *theta)[0])
    # An exponential far out underflows to 0 Ah: no relative fade there (NaN, which the
    # callers refuse), rather than a ZeroDivisionError.
    return _slope(curve, theta, cycle) / capacity if capacity != 0 else math.nan


def _gradient(function: Callable[[FloatArray], float], theta: FloatArray) -> FloatArray:
    """Central-difference gradient, steps scaled to each parameter."""
    grad = np.empty_like(theta)
    for i, value in enumerate(theta):
        h = 1e-6 * max(abs(value), 1e-3)
        up, down = theta.copy(), theta.copy()
        up[i], down[i] = value + h, value - h
        grad[i] = (function(up) - function(down)) / (2 * h)
    return grad


_CURVES: dict[str, Curve] = {"linear": _linear, "exponential": _exponential, "knee": _knee}


def _aic(residuals: FloatArray, k: int, scale: float) -> float:
    """Gaussian AIC; SSE is floored so exact (synthetic) data does not give ``-inf``."""
    n = len(residuals)
    # In logs: squaring a capacity near the float range (1e308 Ah) overflowed, and so did
    # scaling the mean square back (every fit's AIC was inf, the choice arbitrary).
    # The floor's logarithm is taken term by term: 1e-12 x a capacity below 1e-296 Ah
    # underflowed to 0, and log(0) failed every fit as "did not converge".
    floor = 2 * (math.log(1e-12) + math.log(scale))
    scaled = float(np.mean(np.square(residuals / scale)))
    log_mse = math.log(scaled) + 2 * math.log(scale) if scaled > 0 else -math.inf
    return n * max(log_mse, floor) + 2 * k


def _finish(name: str, formula: str, names: tuple[str, ...], theta: FloatArray,
            cov: FloatArray, log: CycleLog) -> FadeFit:
    residuals = log.capacity_ah - _CURVES[name](log.cycle, *theta)
    aic = _aic(residuals, len(names), float(np.max(log.capacity_ah)))
    return FadeFit(name, formula, dict(zip(names, map(float, theta), strict=True)),
                   np.asarray(cov, dtype=np.float64), residuals, aic)


#: curve_fit's xtol, ftol and gtol. Its defaults (1.5e-8) stop so early that the 4th
#: printed digit of an interval depended on where the optimiser stopped.
_TOLERANCE = 1e-14


def _curve_fit(name: str, log: CycleLog, start: FloatArray) -> tuple[FloatArray, FloatArray]:
    import warnings

    from scipy.optimize import OptimizeWarning, curve_fit

    # A poor start can overflow exp() on the way; such trials are rejected by the
    # optimiser itself, and a fit that ends badly is judged afterwards (_attempt).
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore", OptimizeWarning)
        theta, cov = curve_fit(_CURVES[name], log.cycle, log.capacity_ah, p0=start,
                               maxfev=20000, xtol=_TOLERANCE, ftol=_TOLERANCE, gtol=_TOLERANCE)
    return np.asarray(theta, dtype=np.float64), np.asarray(cov, dtype=np.float64)


def _line(x: FloatArray, y: FloatArray) -> tuple[float, float]:
    """Slope and intercept of a least-squares line, a start for the nonlinear fit."""
    import warnings

    # Cycles such as 1e15 + k leave the start poorly conditioned: the fit that follows
    # is judged by its own covariance (_attempt), so numpy's warning would only be noise.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", np.exceptions.RankWarning)
        slope, intercept = np.polyfit(x, y, 1)
    return float(slope), float(intercept)


def fit_linear(log: CycleLog) -> FadeFit:
    """``C(n) = a - b·n`` by least squares."""
    slope, intercept = _line(log.cycle, log.capacity_ah)
    theta, cov = _curve_fit("linear", log, np.array([intercept, -slope]))
    return _finish("linear", "C(n) = a - b*n", ("a", "b"), theta, cov, log)


def fit_exponential(log: CycleLog) -> FadeFit:
    """``C(n) = a·exp(-k·n)``, started from the log-linear fit.

    :raises ValueError: when a capacity is not positive (it has no logarithm).
    :raises OverflowError: when the start's ``a`` is beyond the float range (capacities
        near 1e308 Ah).
    """
    if np.any(log.capacity_ah <= 0):
        raise ValueError("needs capacities > 0 (it fits their logarithm)")
    slope, intercept = _line(log.cycle, np.log(log.capacity_ah))
    theta, cov = _curve_fit("exponential", log, np.array([math.exp(intercept), -slope]))
    return _finish("exponential", "C(n) = a*exp(-k*n)", ("a", "k"), theta, cov, log)


def fit_knee(log: CycleLog) -> FadeFit:
    """Two straight lines meeting at the knee cycle ``nk`` (continuous).

    For a given ``nk`` the other parameters are linear and solved exactly, so the fit is
    a search over ``nk`` alone (:func:`_knee_cycle`), which finds the exact optimum: a
    joint nonlinear fit stalled near a knee on a logged cycle, where the sum of squares
    has a kink, and the printed interval's 4th digit depended on where it stopped.
    """
    nk = _knee_cycle(log)
    _, (a, b1, b2) = _knee_sse(log, nk)
    theta = np.array([a, b1, b2, nk])
    return _finish("knee", "C(n) = a - b1*min(n, nk) - b2*max(n - nk, 0)",
                   ("a", "b1", "b2", "nk"), theta, _knee_covariance(log, theta), log)


def _knee_sse(log: CycleLog, nk: float) -> tuple[float, FloatArray]:
    n = log.cycle
    design = np.column_stack([np.ones_like(n), -np.minimum(n, nk), -np.maximum(n - nk, 0.0)])
    coef, *_ = np.linalg.lstsq(design, log.capacity_ah, rcond=None)
    residual = log.capacity_ah - design @ coef
    return float(residual @ residual), coef


def _knee_cycle(log: CycleLog) -> float:
    """The knee cycle with the least squared error, between the second and the
    second-to-last logged cycle.

    A coarse profile over 200 candidates brackets it; inside the bracket each interval
    between logged cycles is solved exactly. There the knee model is two independent
    lines (the fit on either side) meeting at ``nk``, so the sum of squares has an
    interior minimum only where the two lines' own least-squares fits cross; else its
    least is at a logged cycle, where it has a kink.
    """
    cycles = log.cycle
    candidates = np.linspace(cycles[1], cycles[-2], 200)
    k = int(np.argmin([_knee_sse(log, float(nk))[0] for nk in candidates]))
    low, high = candidates[max(k - 1, 0)], candidates[min(k + 1, len(candidates) - 1)]
    found = [float(candidates[k])]
    for i in range(1, len(cycles) - 2):
        if cycles[i + 1] < low or cycles[i] > high:
            continue
        found += [float(cycles[i]), float(cycles[i + 1])]
        cross = _crossing(log, i)
        if cross is not None and cycles[i] < cross < cycles[i + 1]:
            found.append(cross)
    return min(sorted(found), key=lambda nk: _knee_sse(log, nk)[0])


def _crossing(log: CycleLog, i: int) -> float | None:
    """Where the least-squares lines through cycles ``[0, i]`` and ``(i, end]`` cross
    (None when they are parallel)."""
    shift = log.cycle[i]  # cycles such as 1e15 + k: lines in n - shift keep their digits
    n, y = log.cycle - shift, log.capacity_ah
    (p1, q1), (p2, q2) = (np.linalg.lstsq(np.column_stack([np.ones_like(n[part]), n[part]]),
                                          y[part], rcond=None)[0]
                          for part in (slice(0, i + 1), slice(i + 1, None)))
    if q1 == q2:
        return None
    return float(shift + (p2 - p1) / (q1 - q2))


def _knee_covariance(log: CycleLog, theta: FloatArray) -> FloatArray:
    """The parameters' covariance as scipy's curve_fit gives it, ``s²·(JᵀJ)⁻¹`` by QR,
    with the Jacobian exact.

    A knee on a logged cycle counts that cycle to the first phase: the one-sided
    derivative a forward difference (curve_fit's) takes, rather than a choice that
    flips with the last bit of ``nk``.
    """
    from scipy.linalg import solve_triangular

    a, b1, b2, nk = theta
    n = log.cycle
    jac = np.column_stack([np.ones_like(n), -np.minimum(n, nk), -np.maximum(n - nk, 0.0),
                           (b2 - b1) * (n > nk)])
    r = np.linalg.qr(jac, mode="r")
    # Slopes equal to rounding leave the knee anywhere (a straight line): not identifiable.
    level = abs(b2 - b1) <= 4 * np.finfo(np.float64).eps * max(abs(b1), abs(b2))
    if level or np.any(np.diag(r) == 0):
        return np.full((4, 4), np.inf)
    inverse = solve_triangular(r, np.eye(4))
    residuals = log.capacity_ah - _knee(n, a, b1, b2, nk)
    scale = float(residuals @ residuals) / (len(n) - 4)
    covariance: FloatArray = inverse @ inverse.T * scale
    return covariance


@dataclass(frozen=True, slots=True)
class FadeReport:
    """Every usable fit, the AIC choice and why, and what was left out.

    :ivar fits: usable fits, best (lowest AIC) first.
    :ivar skipped: model name → why it was not usable.
    """

    fits: tuple[FadeFit, ...]
    skipped: dict[str, str]

    @property
    def chosen(self) -> FadeFit:
        """The fit with the lowest AIC."""
        return self.fits[0]

    def explanation(self) -> str:
        """Why the chosen fit won: ΔAIC and Akaike weights against the others."""
        best = self.chosen
        weights = _akaike_weights([f.aic for f in self.fits])
        parts = [f"{best.name} has the lowest AIC ({best.aic:.2f}; Akaike weight {weights[0]:.2f})"]
        for fit, weight in zip(self.fits[1:], weights[1:], strict=True):
            delta = fit.aic - best.aic
            parts.append(f"{fit.name} ΔAIC {delta:+.2f} (weight {weight:.2f}"
                         f"{', essentially as good' if delta < 2 else ''})")
        return "; ".join(parts)


def _akaike_weights(aics: list[float]) -> list[float]:
    best = min(aics)
    raw = [math.exp(-(a - best) / 2) for a in aics]
    return [r / sum(raw) for r in raw]


#: A knee has 4 parameters: fewer than 6 points leaves too little to judge it by.
KNEE_MIN_POINTS = 6


def fit_all(log: CycleLog) -> FadeReport:
    """Fit every model that the data supports and rank them by AIC.

    :raises PhmDataError: when the capacity does not change over the log, or no model
        gives a meaningful fit.
    """
    _check_changes(log)
    fits: list[FadeFit] = []
    skipped: dict[str, str] = {}
    fitters: list[tuple[str, Callable[[CycleLog], FadeFit]]] = [
        ("linear", fit_linear), ("exponential", fit_exponential), ("knee", fit_knee)]
    for name, fitter in fitters:
        if name == "knee" and len(log.cycle) < KNEE_MIN_POINTS:
            skipped[name] = f"needs at least {KNEE_MIN_POINTS} cycles for 4 parameters"
            continue
        reason, fit = _attempt(fitter, log)
        if fit is None:
            skipped[name] = reason
        else:
            fits.append(fit)
    if not fits:
        why = "; ".join(f"{k}: {v}" for k, v in skipped.items())
        raise PhmDataError(f"{log.table.source}: column 'capacity_ah' against 'cycle': "
                           f"no meaningful fade fit ({why})")
    return FadeReport(tuple(sorted(fits, key=lambda f: f.aic)), skipped)


def _check_changes(log: CycleLog) -> None:
    """A new battery's log may not move yet: say so, rather than list three fits that
    failed on it. A fade of 0 is not fitted: readings that agree say the loss is below
    what the logger resolves, not that there is none (the model would never age)."""
    capacity = log.capacity_ah
    if np.all(capacity == capacity[0]):
        raise PhmDataError(
            f"{log.table.source}: column 'capacity_ah': capacity does not change over the log "
            f"({capacity[0]:g} Ah at cycles {log.cycle[0]:g}..{log.cycle[-1]:g}); no fade can "
            "be fitted yet: log more cycles, and keep the config's battery.fade_per_recharge "
            "until then")


def _attempt(fitter: Callable[[CycleLog], FadeFit], log: CycleLog) -> tuple[str, FadeFit | None]:
    try:
        # numpy raises rather than warns: an overflow (capacities near 1e308 Ah) or a
        # division by zero (cycles closer than 1e-300) makes the fit unusable, not a
        # page of warnings followed by a fit of inf and nan.
        with np.errstate(over="raise", divide="raise", invalid="raise"):
            fit = fitter(log)
    except ArithmeticError as exc:  # OverflowError, ZeroDivisionError, FloatingPointError
        return f"not computable in floating point ({exc})", None
    except (RuntimeError, ValueError, np.linalg.LinAlgError) as exc:
        return f"did not converge ({exc})", None
    if not np.all(np.isfinite(fit.covariance)):
        return "parameters not identifiable (infinite covariance)", None
    if fit.name == "knee" and not log.cycle[0] < fit.params["nk"] < log.cycle[-1]:
        return "knee falls outside the logged cycles", None
    return "", fit


def choose(log: CycleLog, model: str | None = None) -> tuple[FadeReport, FadeFit]:
    """All fits, and the one to use: *model* when named, else the lowest AIC.

    :raises PhmDataError: when the named model could not be fitted.
    """
    report = fit_all(log)
    if model is None:
        return report, report.chosen
    for fit in report.fits:
        if fit.name == model:
            return report, fit
    raise PhmDataError(f"{log.table.source}: the {model} fit is not usable: "
                       f"{report.skipped.get(model, 'unknown model')}")
