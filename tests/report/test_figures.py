"""Figures as inline SVG: well-formed, named, with hover values, nothing outside, the same
bytes every time; and the filters that format the page's numbers."""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET

import pytest

from tests.report.conftest import Made, outline
from veribattery.report.render import FILTERS
from veribattery.report.svg import Svg, new_figure, styled, to_svg


@styled
def _figure(ident: str = "fig-test") -> Svg:
    figure = new_figure(3, 2)
    ax = figure.add_subplot()
    (line,) = ax.plot([1, 2, 3], [3, 1, 2])
    line.set_gid("tip-line")
    ax.set_title("A <small> & plain title")
    return to_svg(figure, ident, "Title & name", 'What it shows, "quoted"',
                  {"tip-line": "value < 3 & > 1"})


def test_an_svg_is_well_formed_and_named() -> None:
    svg = _figure()
    root = ET.fromstring(svg.markup)  # well-formed XML, even without namespaces
    assert root.tag == "svg" and root.get("id") == "fig-test" and root.get("role") == "img"
    assert root.get("aria-labelledby") == "fig-test-title fig-test-desc"
    assert root[0].tag == "title" and root[0].text == "Title & name"
    assert root[1].tag == "desc" and root[1].text == 'What it shows, "quoted"'
    assert root.get("viewBox") is not None


def test_an_svg_has_hover_values_and_keeps_only_used_prefixed_ids() -> None:
    markup = _figure().markup
    assert '<g id="fig-test-tip-line"><title>value &lt; 3 &amp; &gt; 1</title>' in markup
    ids = re.findall(r'\sid="([^"]+)"', markup)
    assert all(i.startswith("fig-test") for i in ids)
    for ref in re.findall(r'href="#([^"]+)"|url\(#([^)]+)\)', markup):
        assert (ref[0] or ref[1]) in ids


def test_an_svg_refers_to_nothing_outside() -> None:
    markup = _figure().markup
    assert "http" not in markup and "xmlns" not in markup and "xlink:" not in markup
    assert "<?xml" not in markup and "DOCTYPE" not in markup and "<metadata" not in markup
    assert "<image" not in markup


def test_an_svg_is_the_same_every_time() -> None:
    assert _figure().markup == _figure().markup
    assert _figure("fig-a").markup.replace("fig-a", "X") == \
        _figure("fig-b").markup.replace("fig-b", "X")


def test_the_report_figures_hold_no_raster_image(tiny_report: Made) -> None:
    page = tiny_report.text
    assert "<image" not in page and "data:image" not in page
    titles = [svg["aria-labelledby"] for svg in outline(page).svgs]
    assert len(titles) == len(set(titles))


@pytest.mark.parametrize(("name", "value", "expected"), [
    ("num", 4796.963222950825, "4796.96322295"),
    ("num", 1.0, "1"),
    ("num", True, "true"),
    ("num", None, "undefined"),
    ("num", math.inf, "Infinity"),
    ("full", 0.999999999998424, "0.999999999998424"),
    ("jsvalue", 0.1 + 0.2, "0.30000000000000004"),
    ("jsvalue", math.nan, "null"),
    ("jsvalue", None, "null"),
    ("jsvalue", False, "false"),
    ("jsvalue", math.inf, "Infinity"),
    ("sig", 0.000164232032682, "0.000164232"),
    ("pct", 0.75, "75.0 %"),
    ("count", 176481, "176,481"),
    ("bar_width", 1.5, "6.000rem"),
])
def test_filters_format_and_never_compute(name: str, value: object, expected: str) -> None:
    assert FILTERS[name](value) == expected  # type: ignore[operator]
