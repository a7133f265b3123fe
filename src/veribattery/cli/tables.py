"""Plain-text tables that fit the width they are printed at, never cutting a value.

One rule for every command: a table is laid out for the terminal's width on a
terminal, and for ``$COLUMNS`` (default 80) when the output is piped. A table wider
than that is folded, never truncated: the columns after the *keys* (the leading
columns that name a row, such as the property or the grid point) are split into
groups that fit, each printed as its own block with the keys repeated; a cell too
long for any column is wrapped inside it. Prose lines are wrapped to the same width.
"""

from __future__ import annotations

import os
import shutil
import sys
import textwrap
from collections.abc import Mapping, Sequence
from itertools import zip_longest

import click

__all__ = ["fit_text", "output_width", "print_table", "render_table"]

#: Spaces between columns.
GAP = 2
#: Narrowest column a wrapped cell is given before the table falls back to records.
MIN_COLUMN = 12
#: Width of piped output when ``$COLUMNS`` does not say.
PIPED_WIDTH = 80


def output_width() -> int:
    """Columns available on stdout: the terminal's, else ``$COLUMNS``, else 80."""
    if sys.stdout.isatty():
        return max(shutil.get_terminal_size((PIPED_WIDTH, 24)).columns, 20)
    columns = os.environ.get("COLUMNS", "")
    return max(int(columns), 20) if columns.isdigit() else PIPED_WIDTH


def render_table(headers: Sequence[str], rows: Sequence[Sequence[str]], *, width: int,
                 keys: int = 1, notes: Mapping[int, str] | None = None) -> list[str]:
    """The lines of a table no wider than *width* (see the module's rule).

    :param keys: how many leading columns identify a row (repeated in every block).
    :param notes: prose lines to show before row *i* (in every block), such as a
        fold in a long path; wrapped to the width, indented past the first key.
    """
    notes = notes or {}
    widths = _natural_widths(headers, rows)
    keys = min(keys, len(headers) - 1) if len(headers) > 1 else len(headers)
    key_width = sum(widths[:keys]) + GAP * keys
    if _span(widths) <= width:
        return _block(headers, rows, list(range(len(headers))), widths, notes, width)
    if width - key_width < MIN_COLUMN:
        return _records(headers, rows, width)
    lines: list[str] = []
    for group in _groups(widths[keys:], width - key_width):
        shown = [*range(keys), *(keys + j for j in group)]
        fitted = [min(w, width - key_width) if j >= keys else w for j, w in enumerate(widths)]
        if lines:
            lines.append("")
        lines += _block(headers, rows, shown, fitted, notes, width)
    return lines


def print_table(headers: Sequence[str], rows: Sequence[Sequence[str]], *, keys: int = 1,
                title: str | None = None, notes: Mapping[int, str] | None = None) -> None:
    """Print a table on stdout at :func:`output_width` (a title line first, if given)."""
    width = output_width()
    if title:
        click.echo(fit_text(title, width))
    for line in render_table(headers, rows, width=width, keys=keys, notes=notes):
        click.echo(line)


def fit_text(text: str, width: int | None = None, indent: str = "") -> str:
    """*text* wrapped to *width* (default :func:`output_width`), continued lines indented."""
    return textwrap.fill(text, width or output_width(), subsequent_indent=indent,
                         break_on_hyphens=False)


def _natural_widths(headers: Sequence[str], rows: Sequence[Sequence[str]]) -> list[int]:
    return [max([len(h), *(len(r[j]) for r in rows)]) for j, h in enumerate(headers)]


def _span(widths: Sequence[int]) -> int:
    return sum(widths) + GAP * (len(widths) - 1)


def _groups(widths: Sequence[int], room: int) -> list[list[int]]:
    """Consecutive columns packed greedily into groups no wider than *room*."""
    groups: list[list[int]] = [[]]
    used = 0
    for j, w in enumerate(widths):
        w = min(w, room)
        if groups[-1] and used + GAP + w > room:
            groups.append([])
            used = 0
        used += w + (GAP if groups[-1] else 0)
        groups[-1].append(j)
    return groups


def _block(headers: Sequence[str], rows: Sequence[Sequence[str]], shown: Sequence[int],
           widths: Sequence[int], notes: Mapping[int, str], width: int) -> list[str]:
    lines = [_line([headers[j] for j in shown], [widths[j] for j in shown])]
    lines.append(_line(["─" * widths[j] for j in shown], [widths[j] for j in shown]))
    indent = " " * (widths[0] + GAP)
    for i, row in enumerate(rows):
        if i in notes:
            lines += textwrap.wrap(notes[i], width, initial_indent=indent,
                                   subsequent_indent=indent + "  ", break_on_hyphens=False)
        lines += _wrapped_row([row[j] for j in shown], [widths[j] for j in shown])
    return lines


def _wrapped_row(cells: Sequence[str], widths: Sequence[int]) -> list[str]:
    parts = [_cut(cell, w) for cell, w in zip(cells, widths, strict=True)]
    return [_line([p or "" for p in line], widths) for line in zip_longest(*parts)]


def _cut(cell: str, width: int) -> list[str]:
    if len(cell) <= width:
        return [cell]
    return textwrap.wrap(cell, width, break_on_hyphens=False) or [cell[:width]]


def _line(cells: Sequence[str], widths: Sequence[int]) -> str:
    return (" " * GAP).join(c.ljust(w) for c, w in zip(cells, widths, strict=True)).rstrip()


def _records(headers: Sequence[str], rows: Sequence[Sequence[str]], width: int) -> list[str]:
    """One ``header: value`` line per cell, rows separated by blank lines (very narrow)."""
    lines: list[str] = []
    for row in rows:
        if lines:
            lines.append("")
        for header, cell in zip(headers, row, strict=True):
            lines.append(fit_text(f"{header}: {cell}", width, indent="  "))
    return lines
