"""The mission facade: config → rendered PRISM text → the same pipeline as any user file."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager, suppress
from dataclasses import dataclass, replace
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING

from veribattery._files import write_texts
from veribattery.checker import CheckResult, check
from veribattery.config import MissionConfig, Requirement, config_to_yaml, derive_parameters
from veribattery.errors import Span, VeribatteryError
from veribattery.explore.dtmc import DTMC
from veribattery.lang import (
    flatten_model,
    parse_model,
    parse_properties,
    parse_property,
    resolve_property,
)
from veribattery.lang.expressions import walk
from veribattery.lang.nodes import (
    BOUND_RELATIONS,
    Conditional,
    ConditionalReach,
    ConstDecl,
    Expr,
    LabelRef,
    Model,
    ProbOp,
    PropertiesFile,
    Property,
    RewardBounded,
    RewardOp,
    Value,
)
from veribattery.lang.property_rules import STEPS_REWARD
from veribattery.lang.semantics import BUILTIN_LABELS
from veribattery.pipeline import ModelCheckRun, ProgressCallback, ReusingBuilder, check_model

if TYPE_CHECKING:
    from veribattery.explore.lumping import Lumper

MODEL_FILE = "model.prism"
#: The properties PRISM and Storm both read.
PROPERTIES_FILE = "properties.props"
#: The properties in Storm's extensions of PRISM's property language (see
#: :func:`is_storm_only`): named so that nobody gives it to PRISM.
STORM_ONLY_FILE = "storm-only.props"
CONFIG_FILE = "config.resolved.yaml"
#: Every file ``emit`` writes, in the order it lists them.
EMITTED_FILES = (MODEL_FILE, PROPERTIES_FILE, STORM_ONLY_FILE, CONFIG_FILE)

_BOTH_HEADER = f"""\
// PRISM and Storm both read this file:
//   prism {MODEL_FILE} {PROPERTIES_FILE}
//   storm --prism {MODEL_FILE} --prop {PROPERTIES_FILE}
// The properties in Storm's own syntax are in {STORM_ONLY_FILE}.
"""
_STORM_HEADER = f"""\
// Storm only: do not give this file to PRISM. Its properties use Storm's extensions
// of PRISM's property language (conditional ||, reward bounds F{{"r"}}<=T, T=?),
// which PRISM does not parse. Check them with
//   storm --prism {MODEL_FILE} --prop {STORM_ONLY_FILE}
// or `veribattery check {CONFIG_FILE}`. The properties they refer to by name are
// repeated from {PROPERTIES_FILE}, so that Storm reads this file alone.
"""
_NO_PROPERTIES = "// (None of this config's properties is of this kind.)\n"
#: The source name :func:`~veribattery.lang.parse_property` gives its spans.
_FORMULA = "<property>"

#: The recharge-cap warning is given from this probability on: below it the cut cannot
#: change a printed (6 significant digit) result (model-spec.md, Battery ``oob`` row).
RECHARGE_CAP_WARN_AT = 1e-9


@dataclass(frozen=True, slots=True)
class RequirementOutcome:
    """A requirement and whether the checked value meets it."""

    requirement: Requirement
    value: Value
    holds: bool
    #: False when the certified interval straddles the bound (then *holds* is False).
    decided: bool = True

    def as_dict(self) -> dict[str, object]:
        """JSON-ready form."""
        return {"requirement": str(self.requirement), "property": self.requirement.prop,
                "value": self.value, "holds": self.holds, "decided": self.decided}


@dataclass(frozen=True, slots=True)
class MissionReport:
    """The verification of one mission config: the run, named values, requirement outcomes."""

    config: MissionConfig
    run: ModelCheckRun
    requirements: tuple[RequirementOutcome, ...]
    warnings: tuple[str, ...]
    #: P[F rc=RC_MAX]: the probability that the recharge cap cuts the mission (model-spec,
    #: ``oob`` row); always reported in machine-readable output, warned about from
    #: :data:`RECHARGE_CAP_WARN_AT` on.
    recharge_cap_probability: float

    @property
    def reused(self) -> bool:
        """True when an earlier config's state space was re-used (see :class:`MissionChecker`)."""
        return self.run.reused

    @property
    def values(self) -> dict[str, Value]:
        """Property name → value at the initial state, in config order."""
        return {r.property.name or r.property.text: r.value for r in self.run.results}

    @property
    def all_requirements_hold(self) -> bool:
        """True when every requirement holds (vacuously true without requirements)."""
        return all(outcome.holds for outcome in self.requirements)


