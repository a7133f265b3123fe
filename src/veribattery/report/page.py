"""The report facade: collect the numbers, draw the figures, render the page, write it."""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

from veribattery._files import write_text
from veribattery.config import MissionConfig
from veribattery.pipeline import ProgressCallback
from veribattery.report.collect import Notes, ReportOptions, collect_report
from veribattery.report.data import ReportData
from veribattery.report.figures import draw_figures
from veribattery.report.render import render_report
from veribattery.report.sweep import SweepResults

__all__ = ["make_report", "page_of", "write_report"]


def page_of(data: ReportData, notes: Notes | None = None) -> str:
    """The HTML page of collected *data* (figures drawn here; their time is recorded)."""
    if notes is not None:
        notes("drawing the figures and writing the page")
    start = time.perf_counter()
    figures = draw_figures(data)
    seconds = (*data.provenance.timings_s, ("figures", time.perf_counter() - start))
    data = replace(data, provenance=replace(data.provenance, timings_s=seconds))
    return render_report(data, figures)


def make_report(cfg: MissionConfig, options: ReportOptions, *,
                sweep: SweepResults | None = None, progress: ProgressCallback | None = None,
                notes: Notes | None = None) -> tuple[ReportData, str]:
    """The mission report of *cfg*: its numbers, and the self-contained HTML page.

    :param sweep: a sweep's results, matched to *cfg* (:func:`~veribattery.report.read_sweep`).
    :raises VeribatteryError: as the check and the analyses raise it.
    """
    data = collect_report(cfg, options, sweep=sweep, progress=progress, notes=notes)
    return data, page_of(data, notes)


def write_report(path: Path, cfg: MissionConfig, options: ReportOptions, *,
                 sweep: SweepResults | None = None, progress: ProgressCallback | None = None,
                 notes: Notes | None = None) -> ReportData:
    """Write the report of *cfg* to *path* atomically (all or nothing, mode from the umask).

    :return: the report's numbers (e.g. whether every requirement holds).
    """
    data, page = make_report(cfg, options, sweep=sweep, progress=progress, notes=notes)
    write_text(path, page)
    return data
