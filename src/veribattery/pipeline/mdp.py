"""An ``mdp`` model and its properties to results: build the MDP, check each property
(``Pmin``/``Pmax``, ``Rmin``/``Rmax`` and the state formulas around them)."""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from veribattery._memory import trim_for
from veribattery.checker import CheckResult, UndecidedResult
from veribattery.checker.certify.fixpoint import Progress
from veribattery.checker.formula.intervals import Undecided
from veribattery.checker.mdp import MDP, MdpRewards, Strategy
from veribattery.checker.mdp.formula import mdp_answer
from veribattery.checker.mdp.ill_posed import unreachable_reward_target
from veribattery.checker.mdp.operators import require_checkable
from veribattery.checker.mdp.witness import property_strategy
from veribattery.errors import ArgumentError, Span, UndefinedResult
from veribattery.explore.build.mdp import BuiltMdp, build_mdp
from veribattery.lang import (
    FlatModel,
    Model,
    PropertiesFile,
    Property,
    flatten_model,
    resolve_property,
    with_used_rewards,
)
from veribattery.lang.nodes import Value
from veribattery.pipeline.run import (
    STAGES,
    ProgressCallback,
    Stopwatch,
    stages_of,
    tell_building,
    tell_checking,
)
from veribattery.pipeline.stopping import stopping_condition

if TYPE_CHECKING:
    from veribattery.pipeline.session import Rewards

__all__ = ["MdpCheckRun", "check_mdp_model"]


@dataclass(frozen=True, slots=True)
class MdpCheckRun:
    """What one check of an MDP produced: the MDP, one result per property, timings.

    :param model: the flat model the MDP was built from (None if not kept).
    :param errors: properties answered as PRISM answers them, but ill-posed: an input
        error (an infeasible ``multi(...)``: NaN; an ``Rmin [ F phi ]`` whose target no
        strategy can reach: Infinity), each ``file:line:col: why``; the CLI shows the
        results, then these, and exits 2.
    """

    mdp: MDP
    results: tuple[CheckResult, ...]
    timings_s: dict[str, float]
    warnings: tuple[str, ...] = ()
    # Left out of the repr, as the MDP's arrays are: every command of the model.
    model: FlatModel | None = field(default=None, repr=False)
    errors: tuple[str, ...] = ()
    #: States left unexpanded, every property's value known there (``stop_early``).
    stopped: int = 0

    def strategy(self, index: int) -> Strategy:
        """The optimal memoryless strategy of the *index*-th result's property (0-based),
        computed anew (the check keeps only values).

        :raises NoStrategyError: the property has none (step-bounded, no P/R operator).
        :raises ArgumentError: there is no *index*-th result.
        """
        count = len(self.results)
        if not -count <= index < count:
            raise ArgumentError(f"strategy({index}): there is no result {index}; this run "
                                f"has {count} (0-based: 0 to {count - 1})")
        return property_strategy(self.mdp, self.results[index].property.formula)

    @property
    def model_summary(self) -> dict[str, int]:
        """Sizes as reported by ``--json``: states, choices, transitions, initial
        states, deadlocks (and ``stopped_states`` where exploration stopped early)."""
        summary = {
            "states": self.mdp.num_states,
            "choices": self.mdp.num_choices,
            "transitions": self.mdp.num_transitions,
            "initial_states": int(self.mdp.initial.size),
            "deadlocks": self.mdp.deadlocks,
        }
        return summary | ({"stopped_states": self.stopped} if self.stopped else {})


