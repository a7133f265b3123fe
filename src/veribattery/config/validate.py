"""Validation with one-line messages: pydantic's errors → ``key.path: what is allowed, got X``."""

from __future__ import annotations

import difflib
import functools
from collections.abc import Mapping
from typing import Any, get_args

from pydantic import BaseModel, ValidationError

from veribattery.config.exact import brief
from veribattery.config.place import KeyOrigins, KeyPath, key_text
from veribattery.config.schema import UNION_TAGS, MissionConfig

__all__ = ["Path", "dotted", "known_keys", "validate_config"]

#: A key path as pydantic reports it: ``('farm', 'route', 3)``.
Path = KeyPath


@functools.cache  # the schema is fixed; every --set and every sweep point asks
def known_keys() -> tuple[str, ...]:
    """Every dotted key of the schema (both consumption forms), sections included."""
    return tuple(sorted(set(_keys_of(MissionConfig, ""))))


def _keys_of(model: type[BaseModel], prefix: str) -> list[str]:
    keys: list[str] = []
    for name, info in model.model_fields.items():
        key = prefix + name
        keys.append(key)
        for sub in _submodels(info.annotation):
            keys.extend(_keys_of(sub, key + "."))
    return keys


def _submodels(annotation: object) -> list[type[BaseModel]]:
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    return [m for arg in get_args(annotation) for m in _submodels(arg)]


def dotted(path: Path) -> str:
    """``('farm', 'route', 3)`` → ``farm.route[3]``; union tags are dropped."""
    return key_text(_clean(path))


def _clean(path: Path) -> Path:
    return tuple(p for p in path if p not in UNION_TAGS or isinstance(p, int))


def _suggest(path: Path) -> str:
    key = dotted(path)
    if key in known_keys():  # valid in the other consumption form, not beside this one
        return (
            "cannot be mixed with the other form of battery.consumption: give either the "
            "table (takeoff_land, cell, inspection, high_wind_factor) or Eq. 2's parameters "
            "(energy_wh, voltages_v, flight_time_h, action_time_h)"
        )
    close = difflib.get_close_matches(key, known_keys(), n=1, cutoff=0.6)
    if close:
        return f"unknown key (did you mean '{close[0]}'?)"
    return f"unknown key (allowed: {_allowed(path)})"


def _allowed(path: Path) -> str:
    """The keys that may stand where the last key of *path* does."""
    parent = dotted(path[:-1]) + "." if len(path) > 1 else ""
    siblings = [k[len(parent) :] for k in known_keys() if k.startswith(parent)]
    return ", ".join(sorted({k.split(".")[0] for k in siblings}))


_TYPE_WORDS = {
    "int_type": "an integer",
    "string_type": "a string",
    "dict_type": "a mapping",
    "model_type": "a mapping of keys",
    "model_attributes_type": "a mapping of keys",
    "tuple_type": "a list",
}


def _describe(error: Mapping[str, Any]) -> list[tuple[Path, str]]:
    """The key path and the message of one pydantic error; for a check across keys,
    the other keys that would fix it, each with its message (see ``exact.problem``)."""
    path: Path = _clean(tuple(error["loc"]))
    ctx = error.get("ctx") or {}
    if error["type"] == "vb_problem":
        return [(path + _subkey(key), str(message)) for key, message in
                ((ctx.get("key", ""), ctx["message"]), *ctx.get("others", ()))]
    return [_described(path, error)]


def _subkey(key: str) -> Path:
    return tuple(int(p) if p.isdigit() else p for p in key.split(".")) if key else ()


def _described(path: Path, error: Mapping[str, Any]) -> tuple[Path, str]:
    """The key path and message of a pydantic error of its own kind."""
    kind, given = error["type"], brief(error["input"])
    ctx = error.get("ctx") or {}
    if kind == "invalid_key" and path:  # YAML allows 1: or ~: as a key; a config does not
        path = (*path[:-1], str(path[-1]))
        return path, f"a key must be a name, got {given} (allowed: {_allowed(path)})"
    if path and path[-1] == "[key]" and len(path) > 1:  # a dict's key (properties: {1: ...})
        return (*path[:-2], str(path[-2])), f"a key must be a name, got {given}"
    if kind == "extra_forbidden":
        return path, _suggest(path)
    if kind == "literal_error":
        return path, f"must be one of {ctx['expected']}, got {given}"
    if kind in _TYPE_WORDS:
        return path, f"must be {_TYPE_WORDS[kind]}, got {given}"
    return path, str(error["msg"])


def validate_config(data: object, origins: KeyOrigins | None = None) -> MissionConfig:
    """Validate a parsed YAML document into a :class:`MissionConfig`.

    :param data: the document (``None`` for an empty file).
    :param origins: where each key was given, to place the error.
    :raises ConfigError: naming the first bad key, e.g.
        ``strategy.safe_t: must be in (0, 1), got 1.5``.
    """
    origins = origins or KeyOrigins()
    if data is None:
        data = {}
    if not isinstance(data, Mapping):
        raise origins.error([((), f"must be a mapping of keys, got {brief(data)}")])
    try:
        return MissionConfig.model_validate(data)
    except ValidationError as exc:
        errors = exc.errors(include_url=False)
        more = f" (and {len(errors) - 1} more problem(s))" if len(errors) > 1 else ""
        raise origins.error([(path, message + more) for path, message
                             in _describe(errors[0])]) from None
