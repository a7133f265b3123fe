"""YAML → :class:`MissionConfig`: read, apply ``--set`` overrides, validate; and back to YAML."""

from __future__ import annotations

import copy
import difflib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from fractions import Fraction
from pathlib import Path as FsPath
from typing import Any

import yaml
from pydantic import BaseModel

from veribattery.config.exact import fraction_to_decimal
from veribattery.config.origin import property_origins
from veribattery.config.params import derive_parameters
from veribattery.config.place import KeyOrigins, KeyPath
from veribattery.config.schema import MissionConfig, is_property_name
from veribattery.config.source import NumberOutOfRange, compose, construct, decode
from veribattery.config.validate import known_keys, validate_config
from veribattery.errors import ArgumentError, ConfigError, Span

__all__ = ["ConfigDocument", "config_to_yaml", "key_problem", "load_config", "parse_override",
           "read_config", "require_config", "set_value"]

_PROPERTY_KEY = "properties."
#: The largest config file read (a mission config is a few kB).
MAX_CONFIG_BYTES = 16 << 20


def load_config(path_or_text: str | FsPath, overrides: Sequence[str] = ()) -> MissionConfig:
    """Load a mission config from a file (or YAML text), apply overrides, validate.

    A :class:`~pathlib.Path`, or a one-line string naming an existing file or ending
    in ``.yaml``/``.yml``, is read as a file; any other string is the YAML itself
    (so ``""`` is the paper's baseline).

    :param path_or_text: the config file, or its text.
    :param overrides: ``KEY=VALUE`` strings (``--set``); VALUE is parsed as YAML, so
        ``farm.base=[1,1]`` and ``battery.model=basic_high`` both work (one str is one
        override).
    :raises ConfigError: on unreadable files, YAML syntax errors (with line:col),
        malformed overrides and every validation problem.
    :raises ArgumentError: for a config neither a path nor text (a dict), or overrides
        that are no ``KEY=VALUE`` strings.
    """
    return read_config(path_or_text, overrides).validate()


def require_config(cfg: object) -> MissionConfig:
    """*cfg*, if it is a loaded mission config (what rendering and checking take).

    :raises ArgumentError: for anything else (a notebook's file name, its text or a
        dict), with the call that loads one.
    """
    if isinstance(cfg, MissionConfig):
        return cfg
    shown = repr(cfg) if len(repr(cfg)) <= 60 else "..."
    loads = shown if isinstance(cfg, str | FsPath) else "Path('mission.yaml') or YAML text"
    raise ArgumentError(f"a loaded mission config is needed, not {type(cfg).__name__} "
                        f"{shown}: give veribattery.load_config({loads})")


@dataclass(frozen=True, slots=True)
class ConfigDocument:
    """A config document as read, its ``--set`` overrides applied, not yet validated.

    A sweep reads and parses its config once, and validates each point's values set
    on it (:meth:`with_values`): every point's config, and every error in one, is what
    :func:`load_config` would make of the file with the point's keys given by ``--set``.
    """

    #: The document's data, overrides applied.
    data: dict[str, Any]
    #: The YAML node tree, to place errors in the file.
    root: yaml.Node | None
    #: The text and the name it was read under (a path, or ``<string>``).
    written: tuple[str, str]
    #: The dotted keys set by ``--set``: errors under them name the option.
    overridden: tuple[str, ...] = ()
    #: The dotted keys set by :meth:`with_values` (a sweep's point, which it names).
    varied: tuple[str, ...] = ()

    def with_values(self, values: Mapping[str, object]) -> ConfigDocument:
        """This document with *values* at their dotted keys, as ``--set`` would put them
        (each value as YAML loads it: lists, not tuples)."""
        data = self.data
        for key, value in values.items():
            data = set_value(data, key, value)
        return replace(self, data=data, varied=(*self.varied, *values))

    def span_of(self, path: KeyPath) -> Span | None:
        """Where the value at *path* (``("sweep", "vary", 0)``) is written in the file (or
        the deepest key of it that is); None when an override set it."""
        return KeyOrigins(self.root, self.written[1], self.overridden).written_at(path)

    def validate(self) -> MissionConfig:
        """The validated config.

        :raises ConfigError: naming the first bad key: placed in the file, or naming the
            ``--set`` that gave it (see :class:`~veribattery.config.place.KeyOrigins`).
        """
        origins = KeyOrigins(self.root, self.written[1], self.overridden, self.varied)
        cfg = validate_config(self.data, origins)
        cfg._key_origins = origins
        cfg._property_origins = property_origins(cfg.properties, self.root, self.written,
                                                 (*self.overridden, *self.varied))
        # The numbers the model's ints must hold, refused here rather than when the model
        # is rendered: a loaded config is one that renders, and a command fails before it
        # starts any work (its spinner, a sweep's first point).
        derive_parameters(cfg)
        return cfg


