"""``veribattery prism --const N=2:5``: PRISM's experiments, one check per point.

Each point is checked as ``prism --const`` with its values would check it (the model
built anew when its constants change); the table has a row per point and property,
JSON a document per point under ``"points"``, CSV the constants' columns first.
"""

from __future__ import annotations

import csv
import json
import sys
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import click

from veribattery.cli.output import exact_notes, print_dim, print_imprecise, print_warnings
from veribattery.cli.tables import fit_text, print_table
from veribattery.errors import OptionError

if TYPE_CHECKING:
    from veribattery.pipeline import ModelCheckRun
    from veribattery.pipeline.mdp import MdpCheckRun

    Run = ModelCheckRun | MdpCheckRun

__all__ = ["check_experiment_options", "print_experiment"]

#: The options an experiment does not take (each needs one model and one answer).
_SINGLE_RUN = {"explain": "--explain", "simulate": "--simulate",
               "strategy_file": "--export-strategy", "induced_dir": "--export-induced"}


def check_experiment_options(analysis: Mapping[str, Any]) -> None:
    """Refuse, before any work, the options that read one run."""
    for key, option in _SINGLE_RUN.items():
        if analysis.get(key) is not None:
            raise OptionError(f"{option} reads one model: give every --const one value "
                              "(a range N=a:b checks one model per value)")


def print_experiment(points: Sequence[Mapping[str, str]], runs: Sequence[Run],
                     output_format: str, row: Callable[[Any], tuple[str, str]],
                     document: Callable[[Run], dict[str, object]],
                     csv_rows: Callable[[Run], list[list[str]]]) -> None:
    """The results of every point, in *output_format*; the constants that vary lead.

    :param row: a result as a table row shows it: ``(property, value)``;
    :param document: a run's JSON document; :param csv_rows: a run's CSV rows.
    """
    names = [name for name in points[0] if len({p[name] for p in points}) > 1]
    pairs = list(zip(points, runs, strict=True))
    for point, run in pairs:  # on stderr, whatever the format, as one run's are
        # the same warning may come from several points: each says which
        where = ", ".join(f"{n}={point[n]}" for n in names)
        print_warnings([f"{where}: {w}" if where else w for w in run.warnings])
        print_imprecise(run.results)
    if output_format == "json":
        click.echo(json.dumps({"points": [{"constants": dict(point), **document(run)}
                                          for point, run in pairs]}))
        return
    if output_format == "csv":
        writer = csv.writer(sys.stdout, lineterminator="\n")
        writer.writerow([*names, "property", "name", "value", "lower", "upper", "exact"])
        for point, run in pairs:
            writer.writerows([*(point[n] for n in names), *cells] for cells in csv_rows(run))
        return
    rows = [(*(point[n] for n in names), *row(result)) for point, run in pairs
            for result in run.results]
    print_table((*names, "property", "value"), rows)
    for note in exact_notes(cells[-1] for cells in rows):
        print_dim(fit_text(note))
    states = sorted({int(run.model_summary["states"]) for run in runs})
    sizes = f"{states[0]:,}" if len(states) == 1 else f"{states[0]:,} to {states[-1]:,}"
    count = f"{len(points)} point" + ("s" if len(points) != 1 else "")
    print_dim(f"{count}; models of {sizes} states")
