"""The page as a file: self-contained, small, accessible, every section, and the CLI's
rules (exit status, nothing written on bad input, ``--runs 0``)."""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest

from tests.report.conftest import (
    CASE1,
    EXAMPLE,
    SECTIONS,
    TINY,
    TINY_ARGS,
    Made,
    outline,
    report,
)

#: The paper's baseline must fit in this (issue 24).
MOST_BYTES = 1_000_000


@pytest.mark.parametrize("made", ["tiny_report", "case1_report"])
def test_nothing_leaves_the_file(made: str, request: pytest.FixtureRequest) -> None:
    page = request.getfixturevalue(made).text
    assert "http://" not in page and "https://" not in page
    assert not re.search(r"<(img|link|iframe|object|embed)\b", page)
    assert not re.search(r"<script[^>]*\bsrc=", page)
    assert "@import" not in page and "url(" not in page.replace("url(#", "")
    # Every href is a link within the page.
    assert all(url.startswith("#") for url in outline(page).urls)


def test_the_paper_baseline_is_under_a_megabyte(case1_report: Made) -> None:
    size = case1_report.path.stat().st_size
    assert size < MOST_BYTES, f"{size:,} bytes"


def test_sections_headings_and_tables(tiny_report: Made) -> None:
    found = outline(tiny_report.text)
    for section in (s for s in SECTIONS if s != "sweep"):
        assert section in found.ids
    assert found.headings[0] == 1 and found.headings.count(1) == 1
    # Headings in order: never a level skipped on the way down.
    for before, after in zip(found.headings, found.headings[1:], strict=False):
        assert after <= before + 1, found.headings
    assert found.tables >= 10 and found.th_without_scope == 0
    assert len(found.ids) == len(set(found.ids)), "duplicate ids"


def test_every_figure_is_named_and_described(tiny_report: Made) -> None:
    page = tiny_report.text
    svgs = outline(page).svgs
    assert len(svgs) == 6  # farm, battery, heat map, breakdown, paths, time
    for svg in svgs:
        ident = svg["id"]
        assert svg["role"] == "img"
        assert svg["aria-labelledby"] == f"{ident}-title {ident}-desc"
        assert f'<title id="{ident}-title">' in page and f'<desc id="{ident}-desc">' in page
    assert page.count("<figcaption") == len(svgs)


def test_the_verdict_comes_first(tiny_report: Made) -> None:
    page = tiny_report.text
    main = page.index("<main>")
    assert page.index('id="verdict"', main) < page.index('id="mission"', main)
    assert "The requirement holds." in page and 'class="badge holds">HOLDS' in page


def test_the_model_and_config_are_in_the_page_to_rerun(tiny_report: Made) -> None:
    page = tiny_report.text
    for ident in ("config-resolved", "model-prism", "properties-props", "storm-only-props"):
        assert f'<details class="listing" id="{ident}">' in page
    assert "module Drone" in page and "label &#34;success&#34;" in page
    assert re.search(r'<code class="hash">[0-9a-f]{64}</code>', page)
    assert "<code>veribattery report " in page and "--set farm.cols=3" in page


def test_a_failing_requirement_exits_1_with_the_report_written(tmp_path: Path) -> None:
    target = tmp_path / "fails.html"
    result = report(EXAMPLE, *TINY_ARGS, "--set", 'requirements=["p_success >= 0.9"]',
                    "-o", str(target), "--runs", "0")
    assert result.exit_code == 1, result.output
    page = target.read_text(encoding="utf-8")
    assert 'class="badge fails">FAILS' in page and "not shown safe" in page
    assert 'id="simulation"' not in page  # --runs 0: no Monte-Carlo section
    assert result.stderr.splitlines()[-2:] == [f"wrote {target}", "FAIL p_success >= 0.9"]


