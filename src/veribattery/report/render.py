"""The report's HTML: one Jinja template, its style and script inlined, figures as SVG.

The environment is strict (an undefined name is an error, never an empty string) and
escapes every value; only the SVG figures, made here, are inserted as markup. The
filters format numbers and nothing else: what the page says is decided in
:mod:`veribattery.report.data`'s records.
"""

from __future__ import annotations

import math
from functools import cache

import jinja2

from veribattery.report.data import ReportData, json_number
from veribattery.report.figures import ReportFigures

__all__ = ["FILTERS", "environment", "machine_data", "render_report"]


def _num(value: object) -> str:
    """A result as ``check``'s tables print it: 12 significant digits, true/false."""
    if value is None:
        return "undefined"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return ("Infinity" if value > 0 else "-Infinity") if math.isinf(value) \
            else f"{value:.12g}"
    return str(value)


def _sig(value: object, digits: int = 6) -> str:
    """A number to *digits* significant digits."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return _num(value)
    return f"{value:.{digits}g}"


def _full(value: object) -> str:
    """Every digit: the shortest text that reads back as the same double (JSON's)."""
    return repr(value) if isinstance(value, float) else _num(value)


def _jsvalue(value: object) -> str:
    """A value for a ``data-`` attribute, exactly as JSON writes it."""
    shown = json_number(value if isinstance(value, float | bool | None) else float(str(value)))
    if shown is None:
        return "null"
    if isinstance(shown, bool):
        return "true" if shown else "false"
    return repr(shown) if isinstance(shown, float) else str(shown)


def _pct(value: float, digits: int = 1) -> str:
    return f"{100 * value:.{digits}f} %"


def _fixed(value: float, digits: int = 2) -> str:
    return f"{value:.{digits}f}"


def _count(value: int) -> str:
    return f"{value:,}"


def _bar_width(share: float) -> str:
    """A share as a CSS width (of a bar at most 6 rem long)."""
    return f"{6 * max(0.0, min(1.0, share)):.3f}rem"


#: The template's filters, by name.
FILTERS = {"num": _num, "sig": _sig, "full": _full, "jsvalue": _jsvalue, "pct": _pct,
           "fixed": _fixed, "count": _count, "bar_width": _bar_width}


@cache
def environment() -> jinja2.Environment:
    """The report's Jinja environment (templates shipped in the package)."""
    env = jinja2.Environment(
        loader=jinja2.PackageLoader("veribattery.report", "templates"),
        autoescape=True, undefined=jinja2.StrictUndefined, keep_trailing_newline=True,
    )
    env.filters.update(FILTERS)
    # A NaN would make the page's JSON unreadable to JSON.parse: fail loudly instead.
    env.policies["json.dumps_kwargs"] = {"sort_keys": False, "allow_nan": False}
    return env


def machine_data(data: ReportData) -> dict[str, object]:
    """The report's numbers as the commands print them in JSON, for the page's
    ``#report-data`` block: ``check``, and the summaries of ``distribution``,
    ``explain`` (the breakdown and the paths' probabilities) and ``simulate``."""
    fail = data.failures
    out: dict[str, object] = {
        "check": data.verdict.check_json(),
        "distribution": data.time.distribution_json(),
        "explain": {
            "p_failure": fail.probability,
            "breakdown": {"+".join(t.keys): t.records() for t in fail.tables},
            "paths": [{"probability": p.probability, "steps": len(p.steps) - 1}
                      for p in fail.paths],
        },
    }
    if data.simulation is not None:
        sim = data.simulation
        out["simulate"] = {
            "runs": sim.runs, "seed": sim.seed, "max_steps": sim.max_steps,
            "results": {e.name: {"estimate": json_number(e.estimate),
                                 "ci95": [json_number(e.ci95[0]), json_number(e.ci95[1])],
                                 "runs": e.runs, "undecided": e.undecided,
                                 "value": json_number(e.exact)} for e in sim.estimates},
        }
    return out


def render_report(data: ReportData, figures: ReportFigures) -> str:
    """The whole page as one HTML document."""
    template = environment().get_template("report.html.j2")
    return template.render(data=data, figures=figures, prov=data.provenance,
                           machine=machine_data(data))
