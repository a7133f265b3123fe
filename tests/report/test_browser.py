"""The report in a real browser: headless Chromium, offline, over the DevTools protocol.

Checked on the rendered page: no console error, no request but the file itself, every
section there, the verdict's numbers in the DOM equal to ``check --format json``, no
sideways scrolling at phone width, the script's buttons working, and printing. The
screenshots at desktop (1280 px) and phone (390 px) width and the printed PDF are
kept in pytest's temporary folder (printed at the end of the run with ``-rA``).
Without Chromium the tests are skipped, saying so.
"""

from __future__ import annotations

import base64
import json
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.report.browser import Browser, find_chromium
from tests.report.conftest import CASE1, EXAMPLE, SECTIONS, TINY_ARGS, Made, command_json

#: Desktop and phone viewports (CSS pixels).
DESKTOP = (1280, 900)
PHONE = (390, 844)

_VERDICT = """JSON.stringify({
  results: [...document.querySelectorAll('#results tr[data-name]')].map(row => ({
    name: row.dataset.name,
    value: row.querySelector('td[data-value]').dataset.value,
    text: row.querySelector('td[data-value]').firstChild.textContent.trim(),
    bounds: [...row.querySelectorAll('.bound')].map(b => b.dataset.value),
  })),
  requirements: [...document.querySelectorAll('#requirements tr[data-requirement]')].map(
    row => ({requirement: row.dataset.requirement, holds: row.dataset.holds,
             decided: row.dataset.decided,
             value: row.querySelector('td[data-value]').dataset.value,
             verdict: row.querySelector('.badge').textContent})),
  summary: document.getElementById('verdict-summary').textContent.trim(),
})"""


@pytest.fixture(scope="module")
def chromium() -> str:
    path = find_chromium()
    if path is None:
        pytest.skip("Chromium is not installed (Debian: apt-get install chromium); "
                    "the report was not checked in a browser")
    return path


@pytest.fixture(scope="module")
def artefacts(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("browser")


@pytest.fixture
def browser(chromium: str, tmp_path: Path) -> Iterator[Browser]:
    with Browser(chromium, tmp_path / "profile") as opened:
        yield opened


def _load(browser: Browser, made: Made, size: tuple[int, int], *, mobile: bool = False) -> None:
    browser.open(made.path.resolve().as_uri(), *size, mobile=mobile)


def _clean(browser: Browser, made: Made) -> None:
    assert browser.errors() == []
    assert set(browser.requests()) == {made.path.resolve().as_uri()}


@pytest.mark.parametrize(("made", "config", "sets"), [
    ("tiny_report", EXAMPLE, TINY_ARGS), ("case1_report", CASE1, ()),
], ids=["tiny", "case1"])
def test_the_rendered_verdict_is_checks(browser: Browser, made: str, config: str,
                                        sets: tuple[str, ...], artefacts: Path,
                                        request: pytest.FixtureRequest) -> None:
    report: Made = request.getfixturevalue(made)
    _load(browser, report, DESKTOP)
    _clean(browser, report)
    ids = browser.evaluate("[...document.querySelectorAll('section[id]')].map(s => s.id)")
    assert ids == [s for s in SECTIONS if s != "sweep"]
    shown = json.loads(browser.evaluate(_VERDICT))
    check = command_json("check", config, *sets)
    results, bounds = check["results"], check["bounds"]
    assert isinstance(results, dict) and isinstance(bounds, dict)
    assert [row["name"] for row in shown["results"]] == list(results)
    for row in shown["results"]:
        assert float(row["value"]) == results[row["name"]]
        assert [float(b) for b in row["bounds"]] == bounds[row["name"]]
        assert row["text"] == f"{results[row['name']]:.12g}"
    requirements = check["requirements"]
    assert isinstance(requirements, list)
    assert len(shown["requirements"]) == len(requirements)
    for row, theirs in zip(shown["requirements"], requirements, strict=True):
        assert row["requirement"] == theirs["requirement"]
        assert json.loads(row["holds"]) == theirs["holds"]
        assert json.loads(row["decided"]) == theirs["decided"]
        assert float(row["value"]) == theirs["value"]
        assert row["verdict"] == ("HOLDS" if theirs["holds"] else "FAILS")
    browser.screenshot(artefacts / f"{made}-desktop.png")


@pytest.mark.parametrize("made", ["tiny_report", "case1_report"])
def test_at_phone_width_nothing_scrolls_sideways(browser: Browser, made: str,
                                                 artefacts: Path,
                                                 request: pytest.FixtureRequest) -> None:
    report: Made = request.getfixturevalue(made)
    _load(browser, report, PHONE, mobile=True)
    _clean(browser, report)
    width = browser.evaluate("document.documentElement.scrollWidth")
    assert width <= PHONE[0], f"the page is {width} px wide at {PHONE[0]} px"
    path = browser.screenshot(artefacts / f"{made}-phone.png")
    print(f"screenshots in {path.parent}")


def test_the_script_works(browser: Browser, tiny_report: Made) -> None:
    _load(browser, tiny_report, DESKTOP)
    assert browser.evaluate("document.documentElement.classList.contains('js')")
    assert browser.evaluate("document.querySelectorAll('details[open]').length") == 0
    browser.evaluate("document.getElementById('expand-all').click()")
    opened = browser.evaluate("document.querySelectorAll('details[open]').length")
    assert opened == browser.evaluate("document.querySelectorAll('details').length") > 0
    browser.evaluate("document.getElementById('collapse-all').click()")
    assert browser.evaluate("document.querySelectorAll('details[open]').length") == 0
    _clean(browser, tiny_report)


def test_long_breakdowns_show_every_row_on_demand(browser: Browser, case1_report: Made) -> None:
    _load(browser, case1_report, DESKTOP)
    hidden = "[...document.querySelectorAll('tr.more')].filter(r => !r.offsetParent).length"
    assert browser.evaluate(hidden) > 0
    browser.evaluate("document.querySelectorAll('button.more-rows').forEach(b => b.click())")
    assert browser.evaluate(hidden) == 0
    _clean(browser, case1_report)


def test_it_prints(browser: Browser, tiny_report: Made, artefacts: Path) -> None:
    _load(browser, tiny_report, DESKTOP)
    pdf = base64.b64decode(browser.send("Page.printToPDF", printBackground=True)["data"])
    assert pdf.startswith(b"%PDF")
    (artefacts / "tiny_report.pdf").write_bytes(pdf)
    _clean(browser, tiny_report)
