"""Monte-Carlo simulation of a built DTMC: estimates of ``P=?`` and ``R=?`` properties with CIs.

All runs step together: one array holds every run's current state, and each
step samples the successors of all active runs at once by inverse-CDF lookup in
the rows of the CSR transition matrix (a vectorised binary search over each
row's cumulative probabilities). Each property is an *observer* that decides
runs as they go, so one set of runs serves every property.

Semantics match the checker's: ``R{r}[F T]`` accumulates the state reward and
the expected transition reward of every step taken from a state outside ``T``,
until ``T`` is reached, and is infinite on runs that enter a state from which
``T`` cannot be reached. A run decides ``phi1 U phi2`` as soon as it meets
``phi2``, leaves ``phi1``, or enters a state where the until has probability 0
(found by the checker's graph search, exact). Runs undecided after
``max_steps`` are counted in :attr:`Estimate.undecided` and left out of the
estimate; they are never silently dropped.

Runs go in batches of at most :data:`BATCH_RUNS`, each from where the random stream
left off, their counts, means and squared deviations pooled (Chan, Golub and LeVeque's
parallel update): memory stays that of one batch (10^8 runs took 9.3 GB at once), and
a simulation of one batch is what it always was, float for float.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from veribattery._types import BoolArray, FloatArray, IntArray
from veribattery.analyses.actions import ActionLabeller
from veribattery.analyses.observers import Observer, observer_for
from veribattery.errors import CheckError
from veribattery.explore.dtmc import DTMC
from veribattery.lang.nodes import Property

__all__ = ["Estimate", "Simulation", "path_table", "simulate"]

#: The most runs stepped together (some 50 bytes each, per property and step).
BATCH_RUNS = 1 << 20

#: Normal quantiles of the two-sided 95 % and 99.9 % intervals.
Z95 = 1.959963984540054
Z999 = 3.2905267314919255


@dataclass(frozen=True, slots=True)
class Estimate:
    """The Monte-Carlo estimate of one property beside its exact value.

    :ivar name: the property's name (or its text).
    :ivar text: the property's text.
    :ivar estimate: the sample mean over the decided runs.
    :ivar ci95: 95 % confidence interval (Wilson score for probabilities, normal for rewards).
    :ivar ci999: 99.9 % interval, used to flag a disagreeing exact value.
    :ivar runs: runs that decided the property.
    :ivar undecided: runs that had not decided it after ``max_steps``.
    :ivar exact: the exact value, when known.
    """

    name: str
    text: str
    estimate: float
    ci95: tuple[float, float]
    ci999: tuple[float, float]
    runs: int
    undecided: int
    exact: float | None = None

    @property
    def disagrees(self) -> bool:
        """The exact value lies outside the 99.9 % interval."""
        if self.exact is None or self.runs == 0 or math.isnan(self.estimate):
            return False
        lo, hi = self.ci999
        if math.isinf(self.exact) or math.isinf(self.estimate):
            return self.exact != self.estimate
        slack = 1e-12 * max(1.0, abs(self.exact))
        return not lo - slack <= self.exact <= hi + slack


@dataclass(frozen=True, slots=True)
class Simulation:
    """The estimates of one simulation, and the recorded paths.

    :ivar paths: the state sequences of the first runs (as many as asked to record).
    :ivar skipped: properties that were not simulated, with the reason.
    """

    runs: int
    seed: int
    max_steps: int
    steps: int
    estimates: tuple[Estimate, ...]
    skipped: tuple[str, ...]
    paths: tuple[IntArray, ...]

    def warnings(self) -> tuple[str, ...]:
        """Disagreements with exact values, and undecided runs."""
        out = []
        for e in self.estimates:
            if e.undecided:
                out.append(f"{e.name}: {e.undecided} of {self.runs} runs undecided after "
                           f"{self.max_steps} steps (left out of the estimate; raise --max-steps)")
            if e.disagrees:
                out.append(f"{e.name}: the exact value {e.exact:.12g} is outside the 99.9 % "
                           f"interval [{e.ci999[0]:.6g}, {e.ci999[1]:.6g}] of the estimate")
        return (*out, *self.skipped)


class _Sampler:
    """Inverse-CDF sampling of successors, row by row of a CSR matrix."""

    def __init__(self, dtmc: DTMC) -> None:
        P = dtmc.transitions
        self.indptr = P.indptr.astype(np.int64)
        self.indices = P.indices.astype(np.int64)
        rows = np.repeat(np.arange(P.shape[0]), np.diff(self.indptr))
        cum = np.cumsum(P.data.astype(np.longdouble))
        before = np.concatenate([[0.0], cum])[self.indptr[:-1]]
        local = cum - before[rows]
        totals = local[self.indptr[1:] - 1]
        self.cdf = np.asarray(local / totals[rows], dtype=np.float64)
        self.cdf[self.indptr[1:] - 1] = 2.0  # the last successor takes every u < 1

    def step(self, current: IntArray, rng: np.random.Generator) -> IntArray:
        u = rng.random(current.size)
        lo, hi = self.indptr[current], self.indptr[current + 1] - 1
        open_ = lo < hi
        while open_.any():
            mid = (lo + hi) // 2
            right = self.cdf[mid] <= u
            lo = np.where(open_ & right, mid + 1, lo)
            hi = np.where(open_ & ~right, mid, hi)
            open_ = lo < hi
        chosen: IntArray = self.indices[lo]
        return chosen


def simulate(
    dtmc: DTMC,
    properties: Sequence[Property],
    *,
    runs: int,
    seed: int = 0,
    max_steps: int = 100_000,
    exact: Mapping[str, float] | None = None,
    record: int = 0,
) -> Simulation:
    """Estimate each ``P=?``/``R=?`` property of *properties* from *runs* sampled runs.

    :param dtmc: the model; runs start in its first initial state.
    :param properties: resolved properties (constants substituted, labels inlined).
    :param runs: number of runs (at least 1).
    :param seed: seed of numpy's default generator (the results are deterministic).
    :param max_steps: steps after which undecided runs stop.
    :param exact: exact values by property name (or text), shown beside the estimates.
    :param record: how many of the first runs to keep as paths.
    :raises CheckError: when *runs* or *max_steps* is below 1.
    """
    if runs < 1:
        raise CheckError(f"--runs must be at least 1, not {runs}")
    if max_steps < 1:
        raise CheckError(f"--max-steps must be at least 1, not {max_steps}")
    batch = max(BATCH_RUNS, record)
    observers, skipped = _observers(dtmc, properties, min(runs, batch))
    tallies = [_Tally() for _ in observers]
    rng, sampler = np.random.default_rng(seed), _Sampler(dtmc)
    steps = 0
    paths: tuple[IntArray, ...] = ()
    for first in range(0, runs, batch):
        size = min(batch, runs - first)
        fresh = [(name, prop, replace(obs, runs=size)) for name, prop, obs in observers]
        current = np.full(size, int(dtmc.initial[0]), dtype=np.int64)
        ran, kept = _run(sampler, fresh, current, rng, max_steps,
                         min(record, size) if first == 0 else 0)
        steps, paths = max(steps, ran), paths or kept
        for tally, (_, _, obs) in zip(tallies, fresh, strict=True):
            tally.add(obs)
    exact = exact or {}
    estimates = tuple(_estimate(name, prop, tally, obs.is_probability, exact.get(name))
                      for (name, prop, obs), tally in zip(observers, tallies, strict=True))
    return Simulation(runs, seed, max_steps, steps, estimates, skipped, paths)


def _observers(
    dtmc: DTMC, properties: Sequence[Property], runs: int
) -> tuple[list[tuple[str, Property, Observer]], tuple[str, ...]]:
    chosen, skipped = [], []
    for prop in properties:
        name = prop.name or prop.text
        try:
            chosen.append((name, prop, observer_for(dtmc, prop.formula, runs)))
        except CheckError as exc:
            skipped.append(f"{name}: not simulated ({exc.message})")
    return chosen, tuple(skipped)


def _run(
    sampler: _Sampler, observers: list[tuple[str, Property, Observer]], current: IntArray,
    rng: np.random.Generator, max_steps: int, record: int,
) -> tuple[int, tuple[IntArray, ...]]:
    """Step every undecided run until all are decided or *max_steps*; keep *record* paths."""
    history: list[IntArray] = [current[:record].copy()]
    finished_at = np.full(record, -1, dtype=np.int64)
    active = _observe(observers, 0, current)
    step = 0
    while active.any() and step < max_steps:
        idx = np.flatnonzero(active)
        current[idx] = sampler.step(current[idx], rng)
        step += 1
        history.append(current[:record].copy())
        active = _observe(observers, step, current)
        finished_at[(finished_at < 0) & ~active[:record]] = step
    finished_at[finished_at < 0] = step
    table = np.stack(history, axis=1) if record else np.zeros((0, 1), dtype=np.int64)
    return step, tuple(table[r, : finished_at[r] + 1] for r in range(record))


def _observe(observers: list[tuple[str, Property, Observer]], step: int,
             current: IntArray) -> BoolArray:
    """Show every observer the runs' states at *step*; the runs some observer still needs."""
    active = np.zeros(current.size, dtype=bool)
    for _, _, obs in observers:
        obs.see(step, current)
        active |= ~obs.decided
    return active


