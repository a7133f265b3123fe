"""The report's figures, drawn from its records (nothing is computed here but positions).

Each function takes the records of :mod:`veribattery.report.data` and returns an
:class:`~veribattery.report.svg.Svg`: an accessible name, a description in words and
hover texts for the values drawn. Colours are colour-blind safe (Okabe-Ito, viridis)
and every colour that carries meaning is also said in a label or a legend.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from matplotlib import colormaps
from matplotlib.axes import Axes
from matplotlib.cm import ScalarMappable
from matplotlib.colors import LogNorm
from matplotlib.lines import Line2D
from matplotlib.patches import FancyArrowPatch, Rectangle
from numpy.typing import ArrayLike

from veribattery.report.data import (
    Battery,
    FailurePath,
    Failures,
    Farm,
    MissionTime,
    ReportData,
)
from veribattery.report.svg import Svg, new_figure, styled, to_svg
from veribattery.report.sweep import Crossing, SweepResults
from veribattery.sweep.plot import sweep_figure

__all__ = [
    "ReportFigures",
    "battery_figure",
    "breakdown_figure",
    "draw_figures",
    "farm_figure",
    "heatmap_figure",
    "paths_figure",
    "sweep_figures",
    "time_figure",
]

#: Okabe-Ito colours: distinguishable with every common colour-vision deficiency.
BLUE, ORANGE, GREEN, RED, PURPLE, SKY, YELLOW, GREY = (
    "#0072B2", "#E69F00", "#009E73", "#D55E00", "#CC79A7", "#56B4E9", "#F0E442", "#999999")
#: Requirement bounds and where they stop holding: apart from every line colour.
DARK_RED = "#a40e26"
PATH_COLOURS = (BLUE, ORANGE, PURPLE, GREEN, SKY)
#: Paths often share most of their steps: each also gets its own dash and width.
PATH_STYLES = (("-", 2.2), ("--", 1.5), (":", 1.5), ("-.", 1.2), ("-", 0.8))
#: Marker of each action on the failure paths (the failing step is a red cross).
ACTION_MARKERS = {"takeoff": "^", "fly": ">", "inspect": "o", "next": ">", "back": "<",
                  "backnext": "<", "land": "v", "recharge": "s", "wait": "."}


def _cell_square(ax: Axes, cell: tuple[int, int], **style: object) -> Rectangle:
    """The square of cell ``[x, y]``: between turbines x..x+1 and y..y+1."""
    square = Rectangle((cell[0], cell[1]), 1, 1, **style)  # type: ignore[arg-type]
    ax.add_patch(square)
    return square


def _farm_axes(ax: Axes, farm: Farm) -> None:
    """Turbines on their lattice, the cells between them, the base marked."""
    cols, rows = farm.cells
    for x in range(cols):
        for y in range(rows):
            _cell_square(ax, (x, y), facecolor="none", edgecolor="#cccccc", linewidth=0.6)
    tx, ty = np.meshgrid(np.arange(farm.cols), np.arange(farm.rows))
    ax.scatter(tx.ravel(), ty.ravel(), marker="2", s=60, color="#333333", linewidths=1.2,
               zorder=4, label="turbine")
    _cell_square(ax, farm.base, facecolor="none", edgecolor=GREEN, linewidth=2.5, zorder=5)
    ax.text(farm.base[0] + 0.08, farm.base[1] + 0.1, "base", color=GREEN, fontsize=8,
            fontweight="bold", zorder=6)
    ax.set_xlim(-0.3, farm.cols - 0.7)
    ax.set_ylim(-0.3, farm.rows - 0.7)
    ax.set_aspect("equal")
    ax.set_xticks(np.arange(cols) + 0.5, [str(x) for x in range(cols)])
    ax.set_yticks(np.arange(rows) + 0.5, [str(y) for y in range(rows)])
    ax.tick_params(length=0)
    ax.set_xlabel("cell x")
    ax.set_ylabel("cell y")
    for side in ax.spines.values():
        side.set_visible(False)


@styled
def farm_figure(farm: Farm) -> Svg:
    """The farm: turbines, cells, the base, and the route through the cells in order."""
    figure = new_figure(5.2, 4.6)
    ax = figure.add_subplot()
    _farm_axes(ax, farm)
    tips = {}
    centres = [(x + 0.5, y + 0.5) for x, y in farm.route]
    for (x0, y0), (x1, y1) in itertools.pairwise(centres):
        ax.add_patch(FancyArrowPatch((x0, y0), (x1, y1), arrowstyle="-|>", mutation_scale=9,
                                     color=BLUE, linewidth=1.2, shrinkA=9, shrinkB=9, zorder=3))
    for k, ((cx, cy), cell, n) in enumerate(zip(centres, farm.route, farm.turbines,
                                                strict=True)):
        dot = ax.scatter([cx], [cy], s=150, color="white", edgecolors=BLUE, zorder=5)
        dot.set_gid(f"route-{k}")
        tips[f"route-{k}"] = (f"stop {k + 1}: cell [{cell[0]},{cell[1]}], {n} turbine"
                              f"{'s' if n != 1 else ''} to inspect")
        ax.text(cx, cy, str(k + 1), ha="center", va="center", fontsize=7, color=BLUE,
                zorder=6)
    ax.set_title(f"Route: {len(farm.route)} cells in order ({farm.route_name})", loc="left")
    desc = (f"A {farm.cols} by {farm.rows} grid of turbines with {farm.cells[0]} by "
            f"{farm.cells[1]} cells between them; the base is cell [{farm.base[0]},"
            f"{farm.base[1]}]. The route visits the cells in this order: "
            + ", ".join(f"[{x},{y}]" for x, y in farm.route) + ".")
    return to_svg(figure, "fig-farm", "The farm and the route", desc, tips)


@styled
def battery_figure(battery: Battery, expected_recharges: float | None) -> Svg:
    """Capacity after each recharge, with the voltage levels and the reserve over it."""
    figure = new_figure(6.4, 4.2)
    ax = figure.add_subplot()
    rc = np.arange(len(battery.capacity_ah))
    cap = np.asarray(battery.capacity_ah)
    ax.fill_between(rc, battery.level_high * cap, cap, step="post", color=GREEN, alpha=0.18,
                    label=f"high voltage (SOC above {battery.level_high:.0%})")
    ax.fill_between(rc, battery.level_low * cap, battery.level_high * cap, step="post",
                    color=YELLOW, alpha=0.25, label="medium voltage")
    ax.fill_between(rc, 0, battery.level_low * cap, step="post", color=RED, alpha=0.15,
                    label=f"low voltage (SOC below {battery.level_low:.0%})")
    ax.step(rc, cap, where="post", color="black", linewidth=1.4, label="capacity")
    ax.step(rc, battery.safe_t * cap, where="post", color=BLUE, linestyle="--", linewidth=1,
            label=f"reserve kept (safe_t = {battery.safe_t:g} of capacity)")
    if expected_recharges is not None and math.isfinite(expected_recharges):
        ax.axvline(expected_recharges, color=GREY, linestyle=":", linewidth=1.2)
        ax.text(expected_recharges, 0.02, f" E[recharges] = {expected_recharges:.3g}",
                transform=ax.get_xaxis_transform(), fontsize=8, color="#555555")
    ax.set_xlim(0, rc[-1])
    ax.set_ylim(0, max(cap) * 1.05)
    ax.set_xlabel("recharges so far")
    ax.set_ylabel("charge (Ah)")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.2), ncols=2, fontsize=8.5,
              frameon=False)
    ax.grid(True, alpha=0.3)
    desc = (f"The capacity starts at {cap[0]:g} Ah and is {cap[-1]:g} Ah after "
            f"{rc[-1]} recharges (fade {battery.fade_per_recharge:g} per recharge). The "
            f"voltage is high above {battery.level_high:.0%} of the capacity and low below "
            f"{battery.level_low:.0%}; the drone keeps a reserve of {battery.safe_t:g} of the "
            "capacity.")
    return to_svg(figure, "fig-battery", "Battery capacity and voltage levels over recharges",
                  desc)


@styled
def heatmap_figure(farm: Farm, failures: Failures) -> Svg:
    """P(failure) entered from each cell, on the farm (log colour scale)."""
    figure = new_figure(5.4, 4.6)
    ax = figure.add_subplot()
    _farm_axes(ax, farm)
    values = dict(failures.by_cell)
    positive = [p for p in values.values() if p > 0]
    tips = {}
    if positive:
        top = max(positive)
        low = max(min(positive), top * 1e-12)
        norm = LogNorm(vmin=low, vmax=top)
        colours = colormaps["YlOrRd"]
        for i, (cell, p) in enumerate(sorted(values.items())):
            if p <= 0:
                continue
            square = _cell_square(ax, cell, facecolor=colours(norm(max(p, low))),
                                  edgecolor="white", linewidth=1, zorder=2)
            square.set_gid(f"cell-{i}")
            share = p / failures.probability if failures.probability > 0 else 0.0
            tips[f"cell-{i}"] = (f"cell [{cell[0]},{cell[1]}]: P(failure) = {p:.4g} "
                                 f"({share:.2%} of all failures)")
            ax.text(cell[0] + 0.5, cell[1] + 0.5, f"{p:.1e}\n{share:.0%}", ha="center",
                    va="center", fontsize=7, zorder=6,
                    color="white" if norm(p) > 0.75 else "black")
        bar = figure.colorbar(ScalarMappable(norm=norm, cmap=colours), ax=ax, shrink=0.85)
        # matplotlib rasterises a long colour bar into an embedded PNG; keep it vector,
        # so that the page holds no image at all.
        if bar.solids is not None:
            bar.solids.set_rasterized(False)
        bar.set_label("P(failure) entered from the cell")
    ax.set_title(f"P(failure) = {failures.probability:.4g}, by cell", loc="left")
    after = _after_route(failures)
    if after:
        ax.text(0.0, -0.13, after, transform=ax.transAxes, fontsize=8, va="top")
    worst = sorted(values.items(), key=lambda item: -item[1])[:3]
    desc = ("Heat map of the farm: each cell coloured by the probability that the mission "
            "fails while working it. " + ("Most failures: " + "; ".join(
                f"cell [{c[0]},{c[1]}] {p:.3g}" for c, p in worst) + "." if worst else
                "No cell has a failure.") + (f" {after}." if after else ""))
    return to_svg(figure, "fig-heatmap", "Where failures happen on the farm", desc, tips)


def _after_route(failures: Failures) -> str:
    """The failures on the way home after the last cell, which no cell of the map shows."""
    if failures.after_route <= 0 or failures.probability <= 0:
        return ""
    share = failures.after_route / failures.probability
    return (f"Not on the map: after the last cell, on the way home, "
            f"P(failure) = {failures.after_route:.3g} ({share:.2%})")


@styled
def breakdown_figure(failures: Failures) -> Svg:
    """Shares of P(failure) by wind and by voltage level, as bars labelled with the values."""
    figure = new_figure(6.4, 2.4)
    panels = figure.subplots(1, 2)
    tips = {}
    parts = []
    for ax, keys, title in zip(panels, (("wind",), ("level",)), ("by wind", "by voltage level"),
                               strict=True):
        table = failures.table(*keys)
        rows = table.rows if table is not None else ()
        names = [str(r.values[0]) for r in rows]
        shares = [100 * r.share for r in rows]
        bars = ax.barh(names, shares, color=[_level_colour(n) for n in names])
        for i, (bar, row) in enumerate(zip(bars, rows, strict=True)):
            gid = f"{keys[0]}-{i}"
            bar.set_gid(gid)
            tips[gid] = f"{title[3:]} {row.values[0]}: P(failure) = {row.probability:.4g} " \
                        f"({row.share:.2%})"
            ax.text(min(bar.get_width(), 100) + 1, bar.get_y() + bar.get_height() / 2,
                    f"{row.probability:.3g}", va="center", fontsize=8.5)
        parts.append(", ".join(f"{n} {s:.1f}%" for n, s in zip(names, shares, strict=True)))
        ax.set_xlim(0, 125)
        ax.set_xticks([0, 25, 50, 75, 100])
        ax.set_xlabel("share of P(failure) (%)")
        ax.set_title(title, loc="left")
        ax.invert_yaxis()
    desc = f"Shares of P(failure): by wind {parts[0]}; by voltage level {parts[1]}."
    return to_svg(figure, "fig-breakdown", "Failures by wind and by voltage level", desc, tips)


def _level_colour(name: str) -> str:
    return {"high": RED, "low": BLUE, "medium": ORANGE}.get(name, GREY)


@styled
def paths_figure(paths: Sequence[FailurePath]) -> Svg:
    """Battery charge along the most probable failure paths: over the whole mission (hours)
    and over the final sortie's steps, each action marked."""
    figure = new_figure(6.8, 3.4)
    whole, sortie = figure.subplots(1, 2, width_ratios=(1.1, 1))
    tips: dict[str, str] = {}
    for path in paths:
        colour = PATH_COLOURS[(path.rank - 1) % len(PATH_COLOURS)]
        dash, width = PATH_STYLES[(path.rank - 1) % len(PATH_STYLES)]
        hours = [s.minutes / 60 for s in path.steps]
        whole.step(hours, [s.charge_ah for s in path.steps], where="post", color=colour,
                   linewidth=width, linestyle=dash,
                   label=f"path {path.rank} (p = {path.probability_text})")
        _sortie(sortie, path, (colour, dash, width), tips)
    whole.set_xlabel("mission time (hours)")
    whole.set_ylabel("charge (Ah)")
    whole.set_title("whole path", loc="left")
    whole.grid(True, alpha=0.3)
    whole.legend(fontsize=8, loc="lower left")
    sortie.set_xlabel("steps before the failure")
    sortie.set_title("final sortie", loc="left")
    sortie.grid(True, alpha=0.3)
    _action_legend(sortie)
    desc = " ".join(path.story for path in paths)
    return to_svg(figure, "fig-paths", "Battery charge along the most probable failure paths",
                  desc, tips)


