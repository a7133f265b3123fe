"""``.. config-reference::``: every key of the mission config, from the pydantic schema.

Keys, types and defaults come from :class:`veribattery.config.schema.MissionConfig`
and its sections (their docstrings head each table); what each key means comes from
the comments of ``configs/example.yaml``, which writes every key out. A key the
example does not comment is listed all the same, with its type and default.
"""

from __future__ import annotations

import re
import types
import typing
from collections.abc import Iterator
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

import yaml
from docutils import nodes
from docutils.statemachine import StringList
from pydantic import BaseModel
from pydantic.fields import FieldInfo
from sphinx.application import Sphinx
from sphinx.util.docutils import SphinxDirective
from sphinx.util.nodes import nested_parse_with_titles

EXAMPLE = Path(__file__).resolve().parents[2] / "configs" / "example.yaml"
_COMMENT = re.compile(r"\s#\s?(.*)$")


@dataclass(frozen=True)
class Row:
    """One line of a section's table."""

    key: str
    kind: str
    default: str
    meaning: str


def example_comments(text: str) -> dict[str, str]:
    """Dotted key -> the comment written beside it (and on the comment lines below it
    that are indented past the key) in a commented YAML file."""
    lines = text.splitlines()
    found: dict[str, str] = {}

    def walk(node: yaml.Node, prefix: str) -> None:
        if not isinstance(node, yaml.MappingNode):
            return
        for key, value in node.value:
            dotted = prefix + str(key.value)
            comment = _comment_from(lines, key.start_mark.line, key.start_mark.column)
            if comment:
                found[dotted] = comment
            walk(value, dotted + ".")

    walk(yaml.compose(text), "")
    return found


def _comment_from(lines: list[str], line: int, column: int) -> str:
    """The comment on *line* and its continuation lines (comment-only, deeper than *column*)."""
    match = _COMMENT.search(lines[line])
    if match is None:
        return ""
    parts = [match.group(1).strip()]
    for following in lines[line + 1:]:
        stripped = following.lstrip()
        if not stripped.startswith("#") or len(following) - len(stripped) <= column:
            break
        parts.append(stripped[1:].strip())
    return " ".join(parts)


def show(value: object) -> str:
    """A default as a user would write it in YAML."""
    if isinstance(value, Fraction):
        if value.denominator == 1:
            return str(value.numerator)
        text = f"{float(value)!r}"
        return text if Fraction(text) == value else f"{value.numerator}/{value.denominator}"
    if isinstance(value, str):
        return value
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, tuple | list):
        return "[" + ", ".join(show(v) for v in value) + "]"
    if isinstance(value, dict):
        return ", ".join(value) if value else "{}"
    if isinstance(value, BaseModel):
        return "{" + ", ".join(f"{k}: {show(v)}" for k, v in value) + "}"
    return str(value)


def _is_group(annotation: object) -> bool:
    """A section whose keys are all required: written as one value, ``{low: .., high: ..}``."""
    return (isinstance(annotation, type) and issubclass(annotation, BaseModel)
            and all(f.is_required() for f in annotation.model_fields.values()))


def _is_section(annotation: object) -> bool:
    return (isinstance(annotation, type) and issubclass(annotation, BaseModel)
            and not _is_group(annotation))


def _members(annotation: object) -> tuple[object, ...]:
    """The members of a union as written (``Annotated`` kept), or ``()``."""
    annotation = _bare(annotation)
    if typing.get_origin(annotation) in (typing.Union, types.UnionType):
        return typing.get_args(annotation)
    return ()


def _alternatives(annotation: object) -> tuple[object, ...]:
    """The members of a union, ``Annotated`` wrappers removed, or ``()``."""
    return tuple(_bare(m) for m in _members(annotation))


def _bare(annotation: object) -> object:
    while typing.get_origin(annotation) is typing.Annotated:
        annotation = typing.get_args(annotation)[0]
    return annotation


def kind(annotation: object, info: FieldInfo | None = None) -> str:
    """The type of a key in words."""
    annotation = _bare(annotation)
    if annotation is bool:
        return "true/false"
    if annotation is int:
        return "integer"
    if annotation is Fraction:
        positive = any(getattr(getattr(m, "func", None), "__name__", "") == "_positive"
                       for m in (info.metadata if info else ()))
        return "exact number > 0" if positive else "exact number"
    if annotation is str:
        return "text"
    if typing.get_origin(annotation) is typing.Literal:
        return "one of " + ", ".join(f"``{a}``" for a in typing.get_args(annotation))
    if _is_group(annotation):
        assert isinstance(annotation, type) and issubclass(annotation, BaseModel)
        return "{" + ", ".join(annotation.model_fields) + "}, each " + _common_kind(annotation)
    alternatives = _alternatives(annotation)
    if alternatives:
        return " or ".join(kind(a) for a in alternatives)
    origin, args = typing.get_origin(annotation), typing.get_args(annotation)
    if origin is tuple and len(args) == 2 and args[1] is Ellipsis:
        return f"list of {_plural(kind(args[0]))}"
    if origin is tuple and args == (int, int):
        return "cell [x, y]"
    if origin is dict:
        return f"mapping of names to {_plural(kind(args[1]))}"
    return getattr(annotation, "__name__", str(annotation))


def _common_kind(model: type[BaseModel]) -> str:
    kinds = {kind(f.annotation, f) for f in model.model_fields.values()}
    return kinds.pop() if len(kinds) == 1 else "value"


def _plural(text: str) -> str:
    return {"cell [x, y]": "cells [x, y]", "text": "texts"}.get(text, text)