def test_a_new_report_gets_the_umask_mode(tmp_path: Path) -> None:
    target = tmp_path / "mode.html"
    old = os.umask(0o027)
    try:
        assert report(EXAMPLE, *TINY_ARGS, "-o", str(target), "--runs", "0").exit_code == 0
    finally:
        os.umask(old)
    assert target.stat().st_mode & 0o777 == 0o640
    assert [p.name for p in tmp_path.iterdir()] == ["mode.html"]


def _one_line_error(folder: Path, *args: str) -> str:
    """Run with *args*: exit 2, one ``error:`` line, nothing new in *folder*."""
    before = sorted(folder.iterdir())
    result = report(*args)
    assert result.exit_code == 2, result.output
    assert result.stdout == ""
    assert result.stderr.startswith("error: ") and result.stderr.count("\n") == 1, \
        result.stderr
    assert sorted(folder.iterdir()) == before
    return result.stderr


def test_an_existing_output_is_kept_without_force(tmp_path: Path) -> None:
    target = tmp_path / "old.html"
    target.write_text("old")
    message = _one_line_error(tmp_path, EXAMPLE, *TINY_ARGS, "-o", str(target))
    assert "already exists; use --force" in message
    assert target.read_text() == "old"


@pytest.mark.parametrize(("extra", "expected"), [
    (("-o", "{tmp}/report.pdf"), "unsupported file type '.pdf'"),
    (("-o", "{tmp}/nofolder/report.html"), "does not exist"),
    (("-o", "{tmp}/r.html", "--runs", "-1"), "--runs must be at least 0"),
    (("-o", "{tmp}/r.html", "--runs", "10000000000001"), "--runs must be at most "
                                                          "1,000,000,000,000"),
    (("-o", "{tmp}/r.html", "--seed", "-1"), "'--seed': -1 is not in the range x>=0"),
    (("-o", "{tmp}/r.html", "--top", "0"), "--top must be at least 1"),
    (("-o", "{tmp}/r.html", "--deadline", "3 weeks"), "--deadline '3 weeks'"),
    (("-o", "{tmp}/r.html", "--working-day", "0h"), "--working-day 0h"),
    (("-o", "{tmp}/r.html", "--sweep", "{tmp}/missing.csv"),
     "--sweep {tmp}/missing.csv: no such file"),
])
def test_bad_options_are_one_line(tmp_path: Path, extra: tuple[str, ...], expected: str) -> None:
    args = [a.format(tmp=tmp_path) for a in extra]
    assert expected.format(tmp=tmp_path) in _one_line_error(tmp_path, EXAMPLE, *TINY_ARGS,
                                                             *args)


def test_a_bad_config_is_one_line(tmp_path: Path) -> None:
    message = _one_line_error(tmp_path, EXAMPLE, "--set", "strategy.safe_t=2",
                              "-o", str(tmp_path / "r.html"))
    assert "strategy.safe_t" in message


def test_the_tiny_mission_is_what_the_tests_think(tiny_report: Made) -> None:
    assert TINY[-1].startswith("requirements=")
    assert tiny_report.result.stderr.splitlines()[0] == \
        "checking the mission (build and model check)"
    assert "warning: the recharge cap" in tiny_report.result.stderr


def test_case1_is_the_papers_baseline(case1_report: Made) -> None:
    check = case1_report.data["check"]
    assert isinstance(check, dict)
    assert check["model"] == {"states": 176_481, "transitions": 350_504}
    assert CASE1.endswith("case1.yaml")


@pytest.mark.parametrize("name", ["case1.html", "case1-12.8Ah.html"])
def test_the_example_reports_in_docs_stay_self_contained(name: str) -> None:
    path = Path(__file__).resolve().parents[2] / "docs" / "reports" / name
    assert path.exists(), f"{path} is missing: `make reports` makes it"
    page = path.read_text(encoding="utf-8")
    assert path.stat().st_size < MOST_BYTES
    assert "http://" not in page and "https://" not in page
    assert all(url.startswith("#") for url in outline(page).urls)
