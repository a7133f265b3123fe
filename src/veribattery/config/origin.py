"""Where a config's property formulas were written, to place an error found inside one.

The config package cannot parse a formula (that is :mod:`veribattery.lang`, above
it); whoever does reports a problem at a line:col of the formula, and
:meth:`PropertyOrigin.error` turns that into the place in the config file -- exact
when the formula's lines are the file's own (a plain or unescaped quoted one-line
scalar, or a literal ``|`` block), else the key's place and the column inside the
formula -- or names the ``--set`` the formula came from.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import yaml

from veribattery.errors import ConfigError, Span

__all__ = ["PropertyOrigin", "PropertyOrigins", "property_origins"]

_PROPERTIES = "properties"


@dataclass(frozen=True, slots=True)
class PropertyOrigin:
    """Where the formula of ``properties.<name>`` was written."""

    #: The dotted key, ``properties.p_success``.
    key: str
    #: The formula this origin is for (a config changed in code may hold another).
    text: str
    #: The key's place in the config file; None for a ``--set`` or a default.
    key_span: Span | None = None
    #: The file position of the formula's first character, when every line of the
    #: formula is written unchanged from there on in the file.
    start: Span | None = None
    #: True when the formula came from ``--set``.
    from_set: bool = False

    def error(self, message: str, at: Span | None) -> ConfigError:
        """A :class:`ConfigError` for *message* about the formula, *at* a line:col in it."""
        if at is not None and self.start is not None:
            span = Span(self.start.line + at.line - 1, self.start.col + at.col - 1,
                        self.start.source)
            return ConfigError(f"{self.key}: {message}", span)
        inside = "" if at is None else _inside(at)
        if self.from_set:
            return ConfigError(f"--set {self.key}: {inside}{message}")
        return ConfigError(f"{self.key}: {inside}{message}", self.key_span)


def _inside(at: Span) -> str:
    if at.line == 1:
        return f"column {at.col} of the formula: "
    return f"line {at.line}, column {at.col} of the formula: "


@dataclass(frozen=True, slots=True, eq=False)
class PropertyOrigins:
    """The origins of a config's formulas, by property name.

    Not part of the config's value: any two compare equal, so that configs saying
    the same thing are equal wherever they were written (as an AST node's span).
    """

    by_name: Mapping[str, PropertyOrigin] = field(default_factory=dict)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, PropertyOrigins)

    def __hash__(self) -> int:
        return 0

    def error(self, name: str, text: str, message: str, at: Span | None) -> ConfigError:
        """:meth:`PropertyOrigin.error` for the formula *text* of property *name*."""
        origin = self.by_name.get(name)
        if origin is None or origin.text != text:
            origin = PropertyOrigin(f"{_PROPERTIES}.{name}", text)
        return origin.error(message, at)


def property_origins(
    properties: Mapping[str, str], root: yaml.Node | None, written: tuple[str, str],
    overridden: Sequence[str],
) -> PropertyOrigins:
    """Where each of *properties* was written in the YAML *root* of *written*'s text
    (``(text, source)``), or by which of the *overridden* ``--set`` keys."""
    text, source = written
    origins: dict[str, PropertyOrigin] = {}
    nodes = _property_nodes(root)
    for name, formula in properties.items():
        key = f"{_PROPERTIES}.{name}"
        if _PROPERTIES in overridden or key in overridden:
            origins[name] = PropertyOrigin(key, formula, from_set=True)
        elif name in nodes:
            key_node, value = nodes[name]
            start = _start(value, formula, text.splitlines(), source)
            origins[name] = PropertyOrigin(key, formula, _span(key_node, source), start)
    return PropertyOrigins(origins)


def _property_nodes(root: yaml.Node | None) -> dict[str, tuple[yaml.Node, yaml.Node]]:
    """Property name → (key node, value node) under the document's ``properties``."""
    section = _value(root, _PROPERTIES)
    if not isinstance(section, yaml.MappingNode):
        return {}
    return {key.value: (key, value) for key, value in section.value
            if isinstance(key, yaml.ScalarNode)}


def _value(node: yaml.Node | None, name: str) -> yaml.Node | None:
    if isinstance(node, yaml.MappingNode):
        for key, value in node.value:
            if isinstance(key, yaml.ScalarNode) and key.value == name:
                return value
    return None


def _span(node: yaml.Node, source: str) -> Span:
    return Span(node.start_mark.line + 1, node.start_mark.column + 1, source)


def _start(node: yaml.Node, formula: str, lines: list[str], source: str) -> Span | None:
    """The file position of *formula*'s first character, if its lines are the file's."""
    if not isinstance(node, yaml.ScalarNode) or node.value != formula:
        return None
    mark = node.start_mark
    if node.style == "|":
        return _block_start(formula, lines, mark.line + 1, source)
    line = lines[mark.line] if mark.line < len(lines) else ""
    quote = node.style if node.style in ("'", '"') else ""
    col = mark.column + len(quote)
    if "\n" in formula or line[col : col + len(formula) + len(quote)] != formula + quote:
        return None
    return Span(mark.line + 1, col + 1, source)


def _block_start(formula: str, lines: list[str], first: int, source: str) -> Span | None:
    """Where a literal block's text starts (0-based *first* line), if it reads as written."""
    wanted = formula.split("\n")
    if wanted and wanted[-1] == "":
        wanted.pop()
    if not wanted or first + len(wanted) > len(lines) or not wanted[0]:
        return None
    indent = len(lines[first]) - len(lines[first].lstrip(" "))
    for offset, text in enumerate(wanted):
        written = lines[first + offset]
        if written[indent:] != text or (text and written[:indent].strip()):
            return None
    return Span(first + 1, indent + 1, source)
