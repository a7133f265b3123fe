"""The files ``emit`` writes for a mission: the PRISM model, the properties PRISM and Storm
both read, those only Storm reads, and the resolved config; and the check of a config's
properties against its model before anything is built."""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from contextlib import contextmanager, suppress
from dataclasses import dataclass, replace
from pathlib import Path

from veribattery._files import write_texts
from veribattery.config import MissionConfig, config_to_yaml, require_config
from veribattery.errors import Span, VeribatteryError
from veribattery.lang import flatten_model, parse_model, parse_property, resolve_property
from veribattery.lang.expressions import walk
from veribattery.lang.nodes import (
    Conditional,
    ConditionalReach,
    LabelRef,
    Model,
    PropertiesFile,
    Property,
    RewardBounded,
    RewardOp,
)
from veribattery.lang.property_rules import STEPS_REWARD
from veribattery.lang.semantics import BUILTIN_LABELS

__all__ = ["CONFIG_FILE", "EMITTED_FILES", "MODEL_FILE", "PROPERTIES_FILE", "STORM_ONLY_FILE",
           "MissionFiles", "is_storm_only", "mission_files", "placed_in_config",
           "validate_properties", "write_files"]

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


@dataclass(frozen=True, slots=True, repr=False)  # a short repr: see __repr__
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

    def __repr__(self) -> str:
        # Each text's size, not the text: the model alone is some 12,000 characters,
        # printed as one line of escaped newlines. print(files.model) shows it.
        sizes = ", ".join(f"{name}=<{len(text):,} characters>" for name, text in (
            ("model", self.model), ("properties", self.properties),
            ("storm_only", self.storm_only), ("config", self.config)))
        return f"MissionFiles({sizes})"


def mission_files(cfg: MissionConfig) -> MissionFiles:
    """Render the model and properties of *cfg*, the properties validated first and
    split by dialect (:func:`is_storm_only`). Rendering needs Jinja: imported late.

    :raises ConfigError: for a bad property (see :func:`validate_properties`).
    :raises ArgumentError: for anything but a loaded config (a file's name, say).
    """
    from veribattery.render import render_model

    cfg = require_config(cfg)
    cfg.require_bs1()
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


@contextmanager
def placed_in_config(cfg: MissionConfig, props: PropertiesFile) -> Iterator[None]:
    """Errors the check finds in the rendered properties file (``properties.props:8:14``,
    a file the user never wrote), placed where the property was written instead."""
    try:
        yield
    except VeribatteryError as exc:
        span = exc.span
        named = [p for p in props.properties if p.name in cfg.properties
                 and span is not None and span.source == PROPERTIES_FILE
                 and p.span.line <= span.line]
        if span is None or not named:
            raise
        prop = named[-1]
        line = span.line - prop.span.line + 1
        column = span.col - (prop.span.col - 1 + len(f'"{prop.name}": ') if line == 1 else 0)
        raise cfg.property_error(str(prop.name), exc.message.split("\n")[0],
                                 Span(line, max(column, 1), _FORMULA)) from None


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
