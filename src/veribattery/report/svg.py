"""matplotlib figures as inline SVG: deterministic, accessible, and with nothing outside the page.

A figure is saved as SVG text on an Agg canvas (no display, the process's backend
left alone), with text kept as text (smaller, searchable, read by screen readers),
a fixed hash salt and no date or creator metadata, so the same figure gives the
same bytes. The SVG is then made fit to sit inside HTML: no XML prolog or DOCTYPE,
no namespace URLs (HTML's parser puts ``<svg>`` in the SVG namespace itself, and
``href`` replaces ``xlink:href``), every id prefixed with the figure's own (several
figures share one document) and ids nothing refers to dropped. ``role="img"`` with a
``<title>`` and ``<desc>`` names it for assistive technology, and artists given a
``gid`` get a ``<title>`` of their own: the value shown when the pointer rests on them.
"""

from __future__ import annotations

import functools
import io
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from html import escape
from typing import Any, ParamSpec, TypeVar

import matplotlib
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

P = ParamSpec("P")
R = TypeVar("R")

__all__ = ["STYLE", "Svg", "new_figure", "styled", "to_svg"]

#: Applied while a figure is drawn and saved.
STYLE: Mapping[str, Any] = {
    "svg.hashsalt": "veribattery-report",
    "svg.fonttype": "none",
    "font.family": "sans-serif",
    "font.sans-serif": ["DejaVu Sans", "Arial", "Helvetica"],
    "font.size": 10.0,
    "axes.titlesize": 10.5,
    "axes.labelsize": 10.0,
    "legend.fontsize": 8.5,
    "xtick.labelsize": 9.0,
    "ytick.labelsize": 9.0,
}
_NO_METADATA = {"Date": None, "Creator": None, "Format": None, "Type": None}
_PROLOG = re.compile(r"\A.*?(?=<svg\b)", re.S)
_METADATA = re.compile(r"\s*<metadata>.*?</metadata>", re.S)
_NAMESPACES = re.compile(r'\s+xmlns(:\w+)?="[^"]*"')
_ID = re.compile(r'\sid="([^"]+)"')
_REFERENCE = re.compile(r'(?:href="#|url\(#)([^")]+)')


@dataclass(frozen=True, slots=True)
class Svg:
    """A figure ready to inline: its id, accessible name and description, and markup.

    :ivar caption: what the page's caption says about it beyond its title, if the
        figure's own words (the template has the others).
    """

    id: str
    title: str
    desc: str
    markup: str
    caption: str = ""


def styled(function: Callable[P, R]) -> Callable[P, R]:
    """Run *function* under :data:`STYLE`: matplotlib reads most settings when an artist
    is made, so the whole drawing, not just the saving, happens inside it."""

    @functools.wraps(function)
    def draw(*args: P.args, **kwargs: P.kwargs) -> R:
        with matplotlib.rc_context(dict(STYLE)):  # type: ignore[arg-type]
            return function(*args, **kwargs)

    return draw


def new_figure(width: float, height: float) -> Figure:
    """A figure of *width* x *height* inches on an Agg canvas, laid out to fit."""
    figure = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(figure)
    return figure


def to_svg(figure: Figure, ident: str, title: str, desc: str,
           tips: Mapping[str, str] | None = None, caption: str = "") -> Svg:
    """*figure* as inline SVG markup named *ident* (an HTML id).

    :param title: the figure's accessible name (also its ``<title>``).
    :param desc: what it shows, in words (``<desc>``, for readers who cannot see it).
    :param tips: gid of an artist → the text shown on hover.
    :param caption: the page's caption, when the figure words it itself.
    """
    buffer = io.StringIO()
    with matplotlib.rc_context(dict(STYLE)):  # type: ignore[arg-type]
        figure.savefig(buffer, format="svg", metadata=_NO_METADATA)
    text = _clean(buffer.getvalue(), ident, set(tips or {}))
    for gid, tip in (tips or {}).items():
        text = text.replace(f'<g id="{ident}-{gid}">',
                            f'<g id="{ident}-{gid}"><title>{escape(tip)}</title>', 1)
    head = (f'<svg id="{ident}" role="img" aria-labelledby="{ident}-title {ident}-desc"'
            f' focusable="false"')
    text = text.replace("<svg", head, 1)
    opening = text.index(">") + 1
    named = (f'<title id="{ident}-title">{escape(title)}</title>'
             f'<desc id="{ident}-desc">{escape(desc)}</desc>')
    return Svg(ident, title, desc, text[:opening] + named + text[opening:], caption)


def _clean(text: str, ident: str, keep: set[str]) -> str:
    """Inline-ready SVG: prolog, metadata and namespaces gone, ids prefixed or dropped."""
    text = _METADATA.sub("", _PROLOG.sub("", text, count=1))
    text = _NAMESPACES.sub("", text).replace("xlink:href=", "href=")
    used = set(_REFERENCE.findall(text)) | keep

    def rename(match: re.Match[str]) -> str:
        name = match.group(1)
        return f' id="{ident}-{name}"' if name in used else ""

    text = _ID.sub(rename, text)
    text = re.sub(r'href="#([^"]+)"', lambda m: f'href="#{ident}-{m.group(1)}"', text)
    return re.sub(r"url\(#([^)]+)\)", lambda m: f"url(#{ident}-{m.group(1)})", text)
