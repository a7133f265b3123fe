"""Where a config's keys were given, to name that place in an error about one.

A key is written in the config file (its line:col), given by ``--set`` (the error names
the option: the file may not hold the key at all), or set by a sweep's grid point (the
sweep names the point). A check across keys -- ``low <= high``, capacity a whole number
of resolutions -- could be fixed by changing any of them: :meth:`KeyOrigins.error` blames
the one the user gave last, not a key the user never wrote placed at its section's line.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import yaml

from veribattery.errors import ConfigError, Span

__all__ = ["KeyOrigins", "KeyPath", "key_text"]

#: A key path as pydantic reports it: ``('farm', 'route', 3)``.
KeyPath = tuple[str | int, ...]


def key_text(path: KeyPath) -> str:
    """``('farm', 'route', 3)`` → ``farm.route[3]``."""
    text = ""
    for part in path:
        text += f"[{part}]" if isinstance(part, int) else ("." if text else "") + part
    return text or "config"


@dataclass(frozen=True, slots=True, eq=False)
class KeyOrigins:
    """Where a config's keys were given: in the YAML tree *root* of the file *source*,
    by ``--set`` (*set_keys*), or by a sweep point (*varied*).

    Not part of the config's value: any two compare equal (as
    :class:`~veribattery.config.origin.PropertyOrigins`).
    """

    root: yaml.Node | None = None
    source: str = "<string>"
    set_keys: tuple[str, ...] = ()
    varied: tuple[str, ...] = ()

    def __eq__(self, other: object) -> bool:
        return isinstance(other, KeyOrigins)

    def __hash__(self) -> int:
        return 0

    def written_at(self, path: KeyPath) -> Span | None:
        """Where *path* is written in the file (or the deepest key of it that is); None
        when a ``--set`` gave it."""
        if any(_under(path, key) for key in self.set_keys):
            return None
        return _locate(self.root, path, self.source)

    def error(self, blames: Sequence[tuple[str | KeyPath, str]]) -> ConfigError:
        """A :class:`ConfigError` naming the key of *blames* (``(key, message)``, the
        message as it suits that key) the user gave: a ``--set`` one, else a sweep
        point's, else one written in the file, else the first; placed where it was given.
        """
        paths = [(_path(key), message) for key, message in blames]
        path, message = next(
            (blame for given in (self._by_set, self._by_point, self._in_file)
             for blame in paths if given(blame[0])), paths[0])
        key = self._by_set(path)
        if key is not None:
            return ConfigError(f"--set {key}: {message}")
        key = self._by_point(path)
        if key is not None or self.root is None:
            return ConfigError(f"{key or key_text(path)}: {message}")
        return ConfigError(f"{key_text(path)}: {message}",
                           _locate(self.root, path, self.source))

    def _by_set(self, path: KeyPath) -> str | None:
        """The key to name if a ``--set`` gave *path*, or a key in it."""
        return _given(path, self.set_keys)

    def _by_point(self, path: KeyPath) -> str | None:
        """The key to name if the sweep's point gave *path*, or a key in it."""
        return _given(path, self.varied)

    def _in_file(self, path: KeyPath) -> bool:
        node: yaml.Node | None = self.root
        for part in path:
            found = _child(node, part)
            if found is None:
                return False
            node = found[1]
        return True


def _path(key: str | KeyPath) -> KeyPath:
    return tuple(key.split(".")) if isinstance(key, str) else key


def _given(path: KeyPath, keys: tuple[str, ...]) -> str | None:
    """*path* itself when one of *keys* holds it; else the first of *keys* under it (a
    ``--set battery.consumption.energy_wh`` when the check blames the section)."""
    if any(_under(path, key) for key in keys):
        return key_text(path)
    return next((key for key in keys if _under(_path(key), key_text(path))), None)


def _under(path: KeyPath, key: str) -> bool:
    parts = tuple(key.split("."))
    return tuple(str(p) for p in path[: len(parts)]) == parts


def _locate(node: yaml.Node | None, path: KeyPath, source: str) -> Span | None:
    """Where *path* is written: the deepest key or list item of it found in the YAML."""
    mark = node.start_mark if node is not None else None
    for part in path:
        found = _child(node, part)
        if found is None:
            break
        mark, node = found
    return Span(mark.line + 1, mark.column + 1, source) if mark is not None else None


def _child(node: yaml.Node | None, part: str | int) -> tuple[Any, yaml.Node] | None:
    if isinstance(node, yaml.MappingNode):
        for key, value in node.value:
            if key.value == str(part):  # an int part: a key written as a number
                return key.start_mark, value
    if isinstance(node, yaml.SequenceNode) and isinstance(part, int) and part < len(node.value):
        item = node.value[part]
        return item.start_mark, item
    return None
