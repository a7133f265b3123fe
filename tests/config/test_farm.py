"""Grid derivation: appointed turbines, n per cell, route, dist and step."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from veribattery.config import FarmLayout, derive_layout, load_config
from veribattery.config.farm import manhattan, route_cells
from veribattery.config.schema import FarmConfig


def _layout(**farm: object) -> FarmLayout:
    return derive_layout(FarmConfig.model_validate(farm))


def _m(i: int, base: int) -> int:
    """Turbines per cell along one axis: two in the base's column/row, else one."""
    return 2 if i == base else 1


def test_paper_farm_has_36_turbines_in_25_cells() -> None:
    layout = derive_layout(load_config("").farm)
    assert layout.num_turbines == 36
    assert layout.num_cells == 25
    assert layout.cells == (5, 5)


@pytest.mark.parametrize(("cell", "n"), [((0, 0), 1), ((2, 0), 2), ((2, 2), 4), ((4, 4), 1)])
def test_paper_cells_named_in_the_paper(cell: tuple[int, int], n: int) -> None:
    assert derive_layout(load_config("").farm).n_at(cell) == n


def test_paper_n_is_m_x_times_m_y() -> None:
    layout = derive_layout(load_config("").farm)
    m = (1, 1, 2, 1, 1)
    for cell, n in zip(layout.route, layout.n, strict=True):
        assert n == m[cell[0]] * m[cell[1]]


def test_snake_rows_route_dist_and_step() -> None:
    layout = derive_layout(load_config("").farm)
    assert layout.route[:7] == ((0, 0), (1, 0), (2, 0), (3, 0), (4, 0), (4, 1), (3, 1))
    assert layout.route[-1] == (4, 4)
    assert layout.dist[:6] == (4, 3, 2, 3, 4, 3)
    assert layout.dist[12] == 0  # the base cell [2, 2]
    assert layout.step == (1,) * 24


def test_snake_columns_route() -> None:
    layout = _layout(route="snake_columns")
    assert layout.route[:7] == ((0, 0), (0, 1), (0, 2), (0, 3), (0, 4), (1, 4), (1, 3))
    assert layout.num_turbines == 36


def test_non_square_farm_with_corner_base() -> None:
    layout = _layout(cols=7, rows=4, base=[0, 1])
    assert layout.cells == (6, 3)
    assert layout.num_cells == 18
    assert layout.num_turbines == 28
    assert layout.n_at((0, 1)) == 4
    assert layout.n_at((0, 0)) == 2
    assert layout.n_at((5, 1)) == 2
    assert layout.n_at((5, 2)) == 1
    assert layout.dist[:6] == (1, 2, 3, 4, 5, 6)
    assert layout.route[6] == (5, 1)


def test_explicit_route_gives_longer_steps() -> None:
    route = [[0, 0], [1, 1], [1, 0], [0, 1]]
    layout = _layout(cols=3, rows=3, base=[0, 0], route=route)
    assert layout.route == ((0, 0), (1, 1), (1, 0), (0, 1))
    assert layout.step == (2, 1, 2)
    assert layout.dist == (0, 2, 1, 1)
    assert layout.n == (4, 1, 2, 2)


def test_smallest_farm_has_one_cell() -> None:
    layout = _layout(cols=2, rows=2, base=[0, 0])
    assert layout.route == ((0, 0),)
    assert layout.n == (4,)
    assert layout.step == ()


@given(
    cols=st.integers(2, 8),
    rows=st.integers(2, 8),
    bx=st.integers(0, 6),
    by=st.integers(0, 6),
    columns=st.booleans(),
)
def test_every_turbine_goes_to_a_nearest_adjacent_cell(
    cols: int, rows: int, bx: int, by: int, columns: bool
) -> None:
    bx, by = min(bx, cols - 2), min(by, rows - 2)
    route = "snake_columns" if columns else "snake_rows"
    farm = FarmConfig.model_validate({"cols": cols, "rows": rows, "base": [bx, by], "route": route})
    layout = derive_layout(farm)
    assert layout.num_turbines == cols * rows
    assert set(layout.route) == set(route_cells(farm))
    for (tx, ty), cell in layout.appointed:
        assert tx - 1 <= cell[0] <= tx and ty - 1 <= cell[1] <= ty
    for cell, n in zip(layout.route, layout.n, strict=True):
        assert n == _m(cell[0], bx) * _m(cell[1], by)
    assert all(s == 1 for s in layout.step)
    assert layout.dist == tuple(manhattan((bx, by), c) for c in layout.route)