def _sortie(ax: Axes, path: FailurePath, style: tuple[str, str, float],
            tips: dict[str, str]) -> None:
    colour, dash, width = style
    steps = path.sortie
    end = steps[-1].step
    xs = [s.step - end for s in steps]
    ax.step(xs, [s.charge_ah for s in steps], where="post", color=colour, linewidth=width,
            linestyle=dash)
    for i, (x, step) in enumerate(zip(xs, steps, strict=True)):
        failing = step.action.startswith("oob")
        marker = "X" if failing else ACTION_MARKERS.get(step.action, "")
        if not marker:
            continue
        dot = ax.scatter([x], [step.charge_ah], marker=marker, s=60 if failing else 22,
                         color=RED if failing else colour, zorder=4)
        gid = f"p{path.rank}-s{i}"
        dot.set_gid(gid)
        tips[gid] = (f"path {path.rank}, step {step.step}: {step.event}; "
                     f"{step.charge_ah:.1f} Ah ({step.soc:.0%}), {step.wind} wind, "
                     f"{step.level} voltage")


def _action_legend(ax: Axes) -> None:
    shown = {"take-off": "^", "fly": ">", "inspect": "o", "back": "<", "land": "v"}
    handles = [Line2D([], [], marker=m, linestyle="none", color="#444444", label=name)
               for name, m in shown.items()]
    handles.append(Line2D([], [], marker="X", linestyle="none", color=RED,
                          label="out of battery"))
    ax.legend(handles=handles, fontsize=8, loc="upper right", ncols=2)


