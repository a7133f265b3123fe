"""The Pareto figure and CSV from given points: what is drawn, the file types, the rows."""

from __future__ import annotations

import csv
from fractions import Fraction
from pathlib import Path

import pytest

from veribattery.synthesis.pareto import (
    PARETO_COLUMNS,
    Bs1Point,
    FrontPoint,
    pareto_figure,
    write_pareto_csv,
    write_pareto_figure,
)

FRONT = (FrontPoint(0.4, 500.0), FrontPoint(0.1, 90.5), FrontPoint(0.2346, 276.25))
BS1 = (Bs1Point(Fraction(3, 10), 0.2346, 788.0), Bs1Point(Fraction(1, 20), 0.31, 900.0),
       Bs1Point(Fraction(1, 10), 0.2346, 788.0))


def test_figure_draws_the_front_in_order_and_bs1_labelled() -> None:
    figure = pareto_figure(FRONT, BS1, p_max=0.433)
    (ax,) = figure.axes
    front, p_max = ax.get_lines()
    assert list(front.get_xdata()) == [90.5, 276.25, 500.0]
    assert list(front.get_ydata()) == [0.1, 0.2346, 0.4]
    assert list(p_max.get_ydata()) == [0.433, 0.433]
    (bs1,) = ax.collections
    assert bs1.get_offsets().tolist() == [[788.0, 0.2346], [900.0, 0.31], [788.0, 0.2346]]
    # One label per point, safe_t in order: 0.1 and 0.3 give the same strategy here.
    assert sorted(t.get_text() for t in ax.texts) == ["0.05", "0.1, 0.3"]
    assert ax.get_ylim() == (0, 1)
    assert ax.get_ylabel() == "P(success)"
    assert "failed missions included" in ax.get_xlabel()
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels == ["fastest strategy with P(success) ≥ p", "BS1 (safe_t)",
                      "best P(success) = 0.433"]


def test_figure_without_points() -> None:
    (ax,) = pareto_figure((), ()).axes
    assert ax.get_lines() == [] and ax.get_legend() is None


@pytest.mark.parametrize(("suffix", "magic"), [
    (".png", b"\x89PNG"), (".svg", b"<?xml"), (".pdf", b"%PDF"),
])
def test_figure_file_type_follows_the_suffix(tmp_path: Path, suffix: str, magic: bytes) -> None:
    path = write_pareto_figure(tmp_path / f"front{suffix}", FRONT, BS1)
    assert path.read_bytes().startswith(magic)
    assert [p.name for p in tmp_path.iterdir()] == [f"front{suffix}"]


def test_csv(tmp_path: Path) -> None:
    path = tmp_path / "front.csv"
    write_pareto_csv(path, FRONT, BS1)
    with path.open(newline="", encoding="utf-8") as stream:
        header, *rows = list(csv.reader(stream))
    assert tuple(header) == PARETO_COLUMNS
    assert rows == [
        ["front", "0.1", "", "0.1", "90.5"], ["front", "0.2346", "", "0.2346", "276.25"],
        ["front", "0.4", "", "0.4", "500.0"],
        ["bs1", "", "0.05", "0.31", "900.0"], ["bs1", "", "0.1", "0.2346", "788.0"],
        ["bs1", "", "0.3", "0.2346", "788.0"],
    ]