@dataclass(frozen=True, slots=True)
class MissionFiles:
    """The emitted texts: the PRISM model, the properties PRISM and Storm both read,
    those only Storm reads, and the resolved config."""

    model: str
    properties: str
    storm_only: str
    config: str

    def as_mapping(self) -> Mapping[str, str]:
        """File name → text."""
        texts = (self.model, self.properties, self.storm_only, self.config)
        return dict(zip(EMITTED_FILES, texts, strict=True))


def mission_files(cfg: MissionConfig) -> MissionFiles:
    """Render the model and properties of *cfg*, the properties validated first and
    split by dialect (:func:`is_storm_only`). Rendering needs Jinja: imported late.

    :raises ConfigError: for a bad property (see :func:`validate_properties`).
    """
    from veribattery.render import render_model

    model = render_model(cfg)
    parsed = parse_model(model, name=MODEL_FILE)
    both, storm = _dialects(validate_properties(cfg, parsed), _label_names(parsed))
    return MissionFiles(model, _properties_file(_BOTH_HEADER, cfg, both),
                        _properties_file(_STORM_HEADER, cfg, storm), config_to_yaml(cfg))


def _properties_file(header: str, cfg: MissionConfig, formulas: dict[str, str]) -> str:
    """*header*, then *cfg*'s properties file holding only *formulas*."""
    from veribattery.render import render_properties

    text = render_properties(cfg.model_copy(update={"properties": formulas}))
    return header + "\n" + text + ("" if formulas else _NO_PROPERTIES)


def validate_properties(cfg: MissionConfig, model: Model | None = None) -> PropertiesFile:
    """*cfg*'s properties, each parsed alone and resolved against its model (*model*,
    or rendered here): every problem is found before a state space is built.

    :raises ConfigError: for the first property that does not parse, is unsupported,
        or names a label, reward structure or identifier the model lacks. It names the
        config key, placed in the config file or at the ``--set`` it came from, e.g.
        ``case1.yaml:12:16: properties.bad: unknown label "nosuch" (known labels: ...)``.
    """
    if model is None:
        from veribattery.render import render_model

        model = parse_model(render_model(cfg), name=MODEL_FILE)
    properties = tuple(_config_property(cfg, name) for name in cfg.properties)
    props = PropertiesFile((), (), properties, PROPERTIES_FILE)
    flat = flatten_model(model)
    for prop in properties:
        with _placed(cfg, str(prop.name)):
            resolve_property(prop, flat, props)
    return props


def _config_property(cfg: MissionConfig, name: str) -> Property:
    with _placed(cfg, name):
        prop = parse_property(cfg.properties[name])
    if prop.name is not None:
        raise cfg.property_error(
            name, f'the key names the property: write the formula without "{prop.name}":',
            Span(1, 1, _FORMULA))
    return replace(prop, name=name)


@contextmanager
def _placed(cfg: MissionConfig, name: str) -> Iterator[None]:
    """Errors in property *name*'s formula, placed in *cfg* (one line: no caret)."""
    try:
        yield
    except VeribatteryError as exc:
        at = exc.span if exc.span is not None and exc.span.source == _FORMULA else None
        raise cfg.property_error(name, exc.message.split("\n")[0], at) from None


def is_storm_only(formula: object) -> bool:
    """Whether *formula* uses one of Storm's extensions of PRISM's property language,
    which PRISM does not parse: a conditional ``||``, a reward bound ``F{"r"}<=T``, or
    the ``T=?`` operator."""
    return any(
        isinstance(node, Conditional | ConditionalReach | RewardBounded)
        or (isinstance(node, RewardOp) and node.reward == STEPS_REWARD)
        for node in walk(formula)
    )


def _dialects(
    props: PropertiesFile, labels: frozenset[str]
) -> tuple[dict[str, str], dict[str, str]]:
    """The formulas PRISM and Storm both read, and those for Storm alone, by name.

    A property that refers by name to a Storm-only one is Storm-only too; the Storm
    file also holds the properties its own refer to, so that it reads alone.
    """
    named = {str(p.name): p for p in props.properties}
    refs = {name: _references(p, named.keys() - labels) for name, p in named.items()}
    storm = {name for name, p in named.items() if is_storm_only(p.formula)}
    while grown := {name for name in named.keys() - storm if refs[name] & storm}:
        storm |= grown
    needed = set(storm)
    while grown := set().union(*(refs[name] for name in needed)) - needed:
        needed |= grown
    return ({name: p.text for name, p in named.items() if name not in storm},
            {name: p.text for name, p in named.items() if name in needed})