def read_config(path_or_text: str | FsPath, overrides: Sequence[str] = ()) -> ConfigDocument:
    """Read a config file (or YAML text) and apply overrides, without validating (see
    :func:`load_config`, which validates the result).

    :raises ConfigError: on unreadable files, YAML syntax errors (with line:col) and
        malformed overrides.
    :raises ArgumentError: for a config neither a path nor text, or overrides that are
        no ``KEY=VALUE`` strings.
    """
    if isinstance(overrides, str):  # one override, not one per character
        overrides = (overrides,)
    _require_overrides(overrides)
    text, source = _read(path_or_text)
    root = compose(text, source)
    data = _mapping(construct(root, text, source), source)
    overridden: list[str] = []
    for item in overrides:
        key, value = parse_override(item)
        data = set_value(data, key, value)
        overridden.append(key)
    return ConfigDocument(data, root, (text, source), tuple(overridden))


def _require_overrides(overrides: object) -> None:
    if isinstance(overrides, Mapping):
        raise ArgumentError.wrong_kind("overrides", overrides, "a list of KEY=VALUE strings",
                                       "[f'{key}={value}' for key, value in overrides.items()]")
    if not isinstance(overrides, Sequence):
        raise ArgumentError.wrong_kind("overrides", overrides, "a list of KEY=VALUE strings",
                                       "['strategy.safe_t=0.25']")
    for number, item in enumerate(overrides):
        if not isinstance(item, str):
            raise ArgumentError.wrong_kind(f"overrides[{number}]", item, "a KEY=VALUE string",
                                           "'strategy.safe_t=0.25'")


def _read(path_or_text: str | FsPath) -> tuple[str, str]:
    """The text to parse and the name to report it under."""
    if not isinstance(path_or_text, str | FsPath):
        fix = ("its YAML text: yaml.safe_dump(config)" if isinstance(path_or_text, Mapping)
               else "Path('mission.yaml')")
        raise ArgumentError.wrong_kind("path_or_text", path_or_text,
                                       "a config file's Path or its YAML text", fix)
    if isinstance(path_or_text, FsPath) or _looks_like_path(path_or_text):
        path = FsPath(path_or_text)
        try:
            with path.open("rb") as stream:  # bounded: /dev/zero or a pipe may never end
                data = stream.read(MAX_CONFIG_BYTES + 1)
        except OSError as exc:
            raise ConfigError(f"cannot read config {str(path)!r}: {exc.strerror}") from None
        if len(data) > MAX_CONFIG_BYTES:
            raise ConfigError(f"config {str(path)!r}: more than {MAX_CONFIG_BYTES >> 20} MB; "
                              "a mission config is a few kB of YAML")
        return decode(data, str(path)), str(path)
    return path_or_text, "<string>"


def _looks_like_path(text: str) -> bool:
    if "\n" in text or not text.strip():
        return False
    return text.endswith((".yaml", ".yml")) or FsPath(text).is_file()


def _mapping(data: object, source: str) -> dict[str, Any]:
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError(f"config: must be a mapping of keys, got {type(data).__name__}",
                          Span(1, 1, source))
    return data


