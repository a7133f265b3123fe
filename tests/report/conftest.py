"""Reports made once per test session: a tiny farm that fails often, and the paper's case 1.

The tiny mission (3 x 3 turbines, 6 Ah, reserve 0.1, 15 recharges: 2,607 states) fails
with probability 0.105, so every part of the page has something to show; it takes
about a second. Case 1 (176,481 states) takes about 20 s and is made only for the
tests that need the real size.
"""

from __future__ import annotations

import html.parser
import json
from dataclasses import dataclass
from pathlib import Path

import pytest
from click.testing import CliRunner, Result

from veribattery.cli import cli

REPO = Path(__file__).resolve().parents[2]
EXAMPLE = str(REPO / "configs" / "example.yaml")
CASE1 = str(REPO / "configs" / "paper" / "case1.yaml")
#: A tiny farm whose missions fail about one time in ten, and a requirement that holds.
TINY = ("farm.cols=3", "farm.rows=3", "farm.base=[0,0]", "strategy.safe_t=0.1",
        "battery.capacity_ah=6", "battery.max_recharges=15",
        'requirements=["p_success >= 0.85"]')
TINY_ARGS = tuple(arg for item in TINY for arg in ("--set", item))
#: Every section of a page with a simulation and a sweep, by id.
SECTIONS = ("verdict", "mission", "failures", "time", "simulation", "sweep", "reproducibility")


def report(*args: str) -> Result:
    """``veribattery report ARGS`` through click's runner and the CLI group, as a user
    runs it (click's own option errors become one line there)."""
    return CliRunner().invoke(cli, ["report", *args])


def command(*args: str) -> Result:
    """Another ``veribattery`` command, through the CLI group."""
    return CliRunner().invoke(cli, list(args))


def command_json(*args: str) -> dict[str, object]:
    """The JSON a ``veribattery ... --format json`` command prints."""
    result = command(*args, "--format", "json")
    assert result.exit_code in (0, 1), result.output
    data: dict[str, object] = json.loads(result.stdout)
    return data


@dataclass(frozen=True)
class Made:
    """A report written by the CLI: its file, text, the runner's result and its JSON block."""

    path: Path
    result: Result

    @property
    def text(self) -> str:
        return self.path.read_text(encoding="utf-8")

    @property
    def data(self) -> dict[str, object]:
        return embedded_json(self.text)


def embedded_json(page: str) -> dict[str, object]:
    """The page's ``#report-data`` JSON block."""
    start = page.index('<script type="application/json" id="report-data">')
    body = page[page.index(">", start) + 1: page.index("</script>", start)]
    data: dict[str, object] = json.loads(body)
    return data


@pytest.fixture(scope="session")
def tiny_report(tmp_path_factory: pytest.TempPathFactory) -> Made:
    path = tmp_path_factory.mktemp("tiny") / "tiny.html"
    result = report(EXAMPLE, *TINY_ARGS, "-o", str(path), "--runs", "1000")
    assert result.exit_code == 0, result.output
    return Made(path, result)


@pytest.fixture(scope="session")
def case1_report(tmp_path_factory: pytest.TempPathFactory) -> Made:
    path = tmp_path_factory.mktemp("case1") / "case1.html"
    result = report(CASE1, "-o", str(path))
    assert result.exit_code == 0, result.output
    return Made(path, result)


class Outline(html.parser.HTMLParser):
    """Headings, tables, figures and ids of a page, as the parser sees them."""

    def __init__(self) -> None:
        super().__init__()
        self.headings: list[int] = []
        self.ids: list[str] = []
        self.th_without_scope = 0
        self.tables = 0
        self.svgs: list[dict[str, str | None]] = []
        self.urls: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        named = dict(attrs)
        if tag in ("h1", "h2", "h3", "h4", "h5", "h6"):
            self.headings.append(int(tag[1]))
        if named.get("id"):
            self.ids.append(str(named["id"]))
        if tag == "table":
            self.tables += 1
        if tag == "th" and "scope" not in named:
            self.th_without_scope += 1
        if tag == "svg":
            self.svgs.append(named)
        for key in ("src", "href"):
            if named.get(key):
                self.urls.append(str(named[key]))


def outline(page: str) -> Outline:
    parser = Outline()
    parser.feed(page)
    return parser
