"""Exact checks: a model explored with its guards decided exactly and checked in rational
arithmetic (``--exact``)."""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING

from veribattery.checker import CheckResult
from veribattery.checker.ltl.cosafety import require_cosafe
from veribattery.lang import (
    FlatModel,
    Model,
    PropertiesFile,
    Property,
    resolve_property,
    with_used_rewards,
)
from veribattery.lang.nodes import Value
from veribattery.pipeline.inputs import (
    parsed_model,
    parsed_properties,
    reject_unknown_constants,
)
from veribattery.pipeline.run import (
    STAGES,
    CheckOptions,
    ModelCheckRun,
    ProgressCallback,
    Rewards,
    Stopwatch,
    internal_results,
    may_hold,
    run_checks,
    stages_of,
    tell_building,
)

if TYPE_CHECKING:
    from veribattery.checker import Workspace
    from veribattery.explore.exact.dtmc import ExactDTMC

__all__ = ["check_model_exact"]


def check_model_exact(
    model: Model,
    properties: Sequence[Property],
    *,
    props_file: PropertiesFile | None = None,
    constants: Mapping[str, Value | str] | None = None,
    progress: ProgressCallback | None = None,
    stopwatch: Stopwatch | None = None,
    options: CheckOptions | None = None,
    internal: Sequence[Property] = (),
    rewards: Rewards = "all",
) -> ModelCheckRun:
    """:func:`~veribattery.pipeline.check_model` in exact rational arithmetic: each result
    is an :class:`~veribattery.checker.exact.pctl.ExactCheckResult`.

    The model is explored with its guards decided exactly (its own exploration, never a
    re-used state space), and bounds such as ``P<=1/3`` are evaluated exactly from the
    properties as written. *internal* properties are answered as by
    :meth:`~veribattery.pipeline.Session.check`, in floating point on the model's DTMC
    (they feed warnings, not results). *rewards* as for
    :class:`~veribattery.pipeline.Session`: ``"named"`` builds only the reward structures
    the properties read.
    """
    from veribattery.checker import Workspace  # the DTMC checker: not imported for MDPs

    model, properties = parsed_model(model), parsed_properties(properties)
    reject_unknown_constants(model, props_file, constants or {})
    options = CheckOptions.given(options)
    watch = stopwatch or Stopwatch(*STAGES)
    with watch.stage("parse"):
        model, properties, props_file, flat = _decided(model, properties, props_file,
                                                       constants)
        resolved = [resolve_property(p, flat, props_file, constants) for p in properties]
        aside = [resolve_property(p, flat, props_file, constants) for p in internal]
        for prop in resolved:
            require_cosafe(prop.formula)  # refused before the build, not after it
        if rewards == "named":  # (cut alike: the exact builder pairs their structures)
            used = [*resolved, *aside]
            model, flat = with_used_rewards(model, used), with_used_rewards(flat, used)
    stages = stages_of(progress)
    with watch.stage("build"):
        tell_building(stages)
        exact = _build_exact(model, flat, constants, progress)
    dtmc = exact.dtmc
    workspace = Workspace()  # this run's caches: the float pre-pass of exact solves
    checks = _exact_checks(exact, resolved, workspace)
    with watch.stage("check"):
        results, undefined = run_checks(checks, resolved, dtmc, options, stages)
        aside_results = internal_results(dtmc, aside, [may_hold(dtmc, p) for p in aside],
                                         workspace)
    return ModelCheckRun(dtmc, results, watch.seconds, dtmc.warnings + undefined,
                         internal=aside_results, workspace=workspace)


def _decided(
    model: Model, properties: Sequence[Property], props_file: PropertiesFile | None,
    constants: Mapping[str, Value | str] | None,
) -> tuple[Model, list[Property], PropertiesFile | None, FlatModel]:
    from veribattery.explore.exact.decided import flattened_exactly  # gmpy2 only when asked

    return flattened_exactly(model, properties, props_file, constants)


def _build_exact(
    model: Model, flat: FlatModel, constants: Mapping[str, Value | str] | None,
    progress: ProgressCallback | None,
) -> ExactDTMC:
    from veribattery.explore.exact.dtmc import build_exact  # gmpy2 only when asked

    return build_exact(model, flat, constants, progress)


def _exact_checks(exact: ExactDTMC, resolved: Sequence[Property],
                  workspace: Workspace) -> list[Callable[[], CheckResult]]:
    """A check per (decided, resolved) property on the exactly built *exact* model."""
    from veribattery.checker.exact import check_exact  # gmpy2 only when asked

    return [functools.partial(check_exact, exact, p, workspace=workspace) for p in resolved]