def parse_override(item: str) -> tuple[str, object]:
    """Split ``KEY=VALUE`` and parse VALUE as YAML.

    :raises ConfigError: when ``=`` is missing, KEY is unknown or VALUE is not YAML.
    """
    key, sep, raw = item.partition("=")
    key = key.strip()
    if not sep or not key:
        raise ConfigError(f"--set {item!r}: expected KEY=VALUE, e.g. strategy.safe_t=0.25")
    problem = key_problem(key)
    if problem is not None:
        raise ConfigError(f"--set {item!r}: {problem}")
    if not raw.strip():
        return key, None
    try:
        value = construct(compose(raw, None, key), raw, None)
    except NumberOutOfRange as exc:
        raise ConfigError(f"--set {key}: {exc.reason}") from None
    except ConfigError as exc:
        raise ConfigError(f"--set {item!r}: value is not valid YAML: {exc.message}") from None
    return key, value


def key_problem(key: str) -> str | None:
    """Why the dotted *key* cannot be set (``--set``, a sweep's ``--vary``), or None: an
    unknown key (with the closest known one), or a property name that is no identifier."""
    if key.startswith(_PROPERTY_KEY):
        name = key.removeprefix(_PROPERTY_KEY)
        return None if is_property_name(name) else (
            f"property name {name!r} must be an identifier (letters, digits and _, not "
            "starting with a digit)")
    if key in known_keys():
        return None
    close = difflib.get_close_matches(key, known_keys(), n=1, cutoff=0.6)
    hint = f"did you mean '{close[0]}'?" if close else "see configs/example.yaml for the keys"
    return f"unknown key '{key}' ({hint})"


def set_value(cfg_dict: Mapping[str, Any], dotted_key: str, value: object) -> dict[str, Any]:
    """A copy of *cfg_dict* with *value* at *dotted_key* (``farm.base``), sections created.

    The input is left untouched, so a sweep can derive many configs from one base.
    """
    result: dict[str, Any] = copy.deepcopy(dict(cfg_dict))
    node = result
    *parents, leaf = dotted_key.split(".")
    for part in parents:
        child = node.get(part)
        if not isinstance(child, dict):
            child = {}
            node[part] = child
        node = child
    node[leaf] = value
    return result


def config_to_yaml(cfg: MissionConfig) -> str:
    """The resolved config as YAML (every key, defaults filled in); it loads back to *cfg*."""
    text: str = yaml.dump(
        _plain(cfg), Dumper=_Dumper, sort_keys=False, allow_unicode=True, width=100
    )
    return text


# libyaml's emitter (PyYAML's Python emitter is a port of it) writes the same text for
# four times less: a sweep dumps every point's config into its model's header and key.
_SafeDumper = getattr(yaml, "CSafeDumper", yaml.SafeDumper)


class _Dumper(_SafeDumper):  # type: ignore[misc,valid-type]
    """Block-style mappings; lists of scalars (cells) on one line, as a person writes them."""


def _represent_list(dumper: yaml.SafeDumper, data: list[Any]) -> yaml.Node:
    flow = all(not isinstance(item, dict | list) for item in data)
    return dumper.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=flow)


_Dumper.add_representer(list, _represent_list)


def _plain(value: object) -> object:
    """Models as dicts (less the fields their schema excludes at a value, see
    ``exclude_if``), fractions as decimals where exact (else ``"p/q"``), tuples as lists."""
    if isinstance(value, BaseModel):
        return {name: _plain(getattr(value, name))
                for name, info in type(value).model_fields.items()
                if info.exclude_if is None or not info.exclude_if(getattr(value, name))}
    if isinstance(value, Fraction):
        return _plain_fraction(value)
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    return value


def _plain_fraction(value: Fraction) -> int | float | str:
    if value.denominator == 1:
        return value.numerator
    decimal = fraction_to_decimal(value)
    if decimal is not None and repr(float(value)) == decimal:
        return float(value)
    return decimal if decimal is not None else f"{value.numerator}/{value.denominator}"