@styled
def time_figure(timing: MissionTime) -> Svg:
    """The CDFs of mission time to success and to failure, quantiles and deadlines marked."""
    figure = new_figure(6.4, 3.4)
    ax = figure.add_subplot()
    ax.step(timing.minutes, timing.success_cdf, where="post", color=GREEN,
            label="P(success by then)")
    ax.step(timing.minutes, timing.failure_cdf, where="post", color=RED,
            label="P(failed by then)")
    tips: dict[str, str] = {}
    for i, (q, value) in enumerate(timing.quantiles):
        ax.axvline(value, color=GREEN, linestyle=":", linewidth=1)
        ax.text(value, 0.05 + 0.08 * i, f" {q:.0%}: {value:g} min", fontsize=8.5, color=GREEN,
                transform=ax.get_xaxis_transform())
    for i, d in enumerate(timing.deadlines):
        dot = ax.scatter([d.minutes], [d.p_success], color=BLUE, s=18, zorder=4)
        dot.set_gid(f"deadline-{i}")
        tips[f"deadline-{i}"] = f"within {d.text} ({d.minutes:g} min): P(success) = " \
                                f"{d.p_success:.6g}"
    ax.set_xlim(_start(timing), float(timing.minutes[-1]))
    ax.set_ylim(0, 1.02)
    ax.set_xlabel("mission time (minutes)")
    ax.set_ylabel("probability")
    day = timing.working_day_minutes
    top = ax.secondary_xaxis("top", functions=(_scaled(1 / day), _scaled(day)))
    top.set_xlabel(f"working days of {day / 60:g} h")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="center left", fontsize=8.5)
    quantiles = ", ".join(f"{q:.0%} by {v:g} min" for q, v in timing.quantiles)
    desc = (f"Cumulative distribution of mission time. Given success, the mission ends "
            f"{quantiles}. P(success) overall is {timing.p_success:.6g}.")
    return to_svg(figure, "fig-time", "Mission time: cumulative distribution", desc, tips)


