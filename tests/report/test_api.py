"""The report package's public API, and its templates shipped as package data."""

from __future__ import annotations

from importlib.resources import files

from click.testing import CliRunner

import veribattery.report
from veribattery.cli import cli

EXPECTED = {"ReportData", "ReportOptions", "SweepResults", "collect_report", "make_report",
            "page_of", "read_sweep", "write_report"}


def test_all_is_the_api() -> None:
    assert set(veribattery.report.__all__) == EXPECTED
    for name in EXPECTED:
        assert getattr(veribattery.report, name) is not None


def test_the_templates_are_package_data() -> None:
    # Hatch puts every file under src/veribattery in the wheel; these are read through
    # the package (jinja2.PackageLoader), never from the source tree.
    folder = files("veribattery.report") / "templates"
    names = {path.name for path in folder.iterdir()}
    assert {"report.html.j2", "macros.html.j2", "report.css", "report.js"} <= names


def test_the_command_is_listed() -> None:
    assert "report" in cli.list_commands(None)  # type: ignore[arg-type]
    result = CliRunner().invoke(cli, ["report", "--help"], terminal_width=80)
    assert result.exit_code == 0 and max(map(len, result.stdout.splitlines())) <= 80