def _references(prop: Property, names: set[str]) -> set[str]:
    """The properties among *names* that *prop* refers to as ``"name"``."""
    return {node.name for node in walk(prop.formula)
            if isinstance(node, LabelRef) and node.name in names}


def _label_names(model: Model) -> frozenset[str]:
    """The labels a ``"name"`` in a property means before any property of that name."""
    return frozenset(label.name for label in model.labels) | BUILTIN_LABELS


def check_mission(
    cfg: MissionConfig, *, progress: ProgressCallback | None = None, exact: bool = False,
    keep_states: bool = True,
) -> MissionReport:
    """Render *cfg*, parse and check the text like any PRISM file, and judge the requirements.

    :param exact: check in exact rational arithmetic and judge requirements exactly.
    :param keep_states: keep each result's per-state values and bounds (False: only the
        answers, see :meth:`CheckResult.without_states`; the CLI needs no more).
    """
    return _check(cfg, progress, None, exact=exact, keep_states=keep_states)


def _check(
    cfg: MissionConfig,
    progress: ProgressCallback | None,
    builder: ReusingBuilder | None,
    parsed: _Parsed | None = None,
    *,
    exact: bool = False,
    keep_states: bool = True,
    values_only: bool = False,
    lumper: Lumper | None = None,
) -> MissionReport:
    from veribattery.render import render_model, render_properties

    parsed = parsed or _Parsed()
    model = parsed.model(render_model(cfg))  # not mission_files: no config YAML needed
    parsed.validate(cfg, model)
    props = parsed.properties(render_properties(cfg))
    modes = (exact, keep_states, values_only)
    run = _check_properties(model, props, progress, (builder, lumper), modes,
                            lambda dtmc: _recharge_cap_formulas(dtmc, cfg))
    return mission_report(cfg, run)


def mission_report(cfg: MissionConfig, run: ModelCheckRun) -> MissionReport:
    """The report of a finished *run* of *cfg*: requirements judged, recharge cap measured."""
    results = {r.property.name: r for r in run.results}
    outcomes = tuple(_judge(req, results) for req in cfg.parsed_requirements)
    cap = recharge_cap_probability(run, cfg)
    return MissionReport(cfg, run, outcomes, run.warnings + _recharge_cap_warning(cap, cfg), cap)


def _check_properties(model: Model, props: PropertiesFile, progress: ProgressCallback | None,
                      reuse: tuple[ReusingBuilder | None, Lumper | None],
                      modes: tuple[bool, bool, bool],
                      checked_after: Callable[[DTMC], Sequence[Expr]]) -> ModelCheckRun:
    """Check every property; a property without a value here (the conditional defaults
    of a mission that never succeeds, or under ``--exact``) is NaN with a warning
    instead of stopping the whole check (and a sweep). *reuse*: the builder and lumper,
    if any; *modes*: exact, keep_states, values_only."""
    exact, keep_states, values_only = modes
    return check_model(model, props.properties, props_file=props, progress=progress,
                       builder=reuse[0], exact=exact, undefined_ok=True,
                       keep_states=keep_states, values_only=values_only,
                       checked_after=checked_after, lumper=reuse[1])


def is_conditional(formula: object) -> bool:
    """Whether *formula* is a conditional (``||``) P or R query."""
    return isinstance(formula, ProbOp | RewardOp) and isinstance(
        formula.path, Conditional | ConditionalReach)


def mission_dtmc(cfg: MissionConfig, *, progress: ProgressCallback | None = None) -> DTMC:
    """Render *cfg* and build its DTMC, checking no property (for the analyses)."""
    files = mission_files(cfg)
    return check_model(parse_model(files.model, name=MODEL_FILE), (), progress=progress).dtmc