def _scaled(factor: float) -> Callable[[ArrayLike], ArrayLike]:
    """Multiplication by *factor*, as a secondary axis's conversion."""

    def scale(values: ArrayLike) -> ArrayLike:
        return np.asarray(values, dtype=np.float64) * factor

    return scale


def _start(timing: MissionTime) -> float:
    """Where the curves leave 0, less a margin, so the plot is not mostly empty."""
    mass = timing.success_cdf + timing.failure_cdf
    total = max(float(mass[-1]), 1e-300)
    first = int(np.argmax(mass >= 1e-4 * total))
    span = float(timing.minutes[-1] - timing.minutes[first])
    return max(0.0, float(timing.minutes[first]) - 0.05 * span)


@styled
def sweep_figures(sweep: SweepResults, values: Mapping[str, float]) -> tuple[Svg, ...]:
    """One figure per property of the sweep (as ``sweep --plot``), each requirement's
    bound drawn, the points where it stops holding (or holds again) marked, and this
    report's own point (*values*: the report's value of each property) as a star."""
    formulas = dict(sweep.formulas)
    return tuple(_sweep_figure(sweep, prop, i, formulas, values.get(prop))
                 for i, prop in enumerate(sweep.properties))


def _sweep_figure(sweep: SweepResults, prop: str, index: int, formulas: dict[str, str],
                  here: float | None) -> Svg:
    figure = sweep_figure(sweep.frame, sweep.x, prop, properties=formulas or None)
    figure.set_size_inches(6.8, 3.6)
    ax = figure.axes[0]
    tips: dict[str, str] = {}
    bounds = [r for r in sweep.requirements if r.prop == prop]
    for req in bounds:
        ax.axhline(req.bound, color=DARK_RED, linestyle="--", linewidth=0.9)
        ax.text(0.99, req.bound, f"{req.text} ", color=DARK_RED, fontsize=8, va="top",
                ha="right", transform=ax.get_yaxis_transform())
    turns = [c for c in sweep.crossings if c.prop == prop]
    for i, turn in enumerate(turns):
        dot = ax.scatter([turn.after], [turn.after_value], s=110, facecolors="none",
                         edgecolors=DARK_RED if turn.stops else GREEN, linewidths=1.8, zorder=5)
        dot.set_gid(f"turn-{i}")
        tips[f"turn-{i}"] = _turn_text(turn, sweep.x)
    if sweep.here is not None and here is not None and math.isfinite(here):
        star = ax.scatter([sweep.here], [here], marker="*", s=160, color="black", zorder=6,
                          label="this report")
        star.set_gid("here")
        tips["here"] = f"this report: {sweep.x} = {sweep.here:g}, {prop} = {here:.6g}"
    words = "; ".join(_turn_text(t, sweep.x) for t in turns)
    desc = (f"{prop} against {sweep.x} over {sweep.points} sweep points, one line per "
            f"combination of the other varied keys. {words or 'No requirement turns here'}.")
    caption = "One line per combination of the other varied keys; the star is this report's " \
        "own setting."
    if bounds:
        caption += (" The dashed line is the requirement's bound; circles mark where it stops "
                    "holding (red) or holds again (green).")
    return to_svg(figure, f"fig-sweep-{index}", f"Sweep: {prop} against {sweep.x}", desc, tips,
                  caption)


