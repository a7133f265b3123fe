"""The seed paper's Fig. 6 and Fig. 8, and Table 3, reproduced through the sweep machinery.

Fig. 6 and Fig. 8 are drawn from a sweep of the four battery models over new-battery
capacities 5.0-20.0 Ah in 0.1 Ah steps (604 points) at the paper's setting (``safe_t``
0.3, ``p_wsp_c`` 0.1), checking only the properties the figures drawn need (Fig. 6:
P(success); Fig. 8: expected mission time, and given success). Its durable results
(``capacity_sweep.csv`` for both, ``fig6_sweep.csv`` or ``fig8_sweep.csv`` for one) make
every reproduction resumable: a rerun after an interruption checks only the missing
points. pandas and
matplotlib are imported inside the functions that draw.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from veribattery._files import staged
from veribattery.analyses.paper import TABLE3
from veribattery.config.schema import PAPER_PROPERTIES
from veribattery.sweep import parse_axis, run_sweep

if TYPE_CHECKING:
    import pandas as pd
    from matplotlib.axes import Axes

__all__ = [
    "CAPACITY_AXES",
    "CAPACITY_RESULTS",
    "CAPACITY_SETS",
    "FIGURE_PROPERTIES",
    "GIVEN_SUCCESS",
    "MODELS",
    "OPTIMAL_COLUMNS",
    "OPTIMAL_RESULTS",
    "TABLE3_AXES",
    "SweepOptions",
    "capacity_results",
    "capacity_sets",
    "capacity_sweep",
    "draw_fig6",
    "draw_fig8",
    "optimal_curves",
    "optimal_sweep",
    "sweep_results",
    "table3_frame",
    "table3_sweep",
]

MODELS = ("advanced", "basic_high", "basic_medium", "basic_low")
#: Fig. 6/8's grid: model slowest, then capacity.
CAPACITY_AXES = (f"battery.model={','.join(MODELS)}", "battery.capacity_ah=5:20:0.1")
#: The paper's setting for Fig. 6/8 (the baseline, written out).
CAPACITY_SETS = ("strategy.safe_t=0.3", "environment.p_wsp_c=0.1")
CAPACITY_RESULTS = "capacity_sweep.csv"
#: Table 3's four cases in the paper's order: p_wsp_c slowest, safe_t 0.3 before 0.25.
TABLE3_AXES = ("environment.p_wsp_c=0.1,0.3", "strategy.safe_t=0.3,0.25")
TABLE3_RESULTS = "table3_sweep.csv"
#: The property whose presence adds Fig. 8's third panel (expected time given success).
GIVEN_SUCCESS = "exp_mission_time_given_success"
FIGURES = ("fig6", "fig8")
#: The files each figure is written as, beside each other: ``fig6.png``, ...
FIGURE_FILES = (".png", ".svg", ".csv")
#: What each figure draws: a reproduction checks these properties only.
FIGURE_PROPERTIES = {"fig6": ("p_success",), "fig8": ("exp_mission_time", GIVEN_SUCCESS)}
#: The columns of Fig. 6's optimal curves: ``Pmax [ F "success" ]`` and its certified
#: interval (the sweep's ``--optimal`` adds them).
OPTIMAL_COLUMNS = ("p_success_max", "p_success_max_lower", "p_success_max_upper")
#: Where ``--optimal``'s sweep (the capacity sweep in synthesis mode) keeps its rows.
OPTIMAL_RESULTS = "fig6_optimal_sweep.csv"
_X = "battery.capacity_ah"
_ZOOM = (11.5, 13.5)
_STYLE = {"advanced": ("black", "-"), "basic_high": ("tab:blue", "--"),
          "basic_medium": ("tab:orange", "-."), "basic_low": ("tab:red", ":")}


@dataclass(frozen=True)
class SweepOptions:
    """How the reproduction sweeps run (as ``veribattery sweep`` takes them)."""

    jobs: int = 1
    scheduler: str | None = None
    progress: Callable[[int, int], None] | None = None
    notes: Callable[[str], None] | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    def run(self, axes: Sequence[str], sets: Sequence[str], results: Path) -> pd.DataFrame:
        """Run the sweep of *axes* with durable, resumable *results*."""
        return run_sweep("", [parse_axis(a) for a in axes], sets, self.progress, jobs=self.jobs,
                         scheduler=self.scheduler, results=results, notes=self.notes,
                         **self.extra)


def capacity_sweep(
    directory: Path, options: SweepOptions, figures: Sequence[str] = ("fig6", "fig8")
) -> pd.DataFrame:
    """The capacity sweep of *figures* (``fig6``, ``fig8`` or both), checking only the
    properties they draw, resumable in ``directory/`` :func:`capacity_results`."""
    return options.run(CAPACITY_AXES, capacity_sets(figures),
                       directory / capacity_results(figures))


def optimal_sweep(directory: Path, options: SweepOptions) -> pd.DataFrame:
    """The capacity sweep in synthesis mode, resumable in ``directory/``
    :data:`OPTIMAL_RESULTS`: at each model and capacity, the best return policy's certified
    ``Pmax`` of success (rows named by :data:`OPTIMAL_COLUMNS`; one MDP per point, which
    does not depend on ``safe_t``)."""
    return options.run(CAPACITY_AXES, (*CAPACITY_SETS, "strategy.mode=synthesize"),
                       directory / OPTIMAL_RESULTS)


def optimal_curves(frame: pd.DataFrame) -> pd.DataFrame:
    """:func:`optimal_sweep`'s rows as :func:`draw_fig6` takes them: one row per model and
    capacity, with the columns :data:`OPTIMAL_COLUMNS`."""
    rows = frame[frame["property"].isin(OPTIMAL_COLUMNS)]
    table = rows.pivot(index=["battery.model", _X], columns="property", values="value")
    return table[list(OPTIMAL_COLUMNS)].astype(float).rename_axis(None, axis=1).reset_index()


def capacity_sets(figures: Sequence[str]) -> tuple[str, ...]:
    """The ``--set`` strings of the capacity sweep for *figures*: the paper's setting and
    the properties those figures draw (and no others: each costs a solve per point)."""
    names = dict.fromkeys(name for figure in FIGURES if figure in figures
                          for name in FIGURE_PROPERTIES[figure])
    chosen = {name: PAPER_PROPERTIES[name] for name in names}
    return (*CAPACITY_SETS, "properties=" + json.dumps(chosen))


def capacity_results(figures: Sequence[str]) -> str:
    """The results file of the capacity sweep for *figures*: one per property set, so
    that ``fig6`` alone, ``fig8`` alone and both each resume their own sweep."""
    chosen = [figure for figure in FIGURES if figure in figures]
    return CAPACITY_RESULTS if len(chosen) > 1 else f"{chosen[0]}_sweep.csv"


def sweep_results(what: str, optimal: bool = False) -> tuple[str, ...]:
    """The results files (in the output folder) of the sweeps ``reproduce WHAT`` runs
    (``table3``, ``fig6``, ``fig8`` or ``all``; *optimal*: with ``--optimal``)."""
    names = [TABLE3_RESULTS] if what in ("table3", "all") else []
    if what != "table3":
        names.append(capacity_results(FIGURES if what == "all" else (what,)))
    return (*names, *([OPTIMAL_RESULTS] if optimal else []))


def table3_sweep(directory: Path, options: SweepOptions) -> pd.DataFrame:
    """Table 3's four cases as a sweep, resumable in ``directory/table3_sweep.csv``."""
    return options.run(TABLE3_AXES, (), directory / TABLE3_RESULTS)


