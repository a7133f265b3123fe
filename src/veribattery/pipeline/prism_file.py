"""A user's PRISM file and its properties, picked by index, name or text, to results
(the ``veribattery prism`` command and :func:`veribattery.check_prism_file`)."""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from veribattery.checker import CheckResult
from veribattery.checker.result import require_keep
from veribattery.errors import ArgumentError, PrismSemanticError
from veribattery.lang import (
    Model,
    PropertiesFile,
    Property,
    is_index,
    parse_model,
    parse_properties,
    parse_property,
    select_properties,
)
from veribattery.lang.nodes import Value
from veribattery.pipeline.exact import check_model_exact
from veribattery.pipeline.inputs import reject_unknown_constants
from veribattery.pipeline.run import (
    STAGES,
    CheckOptions,
    Keep,
    ModelCheckRun,
    ProgressCallback,
    Stopwatch,
    require_rewards,
)
from veribattery.pipeline.undecided import settle_undecided

if TYPE_CHECKING:
    from veribattery.pipeline.mdp import MdpCheckRun
    from veribattery.pipeline.run import Rewards

__all__ = ["check_prism_file", "select"]


def select(
    props: PropertiesFile | None, selectors: Sequence[str]
) -> tuple[Property, ...]:
    """Properties picked by index, name or literal text (all of *props* if none given).

    :param props: the properties file, if any.
    :param selectors: 1-based indices, property names, or property text.
    :raises ArgumentError: for a selector that is no str (an int index, say).
    """
    for number, selector in enumerate(selectors or ()):  # None: none, as before
        if not isinstance(selector, str):
            raise ArgumentError.wrong_kind(f"selectors[{number}]", selector, "a str (a 1-based "
                                           "index, a name or a property's text)",
                                           repr(str(selector)))
    if not selectors:
        if props is None:
            raise PrismSemanticError("no property given: use --props FILE or --property "
                                     "TEXT (props_source= or selectors= from Python)")
        if not props.properties:  # else an empty table, as if every property held
            raise PrismSemanticError(f"{props.source}: no properties in the file; add "
                                     "one, or give --property TEXT (selectors= from Python)")
        return props.properties
    return tuple(p for s in selectors for p in _select_one(props, s))


def _supported(properties: Sequence[Property], model_type: str
               ) -> tuple[tuple[Property, ...], tuple[str, ...]]:
    """Split off properties outside the supported subset, with a warning for each.

    Checking a whole file should not fail for one ``filter(...)`` (or, on an MDP, one
    ``S``); a property the user picked by name, index or text still fails with the
    reason (resolve_property, or the MDP pipeline's check before the build).
    """
    reasons = [(p, _unsupported(p, model_type)) for p in properties]
    skipped = tuple(f"skipped {p.span}: unsupported property {p.text} ({reason})"
                    for p, reason in reasons if reason is not None)
    return tuple(p for p, reason in reasons if reason is None), skipped


def _unsupported(prop: Property, model_type: str) -> str | None:
    """Why *prop* cannot be checked on a model of *model_type*, or None."""
    if prop.unsupported is not None or model_type != "mdp":
        return prop.unsupported
    from veribattery.checker.mdp.operators import unsupported_on_mdp  # for MDPs only

    refusal = unsupported_on_mdp(prop.formula)
    return None if refusal is None else refusal.message


def _select_one(props: PropertiesFile | None, selector: str) -> tuple[Property, ...]:
    if props is not None and (is_index(selector) or _names_property(props, selector)):
        return select_properties(props, selector)
    return (parse_property(selector),)


def _names_property(props: PropertiesFile, name: str) -> bool:
    return any(p.name == name for p in props.properties)