def rows(model: type[BaseModel], prefix: str, comments: dict[str, str],
         default: BaseModel | None = None, form: str = "") -> Iterator[Row]:
    """One row per key of *model*, depth first; sections get a row and their keys below."""
    for name, info in model.model_fields.items():
        key = prefix + name
        annotation = _bare(info.annotation)
        value = (getattr(default, name) if default is not None
                 else None if info.is_required() else info.get_default(call_default_factory=True))
        meaning = _inline(comments.get(key, ""))
        if form:
            meaning = f"*{form} form.* {meaning}".rstrip()
        forms = _forms(info)
        if _is_section(annotation):
            yield Row(key, "section", "", meaning)
            assert isinstance(annotation, type) and issubclass(annotation, BaseModel)
            yield from rows(annotation, key + ".", comments, value, form)
        elif forms:
            yield Row(key, "section in one of two forms", "", _forms_text(info, forms, meaning))
            for tag, alternative in forms:
                same = isinstance(value, alternative)
                yield from rows(alternative, key + ".", comments if same else {},
                                value if same else None, form=tag)
        else:
            shown = "required" if value is None and info.is_required() else show(value)
            yield Row(key, kind(annotation, info), shown, meaning)


def _forms(info: FieldInfo) -> list[tuple[str, type[BaseModel]]]:
    """The tagged sections of a discriminated union: ``[(tag, model), ...]``."""
    forms = []
    for member in _members(info.annotation):
        tag = next((m.tag for m in getattr(member, "__metadata__", ())
                    if hasattr(m, "tag")), None)
        model = _bare(member)
        if tag is not None and _is_section(model):
            assert isinstance(model, type) and issubclass(model, BaseModel)
            forms.append((str(tag), model))
    return forms


def _forms_text(info: FieldInfo, forms: list[tuple[str, type[BaseModel]]], meaning: str) -> str:
    """What a two-form section holds, from the forms' docstrings and the discriminator's."""
    described = "; ".join(f"``{tag}``: {_summary(model)}" for tag, model in forms)
    chooser = next((_summary(m.discriminator) for m in _all_metadata(info)
                    if callable(getattr(m, "discriminator", None))), "")
    text = f"{_sentence(meaning)} Forms: {described}." if meaning else f"Forms: {described}."
    return f"{text} Form: {chooser}" if chooser else text


def _all_metadata(info: FieldInfo) -> list[object]:
    found = list(info.metadata)
    annotation = info.annotation
    while typing.get_origin(annotation) is typing.Annotated:
        found += list(getattr(annotation, "__metadata__", ()))
        annotation = typing.get_args(annotation)[0]
    return found


def _summary(obj: object) -> str:
    """The first line of *obj*'s docstring, without its full stop."""
    doc = (getattr(obj, "__doc__", None) or "").strip()
    return doc.splitlines()[0].rstrip(".") if doc else ""


def _sentence(text: str) -> str:
    """*text* ending with a full stop."""
    return text if text.endswith((".", "!", "?")) else text + "."


def _inline(text: str) -> str:
    """A YAML comment as reST: `code` spans kept literal, the rest escaped (``*`` means x)."""
    parts = text.split("`")
    if len(parts) % 2 == 0:  # an unpaired backtick: all plain
        return _escape(text)
    return "".join(f"``{p}``" if i % 2 else _escape(p) for i, p in enumerate(parts) if p)


def _escape(text: str) -> str:
    """Plain text for a table cell (the config's comments use ``*`` as multiplication)."""
    return text.replace("\\", "\\\\").replace("*", r"\*").replace("`", r"\`").replace("|", r"\|")


def _cell(text: str) -> str:
    return text if "``" in text or text.startswith("*") else _escape(text)


def _table(section_rows: list[Row]) -> list[str]:
    lines = [".. list-table::", "   :header-rows: 1", "   :widths: 30 20 15 35", "",
             "   * - key", "     - type", "     - default", "     - meaning"]
    for row in section_rows:
        default = f"``{row.default}``" if row.default else ""
        lines += [f"   * - ``{row.key}``", f"     - {_cell(row.kind)}", f"     - {default}",
                  f"     - {row.meaning}"]
    return [*lines, ""]


class ConfigReference(SphinxDirective):
    """One table per top-level section of the mission config."""

    def run(self) -> list[nodes.Node]:
        from veribattery.config.schema import MissionConfig

        self.env.note_dependency(str(EXAMPLE))
        comments = example_comments(EXAMPLE.read_text(encoding="utf-8"))
        text: list[str] = []
        for name, info in MissionConfig.model_fields.items():
            annotation = _bare(info.annotation)
            title = f"``{name}``"
            text += [title, "-" * len(title), ""]
            if _is_section(annotation):
                assert isinstance(annotation, type) and issubclass(annotation, BaseModel)
                doc = (annotation.__doc__ or "").strip().splitlines()[0]
                text += [doc, ""] if doc else []
                note = comments.get(name, "")
                text += [_sentence(_inline(note[0].upper() + note[1:])), ""] if note else []
            text += _table(list(_section_rows(name, info, comments)))
        container = nodes.section()
        nested_parse_with_titles(self.state, StringList(text, source=str(EXAMPLE)), container)
        return list(container.children)


def _section_rows(name: str, info: FieldInfo, comments: dict[str, str]) -> Iterator[Row]:
    """The rows of one top-level key: its section's keys, or the key itself."""
    annotation = _bare(info.annotation)
    if _is_section(annotation):
        assert isinstance(annotation, type) and issubclass(annotation, BaseModel)
        default = info.get_default(call_default_factory=True)
        yield from rows(annotation, name + ".", comments, default)
        return
    value = info.get_default(call_default_factory=True)
    yield Row(name, kind(annotation, info), show(value), _inline(comments.get(name, "")))


def setup(app: Sphinx) -> dict[str, object]:
    app.add_directive("config-reference", ConfigReference)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