def _curves(frame: pd.DataFrame, prop: str) -> pd.DataFrame:
    """Capacity (rows) x model (columns) table of *prop*."""
    rows = frame[frame["property"] == prop]
    table = rows.pivot(index=_X, columns="battery.model", values="value").astype(float)
    return table[[m for m in MODELS if m in table.columns]].rename_axis(None, axis=1)


def draw_fig6(frame: pd.DataFrame, directory: Path,
              optimal: pd.DataFrame | None = None) -> list[Path]:
    """Fig. 6: P(success) vs capacity, with a zoom on 11.5-13.5 Ah; PNG, SVG and CSV.

    :param optimal: per model and capacity, the best policy's certified ``Pmax`` of
        success (columns ``battery.model``, ``battery.capacity_ah`` and
        :data:`OPTIMAL_COLUMNS`), drawn beside each model's BS1 curve and written to
        the CSV; None: the paper's figure.
    """
    curves = _curves(frame, "p_success")
    best = None if optimal is None else _optimal_curves(optimal, OPTIMAL_COLUMNS[0])
    figure, (main, zoom) = _figure(2, (11, 4.6), width_ratios=(1.6, 1))
    for ax in (main, zoom):
        _plot_models(ax, curves, marker_size=3 if ax is zoom else 0)
        if best is not None:
            _plot_optimal(ax, best)
        ax.set_xlabel("new-battery capacity (Ah)")
        ax.set_ylabel("P(mission success)")
    main.axvspan(*_ZOOM, color="0.85", zorder=0, label="zoomed (right)")
    main.set_title("Fig. 6: probability of mission success")
    drawn = curves if best is None else curves.join(best.add_suffix(" Pmax"))
    inside = drawn[(drawn.index >= _ZOOM[0]) & (drawn.index <= _ZOOM[1])]
    zoom.set_xlim(*_ZOOM)
    _fit_y(zoom, inside)
    zoom.set_title(f"zoom {_ZOOM[0]}-{_ZOOM[1]} Ah: the advanced model's dip")
    main.legend(loc="lower right", fontsize="small")
    if optimal is None:
        return _save(figure, curves, directory, "fig6", "p_success")
    table = curves.add_prefix("p_success:")
    for column in OPTIMAL_COLUMNS:
        table = table.join(_optimal_curves(optimal, column).add_prefix(f"{column}:"))
    return _save(figure, table, directory, "fig6", None)


def _optimal_curves(optimal: pd.DataFrame, column: str) -> pd.DataFrame:
    """Capacity (rows) x model (columns) table of *optimal*'s *column*."""
    table = optimal.pivot(index=_X, columns="battery.model", values=column).astype(float)
    return table[[m for m in MODELS if m in table.columns]].rename_axis(None, axis=1)


