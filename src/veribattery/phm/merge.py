"""Merge config values into a user's YAML file without losing its comments or layout.

PyYAML drops comments on a round trip, so the merge edits the *text*: the position
of every key and value comes from :func:`yaml.compose`, a changed scalar is replaced
in place (its trailing comment stays, unless it holds a number: then it described the
old value, and says where the new one came from instead), a new key is inserted after
its section's last line at the section's indentation, and a replaced section is
rewritten at its own indentation (comments *inside* a replaced section go with the old
values). The result is parsed again and must equal the intended data, or nothing is
written; the file is replaced atomically, as it was: through a symbolic link, with its
mode and line endings.
"""

from __future__ import annotations

import errno
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

from veribattery._files import write_text
from veribattery.config import set_value
from veribattery.phm.data import PhmDataError
from veribattery.phm.fragment import block_yaml, to_yaml_value

__all__ = ["hard_links", "merge_text", "write_atomic"]


def merge_text(text: str, updates: Mapping[str, object], source: str = "<string>",
               note: str | None = None) -> str:
    """*text* with each dotted key of *updates* set, comments and layout kept.

    :param note: where the new values come from (``fitted by veribattery phm fade from
        cycles.csv``): a changed value's trailing comment that holds a number described
        the old value (``# BA1 (0.2 % per recharge)``) and becomes ``# NOTE``; without a
        note it is dropped.
    :raises PhmDataError: when the text is not a YAML mapping, or the edit would not
        give exactly the intended data.
    """
    expected = _load(text, source)
    note = None if note is None else " ".join(note.split())  # one line, whatever the name
    for key, value in updates.items():
        text = _set(text, key.split("."), value, source, note)
        expected = set_value(expected, key, yaml.safe_load(to_yaml_value(value)))
    if _load(text, source) != expected:
        raise PhmDataError(f"{source}: cannot merge {', '.join(updates)} safely into this "
                           "layout; the file is left unchanged (apply the fragment by hand)")
    return text


def _load(text: str, source: str) -> dict[str, Any]:
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise PhmDataError(f"{source}: not valid YAML: {exc}".splitlines()[0]) from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise PhmDataError(f"{source}: a config must be a mapping of keys")
    return data


def _nest(path: list[str], value: object) -> object:
    for part in reversed(path):
        value = {part: value}
    return value


def _set(text: str, path: list[str], value: object, source: str, note: str | None) -> str:
    root = yaml.compose(text)
    if root is None:
        prefix = text if not text or text.endswith("\n") else text + "\n"
        return prefix + block_yaml(_nest(path, value), 0)
    if not isinstance(root, yaml.MappingNode):
        raise PhmDataError(f"{source}: a config must be a mapping of keys")
    node: yaml.MappingNode = root
    for depth, part in enumerate(path):
        child = next((v for k, v in node.value if k.value == part), None)
        rest = _nest(path[depth + 1 :], value)
        if child is None:
            return _insert(text, node, part, rest)
        if depth == len(path) - 1 or not isinstance(child, yaml.MappingNode):
            return _replace(text, child, rest, note)
        node = child
    raise AssertionError("unreachable: the path is never empty")


def _line_end(text: str, index: int) -> int:
    """Index just past the end of the line holding *index*."""
    newline = text.find("\n", index)
    return len(text) if newline < 0 else newline + 1


def _content_end(node: yaml.Node) -> int:
    """Index of the last character of *node*'s content (its last scalar)."""
    if isinstance(node, yaml.MappingNode) and node.value and not node.flow_style:
        return _content_end(node.value[-1][1])
    if isinstance(node, yaml.SequenceNode) and node.value and not node.flow_style:
        return _content_end(node.value[-1])
    end: int = node.end_mark.index
    start: int = node.start_mark.index
    return max(end - 1, start)


def _insert(text: str, mapping: yaml.MappingNode, key: str, value: object) -> str:
    if mapping.flow_style or not mapping.value:
        return _replace_flow(text, mapping, key, value)
    indent = mapping.value[0][0].start_mark.column
    at = _line_end(text, _content_end(mapping))
    prefix = text[:at] if text[:at].endswith("\n") or not at else text[:at] + "\n"
    return prefix + block_yaml({key: value}, indent) + text[at:]


def _replace_flow(text: str, mapping: yaml.MappingNode, key: str, value: object) -> str:
    start, end = mapping.start_mark.index, mapping.end_mark.index
    data = yaml.safe_load(text[start:end]) or {}
    data[key] = yaml.safe_load(to_yaml_value(value))
    flow: str = yaml.safe_dump(data, default_flow_style=True, sort_keys=False, width=10**6)
    flow = flow.strip()
    return text[:start] + flow + text[end:]


def _replace(text: str, node: yaml.Node, value: object, note: str | None) -> str:
    if isinstance(value, Mapping) and isinstance(node, yaml.MappingNode) and not node.flow_style:
        indent = node.start_mark.column
        start = node.start_mark.index - indent
        return text[:start] + block_yaml(value, indent) + text[_line_end(text, _content_end(node)):]
    start, end = node.start_mark.index, node.end_mark.index
    new = to_yaml_value(value)
    if start == end:  # an empty value (``key:``): put the new one after the colon
        return text[:start] + " " + new + text[end:]
    merged = text[:start] + new + text[end:]
    if yaml.safe_load(text[start:end]) == yaml.safe_load(new):
        return merged  # the same value: what its comment says still holds
    return _restate_comment(merged, start + len(new), note)


#: A trailing comment after a value, and a digit in it.
_COMMENT = re.compile(r"([ \t]+)#([^\r\n]*)")
_DIGIT = re.compile(r"\d")


def _restate_comment(text: str, at: int, note: str | None) -> str:
    """The comment after a new value ending at *at*: one with a number described the old
    value (``fade_per_recharge: 0.000145 # BA1 (0.2 % per recharge)`` misled), so it
    becomes ``# note``, or goes; other comments (``# as bought``) stay."""
    match = _COMMENT.match(text, at)
    if match is None or not _DIGIT.search(match.group(2)):
        return text
    replacement = f"{match.group(1)}# {note}" if note else ""
    return text[:at] + replacement + text[match.end():]


def hard_links(path: Path) -> int:
    """How many names the file at *path* has (a symbolic link followed; 0: no file)."""
    return path.stat().st_nlink if path.exists() else 0


def write_atomic(path: Path, text: str) -> None:
    """Replace the file at *path* by *text* (LF line endings) atomically, as it was.

    A symbolic link is followed: its target is replaced, by a temporary file in the
    target's folder renamed onto it (the rename replaced the link itself, and the config
    it pointed to stayed as it was). The mode is kept, and so are CRLF line endings
    (the text was read with universal newlines); a new file gets the mode ``open()``
    would give it.

    :raises OSError: when the file has other hard links: the rename would split them
        from it (they would keep the old config).
    """
    target = path.resolve() if path.is_symlink() else path
    links = hard_links(target)
    if links > 1:
        raise OSError(errno.EMLINK, f"the file has {links} hard links, and replacing it "
                      "would split them", str(path))
    if links and b"\r\n" in target.read_bytes():
        text = text.replace("\r\n", "\n").replace("\n", "\r\n")
    write_text(target, text)
