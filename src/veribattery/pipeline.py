"""The facade: text → parse → semantics → build → check, timed stage by stage.

Every front end runs models through :func:`check_model`: the ``prism`` command
and the Python API by way of :func:`check_prism_file`, the mission commands and
sweeps with the model they rendered and parsed. So a generated mission model is
checked by exactly the code that checks a user's own PRISM file.
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from veribattery._memory import trim_for
from veribattery.checker import CheckResult, check
from veribattery.checker.pctl import prepare
from veribattery.errors import PrismSemanticError, UndefinedResult
from veribattery.explore import DTMC, build_dtmc
from veribattery.lang import (
    FlatModel,
    Model,
    PropertiesFile,
    Property,
    flatten_model,
    parse_model,
    parse_properties,
    parse_property,
    resolve_property,
    select_properties,
    undefined_constants,
)
from veribattery.lang.expressions import walk
from veribattery.lang.nodes import Expr, Filter, Ident, RewardBounded, RewardOp, Value

if TYPE_CHECKING:
    from veribattery.explore.exact import ExactDTMC
    from veribattery.explore.lumping import Lumper
    from veribattery.explore.reuse import Structure

ProgressCallback = Callable[[int, int], None]


@dataclass(frozen=True, slots=True)
class ModelCheckRun:
    """What one run of the pipeline produced: the DTMC, one result per property, timings."""

    dtmc: DTMC
    results: tuple[CheckResult, ...]
    timings_s: dict[str, float]
    warnings: tuple[str, ...] = field(default=())
    #: True when the DTMC re-used an earlier model's state space (see :class:`ReusingBuilder`).
    reused: bool = False
    #: The bisimulation quotient the properties were checked on, if any (see *lumper*
    #: of :func:`check_model`); *dtmc* is always the model's own chain.
    quotient: DTMC | None = None

    @property
    def checked_dtmc(self) -> DTMC:
        """The chain the properties were checked on: the quotient, else the DTMC."""
        return self.quotient if self.quotient is not None else self.dtmc

    @property
    def model_summary(self) -> dict[str, int]:
        """Sizes as reported by ``--json``: states, transitions, initial states, deadlocks."""
        return {
            "states": self.dtmc.num_states,
            "transitions": self.dtmc.num_transitions,
            "initial_states": len(self.dtmc.initial),
            "deadlocks": self.dtmc.deadlocks,
        }


#: The stages of a check, always reported (``Time: parse …, build …, check …``).
_STAGES = ("parse", "build", "check")


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


class ReusingBuilder:
    """Builds DTMCs one after another, re-using the last state space where it can.

    When a model shares the structure of the last model built in full (the same
    variables, guards and assignments; see :mod:`veribattery.explore.reuse`), its
    probabilities, rewards and labels are evaluated on the known states instead of
    exploring them again; otherwise it is built in full and becomes the new base.
    """

    def __init__(self) -> None:
        self._base: tuple[DTMC, Structure] | None = None

    def build(self, flat: FlatModel, progress: ProgressCallback | None = None) -> tuple[DTMC, bool]:
        """The DTMC of *flat*, and whether it re-used the base's state space."""
        from veribattery.explore.reuse import build_reusable, reevaluate  # sweeps only

        if self._base is not None:
            dtmc = reevaluate(*self._base, flat)
            if dtmc is not None:
                return dtmc, True
        dtmc, structure = build_reusable(flat, progress=progress)
        self._base = (dtmc, structure)
        return dtmc, False


def select(
    props: PropertiesFile | None, selectors: Sequence[str]
) -> tuple[Property, ...]:
    """Properties picked by index, name or literal text (all of *props* if none given).

    :param props: the properties file, if any.
    :param selectors: 1-based indices, property names, or property text.
    """
    if not selectors:
        if props is None:
            raise PrismSemanticError("no property given: use --props FILE or --property TEXT")
        return props.properties
    return tuple(p for s in selectors for p in _select_one(props, s))


def _supported(properties: Sequence[Property]) -> tuple[tuple[Property, ...], tuple[str, ...]]:
    """Split off properties outside the supported subset, with a warning for each.

    Checking a whole file should not fail for one ``filter(...)``; a property the
    user picked by name, index or text still fails with the reason (resolve_property).
    """
    skipped = tuple(
        f"skipped {p.span}: unsupported property {p.text} ({p.unsupported})"
        for p in properties if p.unsupported is not None
    )
    return tuple(p for p in properties if p.unsupported is None), skipped


def _select_one(props: PropertiesFile | None, selector: str) -> tuple[Property, ...]:
    if props is not None and (selector.isdigit() or _names_property(props, selector)):
        return select_properties(props, selector)
    return (parse_property(selector),)


