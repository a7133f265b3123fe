"""The last mission texts parsed, so that a sweep's next point parses only what changed."""

from __future__ import annotations

from dataclasses import replace

from veribattery.config import MissionConfig
from veribattery.errors import VeribatteryError
from veribattery.lang import parse_model, parse_properties
from veribattery.lang.nodes import ConstDecl, Model, PropertiesFile
from veribattery.mission.files import MODEL_FILE, PROPERTIES_FILE, validate_properties

__all__ = ["ParseCache", "reparse"]


class ParseCache:
    """The last model and properties texts parsed, to parse only what changed.

    Grid points of a sweep render texts that differ only in comments and constant
    declarations; those declarations are parsed alone (at their own line, so
    positions stay right) and replace the old ones. Anything else: a full parse.
    A sweep keeps one cache per process, for its points' reuse keys and checks one
    after another (see :class:`~veribattery.mission.MissionSession`).
    """

    def __init__(self) -> None:
        self._model: tuple[str, Model] | None = None
        self._props: tuple[str, PropertiesFile] | None = None
        #: Counts full parses: a model from reparse differs in constant values only.
        self._shapes = 0
        self._validated: tuple[int, tuple[tuple[str, str], ...]] | None = None

    def model(self, text: str) -> Model:
        """The model of *text* (a mission's rendered model)."""
        model = None if self._model is None else reparse(*self._model, text)
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
        """The properties file of *text* (a mission's rendered properties)."""
        if self._props is None or self._props[0] != text:
            self._props = (text, parse_properties(text, name=PROPERTIES_FILE))
        return self._props[1]


def reparse(old_text: str, old: Model, text: str) -> Model | None:
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

