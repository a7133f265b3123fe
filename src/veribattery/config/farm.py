"""The wind farm's grid: cells, appointed turbines, the route and its distances.

Turbines stand on a lattice of ``cols x rows``; the cells between them are
``(cols - 1) x (rows - 1)``, named ``[x, y]``. Turbine ``(tx, ty)`` touches the cells
``[tx - 1 or tx, ty - 1 or ty]`` that exist.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from itertools import pairwise

from veribattery.config.schema import Cell, FarmConfig

__all__ = ["FarmLayout", "derive_layout", "manhattan", "route_cells"]

Turbine = tuple[int, int]


def manhattan(a: Cell, b: Cell) -> int:
    """Manhattan distance between two cells, in cells."""
    return abs(a[0] - b[0]) + abs(a[1] - b[1])


@dataclass(frozen=True, slots=True)
class FarmLayout:
    """The derived grid of one farm config; all per-route tuples are indexed by ``k``.

    :ivar cols: turbines across.
    :ivar rows: turbines up.
    :ivar base: the base cell.
    :ivar route: the cells visited, in order (cells with no appointed turbine left out).
    :ivar n: turbines appointed to route cell ``k``.
    :ivar dist: Manhattan distance from the base to route cell ``k``.
    :ivar step: distance from route cell ``k`` to ``k + 1`` (one entry fewer than the route).
    :ivar appointed: each turbine and the cell it is inspected from.
    """

    cols: int
    rows: int
    base: Cell
    route: tuple[Cell, ...]
    n: tuple[int, ...]
    dist: tuple[int, ...]
    step: tuple[int, ...]
    appointed: tuple[tuple[Turbine, Cell], ...]

    @property
    def num_cells(self) -> int:
        """``K``: the number of cells on the route."""
        return len(self.route)

    @property
    def num_turbines(self) -> int:
        """Turbines to inspect: every turbine of the lattice."""
        return sum(self.n)

    @property
    def cells(self) -> tuple[int, int]:
        """Cells across and up."""
        return (self.cols - 1, self.rows - 1)

    def n_at(self, cell: Cell) -> int:
        """Turbines appointed to *cell* (0 for a cell not on the route)."""
        return sum(1 for _, c in self.appointed if c == cell)


def route_cells(farm: FarmConfig) -> tuple[Cell, ...]:
    """Every cell in route order: a snake by rows or columns, or the explicit list."""
    nx, ny = farm.cells
    if isinstance(farm.route, tuple):
        return farm.route
    if farm.route == "snake_columns":
        return tuple((x, y) for x in range(nx) for y in _snake(ny, x))
    return tuple((x, y) for y in range(ny) for x in _snake(nx, y))


def _snake(length: int, lane: int) -> range:
    """Even lanes run forwards, odd lanes back."""
    return range(length) if lane % 2 == 0 else range(length - 1, -1, -1)


def _adjacent(turbine: Turbine, cells: tuple[int, int]) -> list[Cell]:
    tx, ty = turbine
    return [
        (x, y)
        for x in (tx - 1, tx)
        for y in (ty - 1, ty)
        if 0 <= x < cells[0] and 0 <= y < cells[1]
    ]


def _appoint(farm: FarmConfig, order: tuple[Cell, ...]) -> tuple[tuple[Turbine, Cell], ...]:
    """Each turbine goes to its adjacent cell nearest the base; ties to the earlier route cell."""
    rank = {cell: i for i, cell in enumerate(order)}

    def key(cell: Cell) -> tuple[int, int]:
        return (manhattan(cell, farm.base), rank[cell])

    turbines = [(tx, ty) for ty in range(farm.rows) for tx in range(farm.cols)]
    return tuple((t, min(_adjacent(t, farm.cells), key=key)) for t in turbines)


def derive_layout(farm: FarmConfig) -> FarmLayout:
    """Derive cells, appointed turbines, route, ``n``, ``dist`` and ``step`` from *farm*."""
    order = route_cells(farm)
    appointed = _appoint(farm, order)
    count = Counter(cell for _, cell in appointed)
    route = tuple(cell for cell in order if count[cell] > 0)
    return FarmLayout(
        cols=farm.cols,
        rows=farm.rows,
        base=farm.base,
        route=route,
        n=tuple(count[c] for c in route),
        dist=tuple(manhattan(farm.base, c) for c in route),
        step=tuple(manhattan(a, b) for a, b in pairwise(route)),
        appointed=appointed,
    )
