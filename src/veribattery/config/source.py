"""A config's text: decoded as UTF-8 and parsed as YAML, every problem placed at line:col.

YAML alone lets a key appear twice in a mapping (the last one wins, silently); a
config refuses that, naming both places. The document is composed once: its nodes
tell :mod:`veribattery.config.load` where each key is written.

Numbers are read without YAML 1.1's octal and base-60 forms, which YAML 1.2 dropped
too: ``010`` and ``1:05`` are text (PyYAML reads eight and sixty-five), so a typed
value is never silently another number; text where a number belongs is a config error.
"""

from __future__ import annotations

import math
import re
from typing import Any

import yaml

from veribattery._numbers import MAX_EXPONENT, OutOfRange, exact_number, out_of_range
from veribattery._text import decode_text
from veribattery.errors import ConfigError, Span

__all__ = ["MAX_VALUES", "NumberOutOfRange", "WrittenFloat", "compose", "construct", "decode",
           "yaml_error"]

#: The most values a config's aliases may expand to: an explicit route over the
#: largest farm (MAX_TURBINES) is some 300,000.
MAX_VALUES = 1_000_000
_MERGE_TAG = "tag:yaml.org,2002:merge"
_INT_TAG, _FLOAT_TAG = "tag:yaml.org,2002:int", "tag:yaml.org,2002:float"


class NumberOutOfRange(ConfigError):
    """A number too large or too long to read (see :mod:`veribattery._numbers`); the
    message names the key, :attr:`reason` says what is wrong without it."""

    def __init__(self, path: str, reason: str, span: Span | None) -> None:
        super().__init__(f"{path}: {reason}" if path else reason, span)
        self.reason = reason


class _ConfigLoader(yaml.SafeLoader):  # type: ignore[misc]
    """PyYAML's safe loader without YAML 1.1's octal and base-60 numbers (see the
    module's docstring)."""