def _names_property(props: PropertiesFile, name: str) -> bool:
    return any(p.name == name for p in props.properties)


def check_model(
    model: Model,
    properties: Sequence[Property],
    *,
    props_file: PropertiesFile | None = None,
    constants: Mapping[str, Value | str] | None = None,
    progress: ProgressCallback | None = None,
    stopwatch: Stopwatch | None = None,
    exact: bool = False,
    builder: ReusingBuilder | None = None,
    undefined_ok: bool = False,
    keep_states: bool = True,
    values_only: bool = False,
    checked_after: Callable[[DTMC], Sequence[Expr]] | None = None,
    lumper: Lumper | None = None,
) -> ModelCheckRun:
    """Flatten *model*, build its DTMC and check each property at the initial states.

    :param exact: compute in exact rational arithmetic (results are
        :class:`~veribattery.checker.exact.ExactCheckResult`).
    :param builder: re-use the state space of earlier models where possible.
    :param undefined_ok: report a property that has no value on this model
        (:class:`~veribattery.errors.UndefinedResult`) as NaN with a warning,
        instead of failing the run.
    :param keep_states: keep each result's per-state values and bounds; False keeps
        only the answers (:meth:`CheckResult.without_states`), so that one property's
        per-state vectors are alive at a time (what the CLI prints needs no more).
    :param values_only: the caller needs the results, not the DTMC's other reward
        structures: those no property names are not built (a sweep point).
    :param checked_after: the formulas the caller will check on the returned DTMC
        (the mission's recharge-cap probability), so that the properties' linear
        systems are chosen to serve them too (:func:`~veribattery.checker.pctl.prepare`).
    :param lumper: check on the DTMC's bisimulation quotient when it has one worth
        checking on (answers only: without *keep_states*, never with *exact*); the
        answers equal the DTMC's, their last bits aside. A sweep passes one per run of
        points sharing a state space (:mod:`veribattery.explore.lumping`).
    """
    watch = stopwatch or Stopwatch(*_STAGES)
    with watch.stage("parse"):
        flat = flatten_model(model, constants)
        resolved = [resolve_property(p, flat, props_file, constants) for p in properties]
        if values_only and not exact:
            flat = _named_rewards_only(flat, resolved)
    exact_model = None
    with watch.stage("build"):
        if exact:  # guards decided exactly: its own exploration, never a re-used one
            exact_model = _build_exact(model, flat, constants, progress)
            dtmc, reused = exact_model.dtmc, False
        elif builder is None:
            dtmc, reused = build_dtmc(flat, progress=progress), False
        else:
            dtmc, reused = builder.build(flat, progress)
    if not (exact or keep_states or builder is not None):
        # Answers only, and the DTMC not handed to a re-using builder: nothing does
        # arithmetic on whole state rows, so the table can be narrow (65 -> 17 MB on
        # the 11x11 mission).
        dtmc = dtmc.compact()
    later = list(checked_after(dtmc)) if checked_after is not None and not exact else []
    quotient = None
    if lumper is not None and not (exact or keep_states):
        with watch.stage("lump"):
            quotient = _quotient(lumper, dtmc, [p.formula for p in resolved] + later)
    checked = quotient if quotient is not None else dtmc
    if exact_model is not None:
        checks = _exact_checks(exact_model, (properties, resolved), props_file, constants)
    else:
        checks = [functools.partial(check, checked, p, states=keep_states) for p in resolved]
    with watch.stage("check"):
        if exact_model is None:  # linear systems shared between the properties
            trim_for(dtmc.num_states)  # the builder's last temporaries, under the DTMC's
            prepare(checked, [p.formula for p in resolved] + later)
            trim_for(dtmc.num_states)  # the pre-pass's freed temporaries
        results, undefined = _run_checks(checks, resolved, checked, (undefined_ok, keep_states))
    return ModelCheckRun(dtmc, results, watch.seconds, dtmc.warnings + undefined, reused,
                         quotient)


def _quotient(lumper: Lumper, dtmc: DTMC, formulas: Sequence[Expr]) -> DTMC | None:
    """*dtmc*'s quotient for *formulas*: it keeps apart what their atoms read (labels and
    rewards always; the variables they name). None if a formula filters over states (a
    count or sum over them would change) or names something else."""
    variables: set[str] = set()
    for formula in formulas:
        for node in walk(formula):
            if isinstance(node, Filter):
                return None
            if isinstance(node, Ident):
                if node.name not in dtmc.variable_names:
                    return None
                variables.add(node.name)
    return lumper.quotient(dtmc, sorted(variables))