class _Tally:
    """The decided runs' count, mean and sum of squared deviations, pooled over batches
    (one batch: ``np.mean`` and ``np.std(ddof=1)``'s own arithmetic), and the undecided."""

    __slots__ = ("m2", "mean", "n", "undecided")

    def __init__(self) -> None:
        self.n = self.undecided = 0
        self.mean = self.m2 = 0.0

    def add(self, obs: Observer) -> None:
        values: FloatArray = obs.values[obs.decided]
        self.undecided += int(obs.decided.size - values.size)
        n = int(values.size)
        if n == 0:
            return
        mean = float(np.sum(values) / n)
        with np.errstate(invalid="ignore"):  # (inf - inf: an infinite mean, kept below)
            m2 = float(np.sum((values - mean) ** 2))
        if self.n == 0:
            self.n, self.mean, self.m2 = n, mean, m2
            return
        total = self.n + n
        if math.isinf(mean) or math.isinf(self.mean):
            self.n, self.mean, self.m2 = total, max(mean, self.mean), math.nan
            return
        delta = mean - self.mean
        self.m2 += m2 + delta * delta * self.n * n / total
        self.mean += delta * n / total
        self.n = total

    @property
    def std(self) -> float:
        """The sample standard deviation (``ddof=1``)."""
        return math.sqrt(self.m2 / (self.n - 1))