class MissionChecker:
    """Checks mission configs one after another, for sweeps, re-using state spaces.

    When a config's model shares the structure of the last one built in full --
    the varied keys change only transition probabilities, not which transitions
    exist (e.g. ``environment.p_wsp_c`` strictly inside (0, 1)) -- the state space
    is kept and only probabilities, rewards and labels are evaluated again before
    solving; :attr:`MissionReport.reused` says which way each config ran. Configs
    with equal :func:`reuse_key` share one state space unless a probability
    becomes 0 or 1 at one of them; order points by key to build each space once.
    """

    def __init__(self, *, values_only: bool = False, reuse: bool = True,
                 lump: bool | None = None) -> None:
        """:param values_only: the reports' DTMCs need only the reward structures the
            properties use (a sweep keeps values, not models): the others are not built.
        :param reuse: keep each full build's structure for the configs after it. False
            for a checker that checks one config (a sweep task of one point): it then
            builds as :func:`check_mission` does, without the pass that records every
            branch's kind for re-pricing (a tenth of a build), which it would never use.
        :param lump: check on each DTMC's bisimulation quotient where it has one
            (:mod:`veribattery.explore.lumping`; values only). Default: with
            *values_only* and *reuse* (many points of one structure). A sweep decides it
            per run of points sharing a state space, so that a point's values do not
            depend on how the run was cut into tasks.
        """
        self._values_only = values_only
        self._builder = ReusingBuilder() if reuse else None
        if lump is None:
            lump = values_only and reuse
        self._lumper = None
        if lump and values_only:  # sweeps only: a single check never imports lumping
            from veribattery.explore.lumping import Lumper

            self._lumper = Lumper()
        # One parse cache per process: a sweep's workers check one task after another,
        # and consecutive points' texts differ in a constant or two (see _Parsed).
        self._parsed = _PARSES

    def check(
        self, cfg: MissionConfig, *, progress: ProgressCallback | None = None
    ) -> MissionReport:
        """Check *cfg* as :func:`check_mission` does: the same values, to the last bit
        unless checked on a quotient (then within a few ulps, inside the same bounds)."""
        return _check(cfg, progress, self._builder, self._parsed,
                      keep_states=not self._values_only, values_only=self._values_only,
                      lumper=self._lumper)


class _Parsed:
    """The last model and properties texts parsed, to parse only what changed.

    Grid points of a sweep render texts that differ only in comments and constant
    declarations; those declarations are parsed alone (at their own line, so
    positions stay right) and replace the old ones. Anything else: a full parse.
    """

    def __init__(self) -> None:
        self._model: tuple[str, Model] | None = None
        self._props: tuple[str, PropertiesFile] | None = None
        #: Counts full parses: a model from _reparse differs in constant values only.
        self._shapes = 0
        self._validated: tuple[int, tuple[tuple[str, str], ...]] | None = None

    def model(self, text: str) -> Model:
        model = None if self._model is None else _reparse(*self._model, text)
        if model is None:
            model = parse_model(text, name=MODEL_FILE)
            self._shapes += 1
        self._model = (text, model)
        return model

    def validate(self, cfg: MissionConfig, model: Model) -> None:
        """:func:`validate_properties`, skipped when neither the formulas nor the model's
        declarations changed since the last time (a sweep point varies numbers: the
        value-dependent checks, bounds from constants, are left to the check itself)."""
        key = (self._shapes, tuple(cfg.properties.items()))
        if key != self._validated:
            validate_properties(cfg, model)
            self._validated = key

    def properties(self, text: str) -> PropertiesFile:
        if self._props is None or self._props[0] != text:
            self._props = (text, parse_properties(text, name=PROPERTIES_FILE))
        return self._props[1]


#: The process's last parses, for reuse_key and every MissionChecker: a sweep asks for
#: the keys of, and checks, many similar configs in a row.
#: (Safe across threads: a parse is only re-used after checking its text.)
_PARSES = _Parsed()


def _reparse(old_text: str, old: Model, text: str) -> Model | None:
    """*old* with the constant declarations that changed from *old_text* to *text*, or None."""
    before, after = old_text.splitlines(), text.splitlines()
    if len(before) != len(after):
        return None
    decls = {}
    for i, (a, b) in enumerate(zip(before, after, strict=True)):
        if a == b or (_comment(a) and _comment(b)):
            continue
        new, was = _declaration(b, i), _declaration(a, i)
        if new is None or was is None or (new.name, new.type) != (was.name, was.type):
            return None
        decls[new.name] = new
    if not decls.keys() <= {c.name for c in old.constants}:
        return None
    return replace(old, constants=tuple(decls.get(c.name, c) for c in old.constants))


def _comment(line: str) -> bool:
    return line.lstrip().startswith("//")


def _declaration(line: str, index: int) -> ConstDecl | None:
    """The constant declared by *line* (line *index* + 1 of a model), if that is all it holds."""
    if not line.lstrip().startswith("const ") or index < 1:
        return None
    try:
        small = parse_model("dtmc" + "\n" * index + line, name=MODEL_FILE)
    except VeribatteryError:
        return None
    return small.constants[0] if small == _only(small.constants) else None