def check_mdp_model(
    model: Model,
    properties: Sequence[Property],
    *,
    props_file: PropertiesFile | None = None,
    constants: Mapping[str, Value | str] | None = None,
    progress: ProgressCallback | None = None,
    stopwatch: Stopwatch | None = None,
    rewards: Rewards = "all",
    stop_early: bool = False,
) -> MdpCheckRun:
    """Flatten the ``mdp`` *model*, build its MDP and check each property at the
    initial states, in floating point with certified bounds.

    A property whose bound the certified interval cannot decide is an
    :class:`~veribattery.checker.UndecidedResult` (:func:`check_prism_file` settles it
    in exact arithmetic where the model allows).

    :param rewards: the reward structures built: ``"all"`` (the run's MDP has every one,
        as an induced export of a ``multi`` strategy writes them), or ``"named"``, only
        those the properties read (the others cost memory and time for nothing).
    :param stop_early: leave unexpanded the states where every property's value is
        already known (:func:`~veribattery.pipeline.stopping.stopping_condition`), as
        Storm does: the values at the initial states are the same, the MDP smaller.

    :raises CheckError: ``P=?``/``R=?`` (no single value on an MDP), or an operator
        outside the supported ones.
    """
    watch = stopwatch or Stopwatch(*STAGES)
    with watch.stage("parse"):
        flat = flatten_model(model, constants)
        resolved = [resolve_property(p, flat, props_file, constants) for p in properties]
        for prop in resolved:
            require_checkable(prop.formula)  # P=?, S: refused before the build
    stages = stages_of(progress)
    with watch.stage("build"):
        tell_building(stages)
        stop = stopping_condition(resolved, flat) if stop_early else None
        built = build_mdp(with_used_rewards(flat, resolved) if rewards == "named" else flat,
                          progress=progress, stop=stop)
        mdp = as_checker_mdp(built)
        trim_for(mdp.num_states)  # the builder's freed temporaries, under the MDP's arrays
    results = []
    errors: list[str] = []
    with watch.stage("check"):
        for number, prop in enumerate(resolved, start=1):
            tell_checking(stages, number, len(resolved), prop)
            results.append(_checked(mdp, prop, errors,
                                    None if stages is None else stages.solving))
            errors.extend(ill_posed_errors(mdp, results[-1]))
            trim_for(mdp.num_states)
    return MdpCheckRun(mdp, tuple(results), watch.seconds, built.warnings, model=flat,
                       errors=tuple(errors), stopped=built.stopped)


def _checked(mdp: MDP, prop: Property, errors: list[str],
             progress: Progress | None = None) -> CheckResult:
    """*prop*'s answer; an :class:`UndecidedResult` if its bound is undecided; NaN,
    with the reason added to *errors*, if it has no value (an infeasible ``multi``)."""
    start = time.perf_counter()
    try:
        answer = mdp_answer(mdp, prop.formula, progress)
    except Undecided as exc:
        return UndecidedResult.of(prop, exc.message)
    except UndefinedResult as exc:
        errors.append(property_error(prop, f"undefined (NaN): {exc.message}", exc.span))
        return CheckResult(prop, np.zeros(0), math.nan, 0.0)
    return CheckResult.of_answer(prop, answer, time.perf_counter() - start).without_states()


def ill_posed_errors(mdp: MDP, result: CheckResult) -> list[str]:
    """*result*'s entry for :attr:`MdpCheckRun.errors` if its property is ill-posed (see
    :mod:`~veribattery.checker.mdp.ill_posed`), else none. A finite value cannot be
    one: the graph search is made only for an infinite value or a bound's truth."""
    value = result.value
    if isinstance(value, float) and math.isfinite(value):
        return []
    why = unreachable_reward_target(mdp, result.property.formula)
    return [] if why is None else [property_error(result.property, why, None)]


def property_error(prop: Property, why: str, span: Span | None) -> str:
    """``file:line:col: property: why``, at *span* or else at the property."""
    where = span if span is not None and span.line > 0 else prop.span
    return f"{where}: {prop.name or prop.text}: {why}"


def as_checker_mdp(built: BuiltMdp) -> MDP:
    """The checker's :class:`~veribattery.checker.mdp.MDP` of an explored model."""
    return MDP(
        transitions=built.transitions,
        row_groups=built.row_groups,
        initial=built.initial,
        labels=built.labels,
        choice_actions=built.choice_actions,
        actions=built.actions,
        rewards=tuple(MdpRewards(r.name, r.state, r.choice) for r in built.rewards),
        states=built.states,
        variable_names=built.variable_names,
        deadlocks=built.deadlocks,
    )