def _estimate(name: str, prop: Property, tally: _Tally, probability: bool,
              exact: float | None) -> Estimate:
    if tally.n == 0:
        nan = (math.nan, math.nan)
        return Estimate(name, prop.text, math.nan, nan, nan, 0, tally.undecided, exact)
    interval = _wilson if probability else _normal
    return Estimate(name, prop.text, tally.mean, interval(tally, Z95), interval(tally, Z999),
                    tally.n, tally.undecided, exact)


def _wilson(tally: _Tally, z: float) -> tuple[float, float]:
    """Wilson score interval of a proportion (sensible at 0 and 1 hits, unlike the normal one)."""
    n, p = tally.n, tally.mean
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


def _normal(tally: _Tally, z: float) -> tuple[float, float]:
    """Mean ± z standard errors (infinite where a run's reward is)."""
    mean = tally.mean
    if math.isinf(mean):
        return mean, mean
    half = z * tally.std / math.sqrt(tally.n) if tally.n > 1 else 0.0
    return mean - half, mean + half


def path_table(
    dtmc: DTMC, paths: Sequence[IntArray], actions: ActionLabeller | None = None
) -> tuple[list[str], list[list[object]]]:
    """Sampled paths in the columns of PRISM's simulator: run, action, step, variables, rewards.

    Each reward column holds the reward of the step taken from that state (state
    reward plus expected transition reward), so its running sum is what ``C<=k``
    counts; the last row of a run, where it stopped, has no action. A reward named
    like a variable (the mission's ``rc``) is headed ``reward_NAME``, so that every
    column has its own name.
    """
    variables = set(dtmc.variable_names)
    names = [r.name or f"reward{i + 1}" for i, r in enumerate(dtmc.rewards)]
    names = [f"reward_{n}" if n in variables else n for n in names]
    header = ["run", "action", "step", *dtmc.variable_names, *names]
    table: list[list[object]] = []
    for run, states in enumerate(paths):
        rows = dtmc.states[states]
        labels = [str(a) for a in actions(rows)] if actions is not None else [""] * len(states)
        labels[-1] = ""
        for step, state in enumerate(states):
            rewards = [float(r.total[state]) for r in dtmc.rewards]
            table.append([run + 1, labels[step], step, *rows[step].tolist(), *rewards])
    return header, table
