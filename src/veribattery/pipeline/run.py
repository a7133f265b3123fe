"""What a check produces and how it runs its properties, in either arithmetic: the run,
the options, the stopwatch and the loop over the properties."""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Literal, Protocol, get_args, runtime_checkable

import numpy as np

from veribattery._memory import trim_for
from veribattery.checker import CheckResult, Keep, UndecidedResult
from veribattery.checker.formula.intervals import Undecided
from veribattery.checker.result import require_keep
from veribattery.errors import ArgumentError, UndefinedResult
from veribattery.explore import DTMC
from veribattery.lang import Property
from veribattery.lang.expressions import walk
from veribattery.lang.nodes import (
    Eventually,
    Filter,
    ProbOp,
    Quantified,
    RewardOp,
    SteadyOp,
    Value,
)

if TYPE_CHECKING:
    from veribattery.checker import Workspace

__all__ = ["STAGES", "CheckOptions", "CheckProgress", "Keep", "ModelCheckRun", "ProgressCallback",
           "Rewards", "Stopwatch", "internal_results", "may_hold", "require_rewards",
           "run_checks", "stages_of", "tell_building", "tell_checking"]

#: Called while a state space is explored, with (states found, states explored).
ProgressCallback = Callable[[int, int], None]


@runtime_checkable
class CheckProgress(Protocol):
    """A *progress* that hears a whole check, not only the build: given where a
    :data:`ProgressCallback` is, it is also told each stage and how far each long
    solve is, so that a long run can be told from a hang."""

    def __call__(self, states: int, frontier: int) -> None:
        """After each BFS layer: the states found so far and the next frontier's size."""

    def starting(self, text: str) -> None:
        """A stage begins (``"building the state space"``)."""

    def checking(self, number: int, count: int, text: str) -> None:
        """Property *number* (1-based) of *count* is checked next; *text* is its formula."""

    def solving(self, done: int, total: int, unit: str) -> None:
        """A solve of the current property has *done* of *total* *unit* (``"states"``,
        ``"iterations"``) behind it; told per segment or iteration, never per state."""


def stages_of(progress: ProgressCallback | None) -> CheckProgress | None:
    """*progress* if it hears stages and solves too (:class:`CheckProgress`), else None."""
    return progress if isinstance(progress, CheckProgress) else None


def tell_building(stages: CheckProgress | None) -> None:
    """Tell *stages*, if any, that the state space is being built."""
    if stages is not None:
        stages.starting("building the state space")


def tell_checking(stages: CheckProgress | None, number: int, count: int,
                  prop: Property) -> None:
    """Tell *stages*, if any, that property *number* (1-based) of *count* comes next."""
    if stages is not None:
        stages.checking(number, count, prop.text or prop.name or "a formula")

#: The reward structures a check builds: all, or those the properties name.
Rewards = Literal["all", "named"]


def require_rewards(rewards: object) -> None:
    """Refuse a *rewards* outside :data:`Rewards`.

    :raises ArgumentError: naming the value given and the ones there are.
    """
    if rewards not in get_args(Rewards):
        raise ArgumentError(f"rewards must be one of {get_args(Rewards)}, got {rewards!r}")

#: The stages of a check, always reported (``Time: parse …, build …, check …``).
STAGES = ("parse", "build", "check")


#: The operators a state formula needs the checker for (a plain predicate has none).
_OPERATORS = (ProbOp, RewardOp, SteadyOp, Quantified, Filter)


@dataclass(frozen=True, slots=True)
class CheckOptions:
    """How properties are checked, in floating point or exact arithmetic alike.

    :param keep: what each result keeps (:data:`Keep`).
    :param undefined_as_nan: report a property that has no value on the model
        (:class:`~veribattery.errors.UndefinedResult`: the conditional defaults of a
        mission that never succeeds) as NaN with a warning, instead of failing the run.
    :param report_undecided: report a property whose bound the certified interval
        cannot decide as an :class:`~veribattery.checker.UndecidedResult` (for the
        caller to settle in exact arithmetic), instead of failing the run.
    :raises ArgumentError: for a *keep* outside :data:`Keep`.
    """

    keep: Keep = "states"
    undefined_as_nan: bool = False
    report_undecided: bool = False

    def __post_init__(self) -> None:
        require_keep(self.keep)

    @classmethod
    def given(cls, options: object) -> CheckOptions:
        """*options* as a caller passed them: None is the defaults.

        :raises ArgumentError: for anything but a :class:`CheckOptions` (a dict of them).
        """
        if options is None or isinstance(options, cls):
            return options or cls()
        fix = (f"veribattery.CheckOptions(**{options!r})" if isinstance(options, dict)
               else "veribattery.CheckOptions(keep='answers')")
        raise ArgumentError.wrong_kind("options", options, "a CheckOptions", fix)