def _named_rewards_only(flat: FlatModel, properties: Sequence[Property]) -> FlatModel:
    """*flat* without the reward structures no property uses (all of them kept when a
    property refers to one by index or by default)."""
    names: set[str] = set()
    for prop in properties:
        for node in walk(prop.formula):
            if isinstance(node, RewardOp | RewardBounded):
                if not isinstance(node.reward, str):
                    return flat
                names.add(node.reward)
    kept = tuple(r for r in flat.rewards if r.name in names)
    return flat if len(kept) == len(flat.rewards) else replace(flat, rewards=kept)


def _run_checks(
    checks: Sequence[Callable[[], CheckResult]], resolved: Sequence[Property], dtmc: DTMC,
    options: tuple[bool, bool],
) -> tuple[tuple[CheckResult, ...], tuple[str, ...]]:
    """Run each property's check; with *undefined_ok*, a property without a value is NaN;
    without *keep_states*, each result is reduced to its answer as soon as it is made."""
    undefined_ok, keep_states = options
    results: list[CheckResult] = []
    warnings: list[str] = []
    for run_one, prop in zip(checks, resolved, strict=True):
        try:
            result = run_one()
            results.append(result if keep_states else result.without_states())
            del result  # before the next property: its per-state arrays can go now
            if not keep_states:
                trim_for(dtmc.num_states)
        except UndefinedResult as exc:
            if not undefined_ok:
                raise
            size = dtmc.num_states if keep_states else 0
            results.append(CheckResult(prop, np.full(size, np.nan), math.nan, 0.0))
            warnings.append(f"{prop.name or prop.text}: undefined (NaN): {exc.message}")
    return tuple(results), tuple(warnings)


def _build_exact(
    model: Model, flat: FlatModel, constants: Mapping[str, Value | str] | None,
    progress: ProgressCallback | None,
) -> ExactDTMC:
    from veribattery.explore.exact import build_exact  # gmpy2 only when asked

    return build_exact(model, flat, constants, progress)


def _exact_checks(
    exact: ExactDTMC,
    properties: tuple[Sequence[Property], Sequence[Property]],
    props_file: PropertiesFile | None,
    constants: Mapping[str, Value | str] | None,
) -> list[Callable[[], CheckResult]]:
    """A check per property on the exactly built *exact* model.

    *properties* are the properties as written and as resolved: bounds such as
    ``P<=1/3`` are evaluated exactly from the former.
    """
    from veribattery.checker.exact import check_exact, exact_bounds  # gmpy2 only when asked
    from veribattery.explore.rational import exact_constants

    given = dict(constants or {})
    decls = props_file.constants if props_file is not None else ()
    values = exact_constants(decls, given, outer=exact.constants)
    originals, resolved = properties
    return [
        functools.partial(check_exact, exact, p, exact_bounds(o.formula, values))
        for o, p in zip(originals, resolved, strict=True)
    ]


def check_prism_file(
    model_source: str | Path,
    *,
    props_source: str | Path | None = None,
    selectors: Sequence[str] = (),
    constants: Mapping[str, Value | str] | None = None,
    progress: ProgressCallback | None = None,
    exact: bool = False,
    keep_states: bool = True,
) -> ModelCheckRun:
    """The ``veribattery prism`` pipeline: model file (and properties) to results.

    :param model_source: a model file path, or PRISM text.
    :param props_source: a properties file path, or properties text.
    :param selectors: properties to check, by 1-based index, name or text.
    :param constants: values of undefined constants.
    :param exact: check in exact rational arithmetic (``--exact``).
    :param keep_states: keep per-state values and bounds (see :func:`check_model`).
    """
    watch = Stopwatch(*_STAGES)
    with watch.stage("parse"):
        model = parse_model(model_source)
        props = parse_properties(props_source) if props_source is not None else None
        _reject_unknown_constants(model, props, constants or {})
        chosen = select(props, selectors)
        skipped: tuple[str, ...] = ()
        if not selectors:
            chosen, skipped = _supported(chosen)
    run = check_model(
        model, chosen, props_file=props, constants=constants, progress=progress, stopwatch=watch,
        exact=exact, keep_states=keep_states,
    )
    return replace(run, warnings=skipped + run.warnings) if skipped else run


def _reject_unknown_constants(
    model: Model, props: PropertiesFile | None, constants: Mapping[str, object]
) -> None:
    """A ``--const`` that names no declared constant is a typo: say so, don't ignore it."""
    declared = {c.name for c in model.constants}
    declared |= {c.name for c in props.constants} if props is not None else set()
    unknown = sorted(set(constants) - declared)
    if unknown:
        hint = ", ".join(undefined_constants(model, props)) or "none"
        raise PrismSemanticError(
            f"--const {', '.join(unknown)}: no such constant (undefined constants: {hint})"
        )
