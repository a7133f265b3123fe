"""Config → PRISM text: the DTMC of model-spec.md and its properties file.

Templates live in the top-level ``prism_templates/`` folder, which the wheel ships as
``veribattery/prism_templates``. They only lay out numbers that
:func:`~veribattery.config.params.derive_parameters` has already computed.

Compiling the templates to Python is a fixed cost of every process that renders (about
a tenth of a small ``check``), so the compiled code is kept in Jinja's bytecode cache:
a directory of the user's own in the system temp directory (``_jinja2-cache-<uid>``,
mode 0700, checked by Jinja). An entry is used only for the same template file with the
same source (Jinja compares a checksum of it) under the same Jinja bytecode format and
Python version; anything else compiles afresh, and so does every process when the cache
cannot be made, read or written.
"""

from __future__ import annotations

import contextlib
import pickle
import re
from fractions import Fraction
from functools import cache
from pathlib import Path
from typing import Any

import jinja2
from jinja2.bccache import Bucket

from veribattery._collector import collections_spaced
from veribattery.config.exact import fraction_to_decimal
from veribattery.config.load import config_to_yaml, require_config
from veribattery.config.params import derive_parameters
from veribattery.config.schema import MissionConfig
from veribattery.errors import RenderError

__all__ = ["render_model", "render_properties", "template_dir"]

MODEL_TEMPLATE = "model.prism.j2"
PROPERTIES_TEMPLATE = "properties.props.j2"


def template_dir() -> Path:
    """The wheel's ``veribattery/prism_templates`` if present, else the source tree's."""
    package = Path(__file__).resolve().parents[1]
    for candidate in (package / "prism_templates", package.parents[1] / "prism_templates"):
        if (candidate / MODEL_TEMPLATE).is_file():
            return candidate
    raise RenderError(f"PRISM templates not found next to {package}")


def prism_number(value: Fraction | int) -> str:
    """A PRISM literal for an exact value: ``2``, ``0.1``, or ``(1/3)`` when not a decimal."""
    value = Fraction(value)
    if value.denominator == 1:
        return str(value.numerator)
    decimal = fraction_to_decimal(value)
    return decimal if decimal is not None else f"({value.numerator}/{value.denominator})"


def prism_type(value: Fraction | int) -> str:
    """``int`` for whole numbers, else ``double``."""
    return "int" if Fraction(value).denominator == 1 else "double"


def times(coefficient: int, term: str) -> str:
    """``coefficient*term``, leaving out a coefficient of 1."""
    return term if coefficient == 1 else f"{coefficient}*{term}"


class _BestEffortBytecodeCache(jinja2.FileSystemBytecodeCache):
    """Jinja's per-user bytecode cache, read and written if the disk allows: a cache
    file that cannot be read or written means a compile, never an error."""

    def load_bytecode(self, bucket: Bucket) -> None:
        try:
            super().load_bytecode(bucket)
        except (OSError, EOFError, ValueError, pickle.UnpicklingError):  # a damaged file
            bucket.reset()

    def dump_bytecode(self, bucket: Bucket) -> None:
        with contextlib.suppress(OSError):  # a read-only or full disk: compiled next time
            super().dump_bytecode(bucket)


def _bytecode_cache() -> jinja2.BytecodeCache | None:
    """The compiled templates' cache, or None where no safe directory can be had."""
    try:
        return _BestEffortBytecodeCache()
    except (OSError, RuntimeError):  # RuntimeError: Jinja found the directory unsafe
        return None


@cache
def _environment(folder: str) -> jinja2.Environment:
    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader(folder),
        bytecode_cache=_bytecode_cache(),
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
        keep_trailing_newline=True,
        autoescape=False,
    )
    env.filters["num"] = prism_number
    env.filters["ptype"] = prism_type
    env.globals["times"] = times
    return env


def _render(name: str, **context: Any) -> str:
    try:
        template = _environment(str(template_dir())).get_template(name)
        return _tidy(template.render(**context))
    except jinja2.TemplateSyntaxError as exc:
        raise RenderError(f"{exc.name or name}:{exc.lineno}: {exc.message}") from None
    except jinja2.TemplateError as exc:
        raise RenderError(f"{name}: {exc}") from None


def _tidy(text: str) -> str:
    """At most one blank line in a row and no trailing blanks: macros leave stray newlines."""
    text = re.sub(r"[ \t]+\n", "\n", text)
    return re.sub(r"\n{3,}", "\n\n", text).strip("\n") + "\n"


def _header(cfg: MissionConfig) -> list[str]:
    return config_to_yaml(cfg).rstrip("\n").splitlines()


@collections_spaced
def render_model(cfg: MissionConfig) -> str:
    """The PRISM DTMC of *cfg*, with the resolved config as a comment header.

    :raises ConfigError: when the config's numbers overflow PRISM's integers.
    :raises RenderError: when the template fails.
    :raises ArgumentError: for anything but a loaded config (a file's name, say).
    """
    cfg = require_config(cfg)
    return _render(MODEL_TEMPLATE, p=derive_parameters(cfg), config_lines=_header(cfg))


def render_properties(cfg: MissionConfig) -> str:
    """The PRISM properties file of *cfg*: its named properties, in order.

    :raises RenderError: when the template fails.
    :raises ArgumentError: for anything but a loaded config (a file's name, say).
    """
    cfg = require_config(cfg)
    return _render(PROPERTIES_TEMPLATE, properties=cfg.properties, requirements=cfg.requirements)