@dataclass(frozen=True, slots=True)
class ModelCheckRun:
    """What one run of the pipeline produced: the DTMC, one result per property, timings."""

    dtmc: DTMC
    results: tuple[CheckResult, ...]
    timings_s: dict[str, float]
    warnings: tuple[str, ...] = field(default=())
    #: True when the DTMC re-used an earlier model's state space (see
    #: :class:`~veribattery.pipeline.ReusingBuilder`).
    reused: bool = False
    #: The bisimulation quotient the properties were checked on, if any (see *lump* of
    #: :class:`~veribattery.pipeline.Session`); *dtmc* is always the model's own chain.
    quotient: DTMC | None = None
    #: The answers of the caller's internal properties (see
    #: :meth:`~veribattery.pipeline.Session.check`), in their order: read by the caller,
    #: never reported with *results*.
    internal: tuple[CheckResult, ...] = ()
    #: The checker's caches the properties were checked with, for checking more
    #: formulas on :attr:`checked_dtmc` with the same linear systems.
    workspace: Workspace | None = field(default=None, compare=False, repr=False)

    def internal_value(self, name: str) -> Value:
        """The answer of the internal property named *name*.

        :raises KeyError: when no internal property has that name.
        """
        for result in self.internal:
            if result.property.name == name:
                return result.value
        raise KeyError(name)

    @property
    def checked_dtmc(self) -> DTMC:
        """The chain the properties were checked on: the quotient, else the DTMC."""
        return self.quotient if self.quotient is not None else self.dtmc

    @property
    def model_summary(self) -> dict[str, int]:
        """Sizes as reported by ``--json``: states, transitions, initial states, deadlocks
        (and ``stopped_states`` where exploration stopped early)."""
        summary = {
            "states": self.dtmc.num_states,
            "transitions": self.dtmc.num_transitions,
            "initial_states": len(self.dtmc.initial),
            "deadlocks": self.dtmc.deadlocks,
        }
        return summary | ({"stopped_states": self.dtmc.stopped} if self.dtmc.stopped else {})


class Stopwatch:
    """Accumulates wall-clock seconds per named stage (*stages* listed first, at 0)."""

    def __init__(self, *stages: str) -> None:
        self.seconds: dict[str, float] = dict.fromkeys(stages, 0.0)

    @contextmanager
    def stage(self, name: str) -> Iterator[None]:
        start = time.perf_counter()
        try:
            yield
        finally:
            self.seconds[name] = self.seconds.get(name, 0.0) + time.perf_counter() - start


def run_checks(
    checks: Sequence[Callable[[], CheckResult]], resolved: Sequence[Property], dtmc: DTMC,
    options: CheckOptions, progress: CheckProgress | None = None,
) -> tuple[tuple[CheckResult, ...], tuple[str, ...]]:
    """Run each property's check, and the warnings about properties without a value.

    With *undefined_as_nan* a property without a value is NaN, with *report_undecided*
    an undecided bound an :class:`~veribattery.checker.UndecidedResult`; with answers kept only,
    each result is reduced to its answer as soon as it is made.

    :param progress: told which property is checked next.
    """
    per_state = options.keep == "states"
    results: list[CheckResult] = []
    warnings: list[str] = []
    for number, (run_one, prop) in enumerate(zip(checks, resolved, strict=True), start=1):
        tell_checking(progress, number, len(resolved), prop)
        try:
            result = run_one()
            results.append(result if per_state else result.without_states())
            del result  # before the next property: its per-state arrays can go now
            if not per_state:
                trim_for(dtmc.num_states)
        except Undecided as exc:
            if not options.report_undecided:
                raise
            results.append(UndecidedResult.of(prop, exc.message))
        except UndefinedResult as exc:
            if not options.undefined_as_nan:
                raise
            size = dtmc.num_states if per_state else 0
            results.append(CheckResult(prop, np.full(size, np.nan), math.nan, 0.0))
            warnings.append(f"{prop.name or prop.text}: undefined (NaN): {exc.message}")
    return tuple(results), tuple(warnings)


def may_hold(dtmc: DTMC, prop: Property) -> bool:
    """False for a ``P=? [ F a ]`` whose operator-free ``a`` holds in no state of *dtmc*:
    its answer is 0 whatever the probabilities."""
    formula = prop.formula
    if not (isinstance(formula, ProbOp) and formula.op == "=?"):
        return True
    path = formula.path
    if not isinstance(path, Eventually) or path.bound is not None or any(
            isinstance(node, _OPERATORS) for node in walk(path.operand)):
        return True
    from veribattery.checker import state_set  # the DTMC checker: not imported for MDPs

    return bool(state_set(dtmc, path.operand).any())


def internal_results(
    dtmc: DTMC, internal: Sequence[Property], live: Sequence[bool], workspace: Workspace
) -> tuple[CheckResult, ...]:
    """The answers of the *internal* properties on *dtmc* in floating point: the *live*
    ones checked, the others 0 exactly (see :func:`may_hold`)."""
    from veribattery.checker import check  # the DTMC checker: not imported for MDPs

    return tuple(
        check(dtmc, p, keep="answers", workspace=workspace) if may
        else CheckResult(p, np.zeros(0), 0.0, 0.0, 0.0, 0.0)
        for p, may in zip(internal, live, strict=True)
    )
