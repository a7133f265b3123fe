"""``veribattery report``: one self-contained HTML page a safety reviewer can open.

The page puts the verdict first (requirements decided on certified intervals), then
the mission as a picture, where failures come from, mission time, Monte-Carlo
estimates, a sweep's figures if given, and what is needed to reproduce it. Its
numbers are those of ``check``, ``explain``, ``distribution`` and ``simulate`` for
the same config, computed on one build of the model::

    cfg = load_config("configs/paper/case1.yaml")
    write_report(Path("case1.html"), cfg, ReportOptions(title="case1.yaml"))

Modules: :mod:`~veribattery.report.data` (the records), :mod:`~veribattery.report.collect`
(one build, every analysis), :mod:`~veribattery.report.verdict`,
:mod:`~veribattery.report.picture`, :mod:`~veribattery.report.failures`,
:mod:`~veribattery.report.timing`, :mod:`~veribattery.report.montecarlo`,
:mod:`~veribattery.report.sweep` (a sweep's results matched to the config),
:mod:`~veribattery.report.figures` and :mod:`~veribattery.report.svg` (inline SVG),
:mod:`~veribattery.report.render` (Jinja) and :mod:`~veribattery.report.page` (the facade).
"""

from veribattery.report.collect import ReportOptions, collect_report
from veribattery.report.data import ReportData
from veribattery.report.page import make_report, page_of, write_report
from veribattery.report.sweep import SweepResults, read_sweep

__all__ = [
    "ReportData",
    "ReportOptions",
    "SweepResults",
    "collect_report",
    "make_report",
    "page_of",
    "read_sweep",
    "write_report",
]
