"""The Pareto front of P(success) against expected mission time, with BS1 on it.

The front is the least expected mission time of a strategy whose P(success) is at
least ``p`` (``multi(R{"mt"}min=? [ C ], P>=p [ F "success" ])``) for every ``p``: a
convex, piecewise-linear curve whose points here are its vertices (deterministic
strategies, from weighted sums: :func:`~veribattery.synthesis.fastest.front`); every
point between two neighbours is a mix of the two. BS1's
points, one per ``safe_t``, are BS1's own DTMC values. Since BS1 is a strategy of the
MDP, no BS1 point lies left of the front at its P(success) (model-spec.md, "Synthesis").
Expected mission time counts failed missions too (docs/decisions.md, synthesis 9).

The figure is drawn on an Agg canvas (no display), like the sweep figures
(:mod:`veribattery.sweep.plot`); its format follows the file's suffix.
"""

from __future__ import annotations

import csv
from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from veribattery._files import staged
from veribattery.config.exact import show

__all__ = [
    "PARETO_COLUMNS",
    "Bs1Point",
    "FrontPoint",
    "pareto_figure",
    "write_pareto_csv",
    "write_pareto_figure",
]

#: Okabe-Ito blue and vermilion (as the report's figures), and grey for Pmax.
_FRONT, _BS1, _PMAX = "#0072B2", "#D55E00", "#999999"
#: The CSV's columns: the series, its parameter (p or safe_t) and the two values.
PARETO_COLUMNS = ("series", "p_required", "safe_t", "p_success", "exp_mission_time")
_TIME = "expected mission time (min), failed missions included"


@dataclass(frozen=True, slots=True)
class FrontPoint:
    """The fastest strategy with P(success) >= *p*: its expected mission time.

    :ivar p: the P(success) required (of a vertex of the front: its own P(success)).
    :ivar exp_mission_time: the least expected mission time of a strategy meeting it.
    """

    p: float
    exp_mission_time: float


@dataclass(frozen=True, slots=True)
class Bs1Point:
    """BS1 at one *safe_t*: its P(success) and expected mission time."""

    safe_t: Fraction
    p_success: float
    exp_mission_time: float


def pareto_figure(front: Sequence[FrontPoint], bs1: Sequence[Bs1Point], *,
                  p_max: float | None = None) -> Figure:
    """P(success) (y, 0 to 1) against expected mission time (x): the front as a line
    through its points in order of *p* (randomising between two strategies reaches every
    point between them), BS1's points labelled with their ``safe_t``.

    :param p_max: the best P(success) of any strategy, drawn as a dashed line.
    """
    figure = Figure(figsize=(7.5, 4.5), layout="constrained")
    FigureCanvasAgg(figure)
    ax = figure.add_subplot()
    _draw_front(ax, front)
    _draw_bs1(ax, bs1)
    if p_max is not None:
        ax.axhline(p_max, color=_PMAX, linestyle="--", linewidth=1,
                   label=f"best P(success) = {p_max:.6g}")
    ax.set_xlabel(_TIME)
    ax.set_ylabel("P(success)")
    ax.set_ylim(0, 1)
    ax.grid(True, alpha=0.3)
    if front or bs1 or p_max is not None:
        # No strategy is both safer and faster than the front: its upper left is empty.
        ax.legend(fontsize="small", loc="upper left")
    return figure


def write_pareto_figure(path: Path, front: Sequence[FrontPoint], bs1: Sequence[Bs1Point], *,
                        p_max: float | None = None) -> Path:
    """Draw :func:`pareto_figure` and write it to *path* atomically; the format follows
    the suffix (``.png``, ``.svg``, ``.pdf``, ...)."""
    figure = pareto_figure(front, bs1, p_max=p_max)
    with staged(path, suffix=path.suffix) as temporary:
        figure.savefig(temporary, format=path.suffix[1:].lower(), dpi=150)
    return path


def write_pareto_csv(path: Path, front: Sequence[FrontPoint], bs1: Sequence[Bs1Point]) -> None:
    """Write the points to *path* as CSV (:data:`PARETO_COLUMNS`), the front in order of
    *p*, then BS1 in order of ``safe_t``; a front point's P(success) is its *p*."""
    rows = [("front", repr(pt.p), "", repr(pt.p), repr(pt.exp_mission_time))
            for pt in sorted(front, key=lambda pt: pt.p)]
    rows += [("bs1", "", show(pt.safe_t), repr(pt.p_success), repr(pt.exp_mission_time))
             for pt in sorted(bs1, key=lambda pt: pt.safe_t)]
    with staged(path) as temporary, open(temporary, "w", encoding="utf-8", newline="") as out:
        writer = csv.writer(out)
        writer.writerow(PARETO_COLUMNS)
        writer.writerows(rows)


def _draw_front(ax: Axes, front: Sequence[FrontPoint]) -> None:
    points = sorted(front, key=lambda pt: pt.p)
    if points:
        ax.plot([pt.exp_mission_time for pt in points], [pt.p for pt in points],
                color=_FRONT, marker="o", markersize=4, linewidth=1.4, zorder=3, clip_on=False,
                label="fastest strategy with P(success) ≥ p")


def _draw_bs1(ax: Axes, bs1: Sequence[Bs1Point]) -> None:
    if not bs1:
        return
    ax.scatter([pt.exp_mission_time for pt in bs1], [pt.p_success for pt in bs1],
               color=_BS1, marker="s", s=28, zorder=4, clip_on=False, label="BS1 (safe_t)")
    # Several safe_t often give the same strategy, hence the same point: one label.
    labels: dict[tuple[float, float], list[str]] = {}
    for pt in sorted(bs1, key=lambda pt: pt.safe_t):
        labels.setdefault((pt.exp_mission_time, pt.p_success), []).append(show(pt.safe_t))
    for xy, names in labels.items():
        ax.annotate(", ".join(names), xy, textcoords="offset points", xytext=(5, 5),
                    fontsize="small", color=_BS1)