def check_prism_file(
    model_source: str | Path,
    *,
    props_source: str | Path | None = None,
    selectors: Sequence[str] = (),
    constants: Mapping[str, Value | str] | None = None,
    progress: ProgressCallback | None = None,
    exact: bool = False,
    keep: Keep = "states",
    rewards: Rewards = "all",
    before_build: Callable[[str, Sequence[Property]], None] | None = None,
    stop_early: bool = False,
) -> ModelCheckRun | MdpCheckRun:
    """The ``veribattery prism`` pipeline: model file (and properties) to results.

    An ``mdp`` model is checked by :func:`~veribattery.pipeline.mdp.check_mdp_model`
    (*keep* is always answers), or with *exact* by
    :func:`~veribattery.pipeline.mdp_exact.check_mdp_model_exact`. In floating point, a
    bound the certified interval cannot decide is checked again in exact arithmetic
    (:func:`~veribattery.pipeline.undecided.settle_undecided`), and stays an
    :class:`~veribattery.checker.UndecidedResult` where the model has no exact form.

    :param model_source: a model file path, or PRISM text.
    :param props_source: a properties file path, or properties text.
    :param selectors: properties to check, by 1-based index, name or text (one str is
        one selector).
    :param constants: values of undefined constants (of the model or the properties);
        a name that neither declares is an error.
    :param exact: check in exact rational arithmetic (``--exact``:
        :func:`~veribattery.pipeline.check_model_exact`), else in floating point
        (:func:`~veribattery.pipeline.check_model`).
    :param keep: what each result keeps: ``"states"`` or ``"answers"`` (see
        :class:`~veribattery.pipeline.CheckOptions`).
    :param rewards: the reward structures built in floating point: ``"all"``, or
        ``"named"``, only those the properties use (see
        :class:`~veribattery.pipeline.Session`; an MDP's likewise).
    :param before_build: told the model type and the properties to check once they
        are parsed, before any state is built: it may raise to refuse the work (the
        CLI refuses a strategy export that cannot succeed).
    """
    require_keep(keep)
    require_rewards(rewards)
    if isinstance(selectors, str):  # one selector, not one per character
        selectors = (selectors,)
    watch = Stopwatch(*STAGES)
    with watch.stage("parse"):
        model = parse_model(model_source)
        props = parse_properties(props_source) if props_source is not None else None
        reject_unknown_constants(model, props, constants or {})
        chosen = select(props, selectors)
        skipped: tuple[str, ...] = ()
        if not selectors:
            chosen, skipped = _supported(chosen, model.model_type)
        if before_build is not None:
            before_build(model.model_type, chosen)
    if model.model_type == "mdp":
        mdp_run = _check_mdp(model, chosen, props, constants, progress, watch,
                             (exact, rewards, stop_early))
        return replace(mdp_run, warnings=skipped + mdp_run.warnings) if skipped else mdp_run
    from veribattery.pipeline.session import check_model  # the DTMC checker: for DTMCs only

    if exact:
        run = check_model_exact(model, chosen, props_file=props, constants=constants,
                                progress=progress, stopwatch=watch, options=CheckOptions(keep),
                                rewards=rewards)
    else:
        run = check_model(model, chosen, props_file=props, constants=constants,
                          progress=progress, stopwatch=watch,
                          options=CheckOptions(keep, report_undecided=True), rewards=rewards,
                          stop_early=stop_early)
        exact_check = functools.partial(_exact_dtmc_results, keep=keep)
        run = settle_undecided(run, chosen, exact_check, model, props, constants)
    return replace(run, warnings=skipped + run.warnings) if skipped else run


def _check_mdp(
    model: Model, chosen: Sequence[Property], props: PropertiesFile | None,
    constants: Mapping[str, Value | str] | None, progress: ProgressCallback | None,
    watch: Stopwatch, how: tuple[bool, Rewards, bool],
) -> MdpCheckRun:
    """An ``mdp`` model's run: exact, or in floats with undecided bounds settled exactly
    (*how*: ``exact``, ``rewards``, ``stop_early``)."""
    # The MDP engine is imported when a model is an MDP.
    from veribattery.pipeline.mdp import check_mdp_model
    from veribattery.pipeline.mdp_exact import check_mdp_model_exact

    exact, rewards, stop_early = how
    if exact:
        return check_mdp_model_exact(model, chosen, props_file=props, constants=constants,
                                     progress=progress, stopwatch=watch, rewards=rewards)
    run = check_mdp_model(model, chosen, props_file=props, constants=constants,
                          progress=progress, stopwatch=watch, rewards=rewards,
                          stop_early=stop_early)
    return settle_undecided(run, chosen, _exact_mdp_results, model, props, constants)


def _exact_dtmc_results(
    model: Model, properties: Sequence[Property], props: PropertiesFile | None,
    constants: Mapping[str, Value | str] | None, *, keep: Keep,
) -> tuple[CheckResult, ...]:
    return check_model_exact(model, properties, props_file=props, constants=constants,
                             options=CheckOptions(keep)).results


def _exact_mdp_results(
    model: Model, properties: Sequence[Property], props: PropertiesFile | None,
    constants: Mapping[str, Value | str] | None,
) -> tuple[CheckResult, ...]:
    from veribattery.pipeline.mdp_exact import check_mdp_model_exact

    return check_mdp_model_exact(model, properties, props_file=props,
                                 constants=constants).results
