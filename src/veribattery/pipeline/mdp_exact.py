"""An ``mdp`` model checked in exact rational arithmetic (``--exact``): the MDP built with
rational probabilities and rewards, each property checked by exact policy iteration or
exact Bellman rounds (:mod:`~veribattery.checker.mdp.exact_pctl`)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from veribattery.checker.mdp.operators import require_checkable
from veribattery.lang import (
    Model,
    PropertiesFile,
    Property,
    resolve_property,
    with_used_rewards,
)
from veribattery.lang.nodes import Value
from veribattery.pipeline.mdp import MdpCheckRun, as_checker_mdp, ill_posed_errors
from veribattery.pipeline.run import (
    STAGES,
    ProgressCallback,
    Rewards,
    Stopwatch,
    stages_of,
    tell_building,
    tell_checking,
)

__all__ = ["check_mdp_model_exact"]


def check_mdp_model_exact(
    model: Model,
    properties: Sequence[Property],
    *,
    props_file: PropertiesFile | None = None,
    constants: Mapping[str, Value | str] | None = None,
    progress: ProgressCallback | None = None,
    stopwatch: Stopwatch | None = None,
    rewards: Rewards = "all",
) -> MdpCheckRun:
    """:func:`~veribattery.pipeline.mdp.check_mdp_model` in exact rational arithmetic:
    each result is an :class:`~veribattery.checker.exact.ExactCheckResult`.

    The MDP is built with its guards decided exactly and its probabilities and rewards
    as rationals; bounds such as ``P>=1/3`` are evaluated exactly from the properties
    as written. The optimal values come with a strategy whose optimality is verified
    in rationals (:mod:`~veribattery.checker.mdp.exact`). *rewards*: ``"named"`` builds
    only the reward structures the properties read.

    :raises CheckError: for an operator without an exact MDP kernel (multi-objective
        queries, a filter inside an expression, arithmetic on an infinite reward).
    :raises ModelError: for a probability or reward without an exact rational value.
    """
    from veribattery.checker.mdp.exact_pctl import (
        ExactMdpModel,
        check_mdp_exact,
        require_exact_kernel,
    )
    from veribattery.explore.exact.decided import flattened_exactly
    from veribattery.explore.exact.mdp import build_exact_mdp

    watch = stopwatch or Stopwatch(*STAGES)
    with watch.stage("parse"):
        model, properties, props_file, flat = flattened_exactly(model, properties,
                                                                props_file, constants)
        resolved = [resolve_property(p, flat, props_file, constants) for p in properties]
        for prop in resolved:
            require_checkable(prop.formula)  # P=?, S: refused before the build
            require_exact_kernel(prop.formula)
        if rewards == "named":  # (cut alike: the exact builder pairs their structures)
            model, flat = with_used_rewards(model, resolved), with_used_rewards(flat, resolved)
    stages = stages_of(progress)
    with watch.stage("build"):
        tell_building(stages)
        exact = build_exact_mdp(model, flat, constants, progress)
        mdp = as_checker_mdp(exact.built)
    results = []
    errors: list[str] = []
    with watch.stage("check"):
        checked = ExactMdpModel(mdp, exact)
        for number, prop in enumerate(resolved, 1):
            tell_checking(stages, number, len(resolved), prop)
            results.append(check_mdp_exact(checked, prop))
            errors.extend(ill_posed_errors(mdp, results[-1]))
    return MdpCheckRun(mdp, tuple(results), watch.seconds, exact.built.warnings,
                       errors=tuple(errors))

