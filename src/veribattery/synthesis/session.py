"""``synthesize``: the best return policy for a mission, and BS1 measured against it.

:func:`synthesize` builds the mission MDP of a config (whatever its mode), asks it the
questions of model-spec.md's "Synthesis" and checks BS1 at the config's ``safe_t``
beside it:

- ``Pmax [ F "success" ]``, certified;
- BS1's P(success), expected mission time and recharges, certified;
- per requirement on P(success), the fastest strategy that meets it, certified (from
  the Pareto front by weighted sums: :mod:`~veribattery.synthesis.fastest`);
- the threshold table of the safest-then-fastest strategy
  (:mod:`~veribattery.synthesis.optimal`), with that strategy's own values;
- optionally, the Pareto front and BS1's points at several ``safe_t``.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path

from veribattery.checker.mdp import MDP, FrontSearch, reach_probability
from veribattery.config import MissionConfig, derive_parameters
from veribattery.pipeline import CheckProgress, ProgressCallback
from veribattery.render import FastestQuestion, synthesis_questions
from veribattery.synthesis.bs1_values import Bs1Values, bs1_points, bs1_values
from veribattery.synthesis.exports import StrategyExport, strategy_export_texts
from veribattery.synthesis.fastest import (
    Fastest,
    as_safe_as,
    fastest,
    fastest_near_pmax,
    front,
    mission_front,
)
from veribattery.synthesis.model import Certified, ModelSize, mission_model
from veribattery.synthesis.optimal import (
    ChosenStrategy,
    chosen_actions,
    safest_fastest,
    strategy_columns,
)
from veribattery.synthesis.pareto import Bs1Point, FrontPoint
from veribattery.synthesis.strategy import strategy_frame
from veribattery.synthesis.thresholds import ThresholdTable, threshold_table

__all__ = ["FRONT_SAFE_TS", "FrontRequest", "SynthesisResult", "config_requirements", "synthesize"]

#: Told the name of each stage as it starts (``"Pmax"``, ``"BS1"``, ...).
StageCallback = Callable[[str], None]


#: BS1's ``safe_t`` values on the Pareto figure by default (the config's own is added).
FRONT_SAFE_TS = (Fraction(1, 10), Fraction(2, 10), Fraction(3, 10), Fraction(4, 10))


@dataclass(frozen=True, slots=True)
class FrontRequest:
    """The Pareto front asked for: all its vertices (from the fastest strategy up to
    ``Pmax``), and BS1 at each of *safe_ts*."""

    safe_ts: tuple[Fraction, ...] = FRONT_SAFE_TS


@dataclass(frozen=True, slots=True)
class SynthesisResult:
    """What :func:`synthesize` found (values at the initial state).

    :ivar size: the mission MDP's states, choices and transitions.
    :ivar p_success_max: ``Pmax [ F "success" ]``, certified.
    :ivar bs1: BS1 at the config's ``safe_t``, certified.
    :ivar fastest: per requirement, the fastest strategy that meets it (LP answers).
    :ivar strategy: the safest-then-fastest strategy and its own values.
    :ivar table: that strategy's threshold table.
    :ivar front: the Pareto front (empty unless asked); *bs1_front*: BS1's points.
    :ivar timings_s: seconds per stage.
    :ivar strategy_files: the text of each strategy file asked for (path -> text).
    """

    size: ModelSize
    p_success_max: Certified
    bs1: Bs1Values
    fastest: tuple[Fastest, ...]
    strategy: ChosenStrategy
    table: ThresholdTable
    front: tuple[FrontPoint, ...] = ()
    bs1_front: tuple[Bs1Point, ...] = ()
    timings_s: dict[str, float] = field(default_factory=dict)
    strategy_files: dict[Path, str] = field(default_factory=dict)

    @property
    def all_requirements_met(self) -> bool:
        """Whether some strategy meets every requirement asked."""
        return all(f.achievable for f in self.fastest)

    def speedup(self, answer: Fastest) -> float | None:
        """How much less time than BS1 *answer*'s strategy takes, as a fraction of BS1's
        expected mission time (0.19: 19 % faster; None where it has no time)."""
        bs1 = self.bs1.exp_mission_time.value
        if answer.exp_mission_time is None or bs1 <= 0:
            return None
        return 1.0 - answer.exp_mission_time / bs1


def config_requirements(cfg: MissionConfig) -> tuple[FastestQuestion, ...]:
    """*cfg*'s requirements that bound P(success) from below (the others ask nothing of
    the MDP: :func:`~veribattery.synthesis.unasked_requirements` says why)."""
    return synthesis_questions(cfg)[0]


def synthesize(cfg: MissionConfig, requirements: Sequence[FastestQuestion] = (), *,
               as_safe_as_bs1: bool = False, front_request: FrontRequest | None = None,
               progress: ProgressCallback | None = None,
               on_stage: StageCallback | None = None,
               export: StrategyExport | None = None) -> SynthesisResult:
    """The best return policy for *cfg*'s mission, BS1 beside it.

    :param requirements: the requirements on P(success) to answer (e.g.
        :func:`config_requirements` and :func:`~veribattery.synthesis.fastest.required_at_least`).
    :param as_safe_as_bs1: also find the fastest strategy at least as safe as BS1 (at
        the config's ``safe_t``), after *requirements*.
    :param front_request: also compute the Pareto front and BS1's points on it.
    :param progress: told ``(states found, frontier)`` while the MDP is built.
    :param on_stage: told each stage's name as it starts.
    :param export: also make the texts of the strategy's files it asks for
        (:attr:`SynthesisResult.strategy_files`; the caller writes them).
    :raises VeribatteryError: when the config cannot be rendered, built or checked.
    """
    clock = _Clock(on_stage)
    with clock.stage("build"):
        model, mdp = mission_model(cfg, progress=progress)
    with clock.stage("Pmax"):
        pmax = reach_probability(mdp, mdp.labels["success"], objective="max")
    with clock.stage("strategy"):
        chosen = safest_fastest(mdp, pmax)
        table = _table(mdp, chosen, cfg)
    with clock.stage("BS1"):
        bs1 = bs1_values(cfg)
    asked = [*requirements, *([as_safe_as(bs1.p_success.value)] if as_safe_as_bs1 else [])]
    best = Certified.at_initial(mdp, pmax)
    search = _LazyFront(mdp, _solves_told(progress))
    with clock.stage("fastest"):
        answers = tuple(fastest_near_pmax(question, best, chosen)
                        or fastest(mdp, question, search.get()) for question in asked)
    points, bs1_front = _front(search, cfg, front_request, clock)
    texts = {} if export is None else strategy_export_texts(model, mdp, chosen, export)
    return SynthesisResult(ModelSize.of(mdp), best, bs1, answers, chosen, table, points,
                           bs1_front, clock.seconds, texts)


def _table(mdp: MDP, chosen: ChosenStrategy, cfg: MissionConfig) -> ThresholdTable:
    frame = strategy_frame(strategy_columns(mdp, chosen), chosen_actions(mdp, chosen),
                           indifferent=chosen.indifferent[chosen.reached])
    return threshold_table(frame, derive_parameters(cfg))


def _front(search: _LazyFront, cfg: MissionConfig, request: FrontRequest | None,
           clock: _Clock) -> tuple[tuple[FrontPoint, ...], tuple[Bs1Point, ...]]:
    if request is None:
        return (), ()
    with clock.stage("front"):
        points = front(search.get())
    safe_ts = sorted({*request.safe_ts, Fraction(cfg.strategy.safe_t)})
    with clock.stage("BS1 points"):
        return points, bs1_points(cfg, safe_ts)


def _solves_told(progress: ProgressCallback | None) -> Callable[[int], None] | None:
    """Each weighted solve of the front search told as a solve's progress (its number is
    not known beforehand), when *progress* hears solves."""
    if not isinstance(progress, CheckProgress):
        return None
    stages = progress
    return lambda solves: stages.solving(solves, 0, "weighted solve")


class _LazyFront:
    """The run's one front search, made on first use (its weighted optima are shared
    by the requirements and the front)."""

    def __init__(self, mdp: MDP, on_solve: Callable[[int], None] | None) -> None:
        self._mdp = mdp
        self._on_solve = on_solve
        self._search: FrontSearch | None = None

    def get(self) -> FrontSearch:
        if self._search is None:
            self._search = mission_front(self._mdp, self._on_solve)
        return self._search


class _Clock:
    """Seconds per stage, and the stage's name told as it starts."""

    def __init__(self, on_stage: StageCallback | None) -> None:
        self.seconds: dict[str, float] = {}
        self._on_stage = on_stage

    @contextmanager
    def stage(self, name: str) -> Iterator[None]:
        if self._on_stage is not None:
            self._on_stage(name)
        start = time.perf_counter()
        try:
            yield
        finally:
            self.seconds[name] = self.seconds.get(name, 0.0) + time.perf_counter() - start