def _turn_text(turn: Crossing, x: str) -> str:
    what = "stops holding" if turn.stops else "holds again"
    line = f" ({turn.line})" if turn.line else ""
    return f"{turn.requirement} {what} between {x} = {turn.before:g} and {turn.after:g}{line}"


def _numbers(data: ReportData) -> dict[str, float]:
    """The report's numeric results by name (true/false as 1/0, as a sweep draws them)."""
    return {q.name: float(q.value) for q in data.verdict.quantities if q.value is not None}


@dataclass(frozen=True, slots=True)
class ReportFigures:
    """Every figure of a report (the sweep's only with a sweep)."""

    farm: Svg
    battery: Svg
    heatmap: Svg | None
    breakdown: Svg | None
    paths: Svg | None
    time: Svg
    sweeps: tuple[Svg, ...]


def draw_figures(data: ReportData) -> ReportFigures:
    """Draw the figures of *data* (those about failures only if the mission can fail)."""
    fails = data.failures.probability > 0
    recharges = next((q.value for q in data.verdict.quantities if q.name == "exp_recharges"
                      and isinstance(q.value, float)), None)
    return ReportFigures(
        farm=farm_figure(data.farm),
        battery=battery_figure(data.battery, recharges),
        heatmap=heatmap_figure(data.farm, data.failures) if fails else None,
        breakdown=breakdown_figure(data.failures) if fails else None,
        paths=paths_figure(data.failures.paths) if data.failures.paths else None,
        time=time_figure(data.time),
        sweeps=sweep_figures(data.sweep, _numbers(data)) if data.sweep is not None else (),
    )