def _plot_optimal(ax: Axes, best: pd.DataFrame) -> None:
    # thick and pale behind the BS1 curves: where they meet, BS1 is optimal
    for model in best.columns:
        series = best[model].dropna()
        ax.plot(series.index, series, color=_STYLE[model][0], linestyle="-", linewidth=3.2,
                alpha=0.35, label=f"{model} Pmax", zorder=1)


def draw_fig8(frame: pd.DataFrame, directory: Path) -> list[Path]:
    """Fig. 8: expected mission time vs capacity (upper), basic - advanced (lower).

    HOOK (third panel): when the sweep has the property ``exp_mission_time_given_success``
    (the expected mission time conditioned on success, from the analyses issue), a third
    panel draws it; without it the figure has the paper's two panels.
    """
    times = _curves(frame, "exp_mission_time")
    given = _curves(frame, GIVEN_SUCCESS) if (frame["property"] == GIVEN_SUCCESS).any() else None
    panels = 2 if given is None else 3
    figure, axes = _figure(panels, (8, 3.3 * panels), rows=True)
    _plot_models(axes[0], times)
    axes[0].set_ylabel("E[mission time] (min)")
    axes[0].set_title("Fig. 8: expected mission time")
    axes[0].legend(fontsize="small")
    difference = times[[m for m in MODELS[1:] if m in times]].sub(times["advanced"], axis=0)
    _plot_models(axes[1], difference)
    axes[1].axhline(0, color="black", linewidth=0.8)
    axes[1].set_ylabel("basic - advanced (min)")
    axes[1].legend(fontsize="small")
    if given is not None:  # the panel the paper could not draw
        _plot_models(axes[2], given)
        axes[2].set_ylabel("E[time | success] (min)")
        axes[2].legend(fontsize="small")
    axes[-1].set_xlabel("new-battery capacity (Ah)")
    table = times.add_prefix("exp_mission_time:").join(difference.add_prefix("minus_advanced:"))
    if given is not None:
        table = table.join(given.add_prefix(f"{GIVEN_SUCCESS}:"))
    return _save(figure, table, directory, "fig8", None)


def _figure(count: int, size: tuple[float, float], *, rows: bool = False,
            width_ratios: tuple[float, ...] | None = None) -> tuple[Any, list[Axes]]:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=size, layout="constrained")
    FigureCanvasAgg(figure)
    grid = (count, 1) if rows else (1, count)
    axes = figure.subplots(*grid, sharex=rows, gridspec_kw=(
        {"width_ratios": width_ratios} if width_ratios else {}))
    return figure, list(axes)


def _plot_models(ax: Axes, curves: pd.DataFrame, marker_size: float = 0) -> None:
    for model in curves.columns:
        color, style = _STYLE[model]
        series = curves[model].dropna()  # grids may differ between models (a zoomed run)
        ax.plot(series.index, series, color=color, linestyle=style, label=model,
                marker="o" if marker_size else None, markersize=marker_size, linewidth=1.4)
    ax.grid(True, alpha=0.3)


def _fit_y(ax: Axes, inside: pd.DataFrame) -> None:
    low, high = float(inside.min().min()), float(inside.max().max())
    pad = max((high - low) * 0.08, 1e-4)
    ax.set_ylim(low - pad, high + pad)


def _save(figure: Any, table: pd.DataFrame, directory: Path, name: str,
          value: str | None) -> list[Path]:
    directory.mkdir(parents=True, exist_ok=True)
    paths = [directory / f"{name}{suffix}" for suffix in FIGURE_FILES]
    out = table.rename_axis("capacity_ah")
    if value is not None:
        out = out.add_prefix(f"{value}:")
    with ExitStack() as stack:
        png, svg, csv = (stack.enter_context(staged(p, suffix=p.suffix)) for p in paths)
        figure.savefig(png, dpi=150)
        figure.savefig(svg)
        out.to_csv(csv)  # shortest round-trip repr: 12.2, not 12.199999999999999
    return paths


def table3_frame(frame: pd.DataFrame) -> pd.DataFrame:
    """Table 3 from its sweep: each case's paper values, ours and the relative differences."""
    import pandas as pd

    rows = []
    for case, index in zip(TABLE3, sorted(frame["point"].unique()), strict=True):
        ours = frame[frame["point"] == index].set_index("property")
        row: dict[str, object] = {"case": case.case, "safe_t": case.safe_t,
                                  "p_wsp_c": case.p_wsp_c,
                                  "states": int(ours["states"].iloc[0]),
                                  "transitions": int(ours["transitions"].iloc[0])}
        for quantity in ("p_success", "exp_mission_time", "exp_recharges"):
            paper, mine = float(getattr(case, quantity)), float(ours.loc[quantity, "value"])
            row |= {f"{quantity}_paper": paper, f"{quantity}_ours": mine,
                    f"{quantity}_rel_diff": (mine - paper) / paper}
        rows.append(row)
    return pd.DataFrame(rows)