def _only(constants: tuple[ConstDecl, ...]) -> Model | None:
    """A model holding just one constant declaration (to compare a parse with)."""
    if len(constants) != 1:
        return None
    return Model("dtmc", constants, (), (), (), (), (), None, MODEL_FILE)


def reuse_key(cfg: MissionConfig) -> str | None:
    """A key equal for configs whose models may share one state space.

    Decided from the rendered model itself: the key digests the flattened model's
    variables, initial states, guards and assignments (every constant they use
    appears by value), and leaves out update probabilities, rewards and labels.
    Equal keys are necessary for re-use; :class:`MissionChecker` still falls back
    to a full build where a probability becomes 0 or 1.
    """
    from veribattery.explore.reuse import structure_key
    from veribattery.render import render_model

    model = _PARSES.model(render_model(cfg))
    return structure_key(flatten_model(model))


def _judge(requirement: Requirement,
           results: Mapping[str | None, CheckResult]) -> RequirementOutcome:
    """Decide *requirement* from the exact value or the certified interval, never from a
    rounded point value alone.

    With ``--exact`` the comparison is exact. Otherwise it holds only if it holds at
    both ends of ``[lower, upper]`` (the comparisons are monotone, so then everywhere
    between); it fails if it fails at both; otherwise it is undecided, which counts as
    not holding.
    """
    result = results[requirement.prop]
    value = result.value
    exact = getattr(result, "exact", None)
    if isinstance(exact, Fraction):
        return RequirementOutcome(requirement, value, BOUND_RELATIONS[requirement.op](
            exact, requirement.bound))
    if isinstance(value, bool) or math.isnan(value):
        return RequirementOutcome(requirement, value, False)
    ends = (value, value) if result.lower is None or result.upper is None else (
        result.lower, result.upper)
    verdicts = {requirement.holds(end) for end in ends}
    decided = len(verdicts) == 1
    return RequirementOutcome(requirement, value, decided and verdicts == {True}, decided)


def recharge_cap_probability(run: ModelCheckRun, cfg: MissionConfig) -> float:
    """P[F rc=RC_MAX] in *run*'s DTMC (0 without computing when no state reaches the cap)."""
    formulas = _recharge_cap_formulas(run.dtmc, cfg)
    return float(check(run.checked_dtmc, formulas[0], states=False).value) if formulas else 0.0


def _recharge_cap_formulas(dtmc: DTMC, cfg: MissionConfig) -> tuple[Expr, ...]:
    """The formula :func:`recharge_cap_probability` checks on *dtmc* (none when no state
    reaches the cap), also for the pipeline to prepare its linear systems with."""
    rc_max = derive_parameters(cfg).rc_max
    if dtmc.column("rc").max() < rc_max:
        return ()
    return (parse_property(f"P=? [ F rc={rc_max} ]").formula,)


def _recharge_cap_warning(probability: float, cfg: MissionConfig) -> tuple[str, ...]:
    """The spec's warning, only when the cut can change a printed result (P >= 1e-9)."""
    if probability < RECHARGE_CAP_WARN_AT:
        return ()
    return (recharge_cap_message(cfg.battery.max_recharges, probability),)


def recharge_cap_message(rc_max: int, probability: float, where: str = "") -> str:
    """The recharge-cap warning text (*where*: the sweep points concerned, if any)."""
    return (
        f"the recharge cap battery.max_recharges={rc_max} is reached with probability "
        f"{probability:.6g}{where}; those missions are cut (counted as failures)"
    )


def write_files(files: MissionFiles, directory: Path, *, force: bool = False) -> tuple[Path, ...]:
    """Write the emitted files into *directory*, all or nothing, modes from the umask.

    Existing files are never overwritten unless *force*; the files are staged under
    temporary names and renamed only when all are written
    (:func:`~veribattery._files.write_texts`), so a failure leaves no partial output,
    nor a directory created for it.
    """
    targets = {directory / name: text for name, text in files.as_mapping().items()}
    clashes = [str(p) for p in targets if p.exists()]
    if clashes and not force:
        raise VeribatteryError(
            f"{', '.join(clashes)} already exist(s); use --force to overwrite, or pick another -o"
        )
    created = [d for d in (directory, *directory.parents) if not d.exists()]
    directory.mkdir(parents=True, exist_ok=True)
    try:
        write_texts(targets)
    except BaseException:
        for folder in created:  # innermost first; each is empty unless someone else wrote
            with suppress(OSError):
                folder.rmdir()
        raise
    return tuple(targets)