_ConfigLoader.yaml_implicit_resolvers = {
    first: [(tag, pattern) for tag, pattern in resolvers if tag not in (_INT_TAG, _FLOAT_TAG)]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
_ConfigLoader.add_implicit_resolver(
    _INT_TAG, re.compile(r"^(?:[-+]?0b[0-1_]+|[-+]?(?:0|[1-9][0-9_]*)|[-+]?0x[0-9a-fA-F_]+)$"),
    list("-+0123456789"))
_ConfigLoader.add_implicit_resolver(
    _FLOAT_TAG, re.compile(r"^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+][0-9]+)?"
                           r"|\.[0-9][0-9_]*(?:[eE][-+][0-9]+)?"
                           r"|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$"),
    list("-+0123456789."))


def decode(data: bytes, source: str) -> str:
    """*data* as text; see :func:`veribattery._text.decode_text`.

    :raises ConfigError: at the first byte that is not UTF-8.
    """
    return decode_text(data, source, ConfigError)


def compose(text: str, source: str | None, prefix: str = "") -> yaml.Node | None:
    """The YAML node tree of *text* (None when it holds no document).

    :param source: the file's name, or None for a one-line ``--set`` value (then a
        duplicate key is placed by its columns, in the message).
    :param prefix: the dotted key *text* is the value of (a ``--set`` key), for messages.
    :raises ConfigError: on YAML syntax errors, on a key given twice in a mapping, and
        on aliases that expand past :data:`MAX_VALUES` values or into themselves.
    """
    try:
        loader = _ConfigLoader(text)
    except yaml.YAMLError as exc:  # the reader refuses control characters at once
        raise yaml_error(exc, text, source) from None
    try:
        root = loader.get_single_node()
        if root is not None:
            _Walk(source).size(root, prefix)
    except yaml.YAMLError as exc:
        raise yaml_error(exc, text, source) from None
    except RecursionError:  # PyYAML composes nested lists and mappings recursively
        mark = loader.get_mark()
        raise ConfigError("YAML nested too deeply: a config's lists and mappings nest a few "
                          "levels, not hundreds", Span(mark.line + 1, mark.column + 1, source)
                          if source is not None else None) from None
    finally:
        loader.dispose()
    return root


class WrittenFloat(float):
    """A YAML float that keeps the decimal it was written as (:attr:`text`): the nearest
    double of ``0.1000000000000000000001`` is 0.1's and of ``1.0e-330`` is 0, and an
    exact config value (:func:`~veribattery.config.exact.to_fraction`) reads the text."""

    __slots__ = ("text",)
    text: str


class _Constructor(yaml.constructor.SafeConstructor):  # type: ignore[misc]
    """PyYAML's safe constructor, its floats :class:`WrittenFloat`."""

    def construct_yaml_float(self, node: yaml.ScalarNode) -> float:
        value = super().construct_yaml_float(node)
        if not math.isfinite(value):  # .inf, .nan (a number too large is refused before)
            return float(value)
        written = WrittenFloat(value)
        written.text = str(self.construct_scalar(node)).replace("_", "")
        return written


_Constructor.add_constructor(_FLOAT_TAG, _Constructor.construct_yaml_float)
# A config written back (a sweep's points, ``emit``) keeps each float as it was written.
yaml.SafeDumper.add_representer(
    WrittenFloat, lambda dumper, value: dumper.represent_scalar(_FLOAT_TAG, value.text))


def construct(root: yaml.Node | None, text: str, source: str | None) -> Any:
    """The Python value of a node tree from :func:`compose` (floats :class:`WrittenFloat`)."""
    if root is None:
        return None
    try:
        return _Constructor().construct_document(root)
    except yaml.YAMLError as exc:
        raise yaml_error(exc, text, source) from None


def yaml_error(exc: yaml.YAMLError, text: str, source: str | None) -> ConfigError:
    """A :class:`ConfigError` for *exc*, at its line:col in *text* when known."""
    if isinstance(exc, yaml.reader.ReaderError):
        return ConfigError(
            f"YAML does not allow the control character U+{exc.character:04X}; remove it",
            _offset_span(text, exc.position, source),
        )
    problem = getattr(exc, "problem", None) or str(exc)
    context = getattr(exc, "context", None)
    message = f"YAML syntax error: {problem}" + (f" ({context})" if context else "")
    mark = getattr(exc, "problem_mark", None)
    if mark is None or source is None:
        return ConfigError(message)
    return ConfigError(message, Span(mark.line + 1, mark.column + 1, source))


def _offset_span(text: str, offset: int, source: str | None) -> Span | None:
    before = text[:offset]
    line, col = before.count("\n") + 1, offset - before.rfind("\n")
    return Span(line, col, source) if source is not None else None


class _Walk:
    """One walk over a composed YAML tree: a key written twice in a mapping is refused,
    and so is a tree whose aliases expand past :data:`MAX_VALUES` values.

    An alias is the very node its anchor names: nine aliases of a list of nine aliases
    of ... make a tree of 9^9 values from nine lines (a "billion laughs"). Each node is
    visited once, its expanded size remembered, so the walk is as long as the text.
    """

    def __init__(self, source: str | None) -> None:
        self.constructor = yaml.constructor.SafeConstructor()
        self.source = source
        self.sizes: dict[int, int] = {}  # id(node) -> values it expands to

    def size(self, node: yaml.Node, path: str) -> int:
        """The values *node* expands to (itself, and every value under it).

        :raises ConfigError: for a key given twice, an alias inside its own anchor, or
            an expansion past :data:`MAX_VALUES`.
        """
        known = self.sizes.get(id(node))
        if known == 0:
            raise self._error(f"the alias at '{path}' stands for a list or mapping that "
                              "holds it: a config cannot hold itself", node)
        if known is not None:
            return known
        if isinstance(node, yaml.ScalarNode) and node.tag in (_INT_TAG, _FLOAT_TAG):
            self._check_number(node, path)
        self.sizes[id(node)] = 0  # under way
        total = 1 + sum(self.size(child, where) for child, where in self._children(node, path))
        if total > MAX_VALUES:
            raise self._error(f"YAML aliases expand '{path or 'the config'}' to more than "
                              f"{MAX_VALUES:,} values: write the values out, or use fewer "
                              "aliases", node)
        self.sizes[id(node)] = total
        return total

    def _children(self, node: yaml.Node, path: str) -> list[tuple[yaml.Node, str]]:
        """*node*'s items, or its keys and values (a key given twice refused), with paths."""
        if isinstance(node, yaml.SequenceNode):
            return [(item, f"{path}[{index}]") for index, item in enumerate(node.value)]
        if not isinstance(node, yaml.MappingNode):
            return []
        seen: dict[object, yaml.Node] = {}
        children: list[tuple[yaml.Node, str]] = []
        for key, value in node.value:
            name = _key(key, self.constructor)
            dotted = f"{path}.{name}" if path else str(name)
            if name is not None and name in seen:
                raise _duplicate(dotted, seen[name], key, self.source)
            if name is not None:
                seen[name] = key
            children += [(key, dotted), (value, dotted)]
        return children

    def _check_number(self, node: yaml.ScalarNode, path: str) -> None:
        """Refuse a number beyond :data:`~veribattery._numbers.SIZE_RULE` before PyYAML
        reads it: an int of 5,000 digits is a traceback (Python's int/str limit), and
        ``1.0e-5000`` would read as 0 and ``1.0e5000`` as infinity."""
        text = node.value.strip()
        try:
            if text.lstrip("+-")[:2].lower() in ("0x", "0b"):  # no limit for these bases
                if abs(int(text.replace("_", ""), 0)) > 10**MAX_EXPONENT:
                    raise out_of_range(text)
            else:
                exact_number(text)
        except OutOfRange as exc:
            raise NumberOutOfRange(path, str(exc), self._span(node)) from None
        except ValueError:  # .inf, .nan: the schema says what it needs instead
            return

    def _error(self, message: str, node: yaml.Node) -> ConfigError:
        span = self._span(node)
        if span is None:
            return ConfigError(f"{message} (column {node.start_mark.column + 1})")
        return ConfigError(message, span)

    def _span(self, node: yaml.Node) -> Span | None:
        """Where *node* starts in the file (None in a one-line ``--set`` value)."""
        mark = node.start_mark
        return None if self.source is None else Span(mark.line + 1, mark.column + 1,
                                                      self.source)


def _key(node: yaml.Node, constructor: yaml.constructor.SafeConstructor) -> object:
    """A scalar key's value (``1`` and ``01`` are one key), or None for other keys."""
    if not isinstance(node, yaml.ScalarNode) or node.tag == _MERGE_TAG:
        return None
    try:
        value: object = constructor.construct_object(node)
    except yaml.YAMLError:
        return node.value
    return value if value.__hash__ is not None else node.value


def _duplicate(dotted: str, first: yaml.Node, again: yaml.Node, source: str | None
               ) -> ConfigError:
    was, mark = first.start_mark, again.start_mark
    if source is None:  # a one-line --set value: its columns say enough
        return ConfigError(f"duplicate key '{dotted}' at column {mark.column + 1} "
                           f"(first at column {was.column + 1}); give each key once")
    return ConfigError(
        f"duplicate key '{dotted}' (first at line {was.line + 1}, column {was.column + 1}); "
        "give each key once",
        Span(mark.line + 1, mark.column + 1, source),
    )
