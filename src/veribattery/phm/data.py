"""Reading PHM logs: capacity against cycle, and discharge curves (CSV, ``#`` comments).

Files are UTF-8 text; a byte-order mark before the header (spreadsheets' "CSV UTF-8")
is accepted. Every row has as many cells as the header. Every problem is one
:class:`PhmDataError` naming the file, the line (1-based, as an editor shows it;
comment lines count), the data row (1-based, header excluded) and the column (its name,
or ``file:line:col`` for an undecodable byte or a cell without a column), what is wrong
and what would be right.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from veribattery._text import decode_text
from veribattery._types import FloatArray, IntArray
from veribattery.errors import Span, VeribatteryError

__all__ = [
    "CycleLog",
    "DischargeCurve",
    "PhmDataError",
    "Table",
    "coulomb_count",
    "read_cycles",
    "read_discharge",
    "read_table",
]

#: Columns of a capacity log.
CYCLE_COLUMNS = ("cycle", "capacity_ah")
#: The two accepted forms of a discharge log.
SOC_COLUMNS = ("soc", "voltage_v")
CURRENT_COLUMNS = ("time_s", "voltage_v", "current_a")
#: A voltage may rise above the lowest seen so far by this fraction of the curve's
#: span before it counts as "rising while discharging" (sensor noise, relaxation).
VOLTAGE_NOISE = 0.01
#: No battery reaches a megavolt (the largest packs stay near 1 kV); far beyond it the
#: step fit overflowed (1e30 V: a traceback writing the levels as decimals).
MAX_VOLTAGE_V = 1e6


class PhmDataError(VeribatteryError):
    """A PHM data file is unusable: missing column, bad cell, inconsistent rows."""


@dataclass(frozen=True, slots=True)
class Table:
    """Numeric columns of a CSV file, with the file line of every data row.

    :ivar source: the file name, for messages.
    :ivar columns: column name → values, one per data row.
    :ivar lines: the 1-based file line of each data row.
    """

    source: str
    columns: dict[str, FloatArray]
    lines: tuple[int, ...]

    def __len__(self) -> int:
        return len(self.lines)

    def where(self, row: int, column: str) -> str:
        """``file:line: row R, column 'c'`` for data row index *row* (0-based)."""
        return f"{self.source}:{self.lines[row]}: row {row + 1}, column {column!r}"

    def error(self, row: int, column: str, message: str) -> PhmDataError:
        """A one-line error located at *row*, *column*."""
        return PhmDataError(f"{self.where(row, column)}: {message}")


def read_table(path: str | Path, forms: Sequence[Sequence[str]]) -> Table:
    """Read the CSV at *path*, keeping the columns of the first of *forms* it has.

    Lines starting with ``#`` (after blanks) and empty lines are skipped; the first
    other line is the header. Every kept cell must be a finite number.

    :raises PhmDataError: on unreadable files, missing columns and bad cells.
    """
    source = str(path)
    text = _read_text(path, source)
    rows = [(n, line) for n, line in enumerate(text.splitlines(), 1) if _is_data(line)]
    if not rows:
        raise PhmDataError(f"{source}: no header line; expected columns {_wanted(forms)}")
    header = _fields(rows[0][1])
    form = _pick_form(source, rows[0], header, forms)
    for index, (line, row_text) in enumerate(rows[1:]):
        _check_cell_count(source, rows[0][1], (index, line, row_text))
    return _numeric(source, header, form, rows[1:])


def _read_text(path: str | Path, source: str) -> str:
    """The file's text (a byte-order mark dropped, as spreadsheets' "CSV UTF-8" writes)."""
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise PhmDataError(f"cannot read {source}: {exc.strerror}") from None
    return decode_text(data, source, PhmDataError)


def _is_data(line: str) -> bool:
    stripped = line.strip()
    return bool(stripped) and not stripped.startswith("#")


def _fields(line: str) -> list[str]:
    return [cell.strip() for cell in next(csv.reader([line]))]


def _wanted(forms: Sequence[Sequence[str]]) -> str:
    return " or ".join(",".join(form) for form in forms)


def _cell_starts(line: str) -> list[int]:
    """0-based index where each cell of *line* starts (commas inside quotes do not count)."""
    starts, quoted = [0], False
    for index, char in enumerate(line):
        if char == '"':
            quoted = not quoted  # a doubled quote inside a quoted cell flips twice
        elif char == "," and not quoted:
            starts.append(index + 1)
    return starts


def _pick_form(
    source: str, header_row: tuple[int, str], header: list[str], forms: Sequence[Sequence[str]]
) -> tuple[str, ...]:
    line, text = header_row
    for form in forms:
        if all(name in header for name in form):
            _check_unique(source, header_row, header, form)
            return tuple(form)
    missing = [name for name in forms[0] if name not in header]
    raise PhmDataError(
        f"{source}:{line}: header: missing column {missing[0]!r}; expected columns "
        f"{_wanted(forms)}, got {text.strip()}"
    )


def _check_unique(source: str, header_row: tuple[int, str], header: list[str],
                  form: Sequence[str]) -> None:
    for name in form:
        if header.count(name) > 1:
            second = [j for j, cell in enumerate(header) if cell == name][1]
            column = _cell_starts(header_row[1])[second] + 1
            raise PhmDataError(f"header: column {name!r} appears twice; rename or remove one",
                               Span(header_row[0], column, source))


def _check_cell_count(source: str, header: str, row: tuple[int, int, str]) -> None:
    """A data row must have as many cells as the header: an extra cell is no column's."""
    index, line, text = row
    count, expected = len(_fields(text)), len(_fields(header))
    if count == expected:
        return
    starts = _cell_starts(text)
    if count > expected:
        column = starts[expected] + 1 if len(starts) > expected else len(text) + 1
        fix = "remove the extra cell or name its column in the header"
    else:
        column, fix = len(text) + 1, "add the missing cell (an empty cell still needs its comma)"
    raise PhmDataError(f"row {index + 1} has {_cells(count)}, the header has {expected} "
                       f"({header.strip()}); {fix}", Span(line, column, source))


def _cells(count: int) -> str:
    return f"{count} cell" if count == 1 else f"{count} cells"


def _numeric(
    source: str, header: list[str], form: tuple[str, ...], rows: list[tuple[int, str]]
) -> Table:
    index = {name: header.index(name) for name in form}
    values: dict[str, list[float]] = {name: [] for name in form}
    lines = tuple(n for n, _ in rows)
    located = Table(source, {}, lines)
    for row, (_, line) in enumerate(rows):
        cells = _fields(line)
        for name, col in index.items():
            values[name].append(_number(located, row, name, cells[col]))
    return Table(source, {k: np.asarray(v, dtype=np.float64) for k, v in values.items()}, lines)


def _number(table: Table, row: int, column: str, cell: str) -> float:
    if not cell:
        raise table.error(row, column, "empty cell; expected a number")
    try:
        value = float(cell)
    except ValueError:
        raise table.error(row, column, f"not a number: {cell!r}") from None
    if not math.isfinite(value):
        raise table.error(row, column, f"{cell!r} is not a finite number (NaN/inf)")
    return value


@dataclass(frozen=True, slots=True)
class CycleLog:
    """Capacity measured at successive cycles (strictly increasing)."""

    table: Table

    @property
    def cycle(self) -> FloatArray:
        """Cycle numbers."""
        return self.table.columns["cycle"]

    @property
    def capacity_ah(self) -> FloatArray:
        """Measured capacity, Ah."""
        return self.table.columns["capacity_ah"]


def read_cycles(path: str | Path) -> CycleLog:
    """Read a ``cycle,capacity_ah`` log and check it is a fade log one can fit.

    :raises PhmDataError: fewer than 3 rows, a negative cycle, cycles not strictly
        increasing, a capacity that is not positive, or a capacity that increases overall
        (last above first).
    """
    table = read_table(path, [CYCLE_COLUMNS])
    if len(table) < 3:
        raise PhmDataError(
            f"{table.source}: {len(table)} data row(s); a fade fit needs at least 3 cycles"
        )
    cycle, capacity = table.columns["cycle"], table.columns["capacity_ah"]
    if cycle[0] < 0:  # (increasing from there: the first is the only one to look at)
        raise table.error(0, "cycle", f"must be a cycle number >= 0, got {cycle[0]:g}")
    _check_increasing(table, "cycle", cycle)
    bad = np.flatnonzero(capacity <= 0)
    if bad.size:
        raise table.error(int(bad[0]), "capacity_ah", f"must be > 0, got {capacity[bad[0]]:g}")
    if capacity[-1] > capacity[0]:
        raise table.error(
            len(table) - 1, "capacity_ah",
            f"capacity increases overall ({capacity[0]:g} Ah at row 1 to {capacity[-1]:g} Ah); "
            "a fade log must not end above where it starts",
        )
    return CycleLog(table)


def _check_increasing(table: Table, column: str, values: FloatArray) -> None:
    steps = np.flatnonzero(np.diff(values) <= 0)
    if steps.size:
        row = int(steps[0]) + 1
        raise table.error(
            row, column,
            f"{values[row]:g} does not increase on the previous row's {values[row - 1]:g}; "
            f"{column} must be strictly increasing",
        )


@dataclass(frozen=True, slots=True)
class DischargeCurve:
    """Voltage against state of charge, ordered from full (SOC 1) towards empty.

    :ivar soc: state of charge, in [0, 1], decreasing.
    :ivar voltage_v: terminal voltage at each SOC.
    :ivar charge_ah: charge delivered over the log (Coulomb counting), when known.
    :ivar source: the file name.
    """

    soc: FloatArray
    voltage_v: FloatArray
    charge_ah: float | None
    source: str


def coulomb_count(time_s: FloatArray, current_a: FloatArray, q_max_ah: float) -> FloatArray:
    """Eq. 1: ``SOC(k+1) = SOC(k) - I(k)·Δt / Q_max`` from SOC(0) = 1 (Δt in hours)."""
    result: FloatArray = 1.0 - _drawn_ah(time_s, current_a) / q_max_ah
    return result


def _drawn_ah(time_s: FloatArray, current_a: FloatArray) -> FloatArray:
    """Charge drawn up to each row, Ah. The log's total is its last entry, summed the
    same way: a total summed otherwise ended the default count at SOC 2.2e-16, not 0."""
    dt_h = np.diff(time_s) / 3600.0
    return np.concatenate(([0.0], np.cumsum(current_a[:-1] * dt_h)))


def read_discharge(path: str | Path, capacity_ah: float | None = None) -> DischargeCurve:
    """Read a discharge log: ``soc,voltage_v``, or ``time_s,voltage_v,current_a``.

    With time and current the SOC is Coulomb-counted (Eq. 1) from a full battery, with
    ``Q_max`` = *capacity_ah*, or by default the charge the log itself delivers.

    :raises PhmDataError: SOC outside [0, 1] or not monotone, time not increasing,
        negative current, fewer than 3 rows, a voltage not > 0 or rising as the battery
        discharges,
        or a *capacity_ah* that is not a positive number.
    """
    if capacity_ah is not None and not (math.isfinite(capacity_ah) and capacity_ah > 0):
        raise PhmDataError(f"capacity_ah must be a positive number (Ah), got {capacity_ah:g}")
    table = read_table(path, [SOC_COLUMNS, CURRENT_COLUMNS])
    if len(table) < 3:
        raise PhmDataError(f"{table.source}: {len(table)} data row(s); need at least 3")
    _check_voltage_range(table, table.columns["voltage_v"])
    if "soc" in table.columns:
        soc, charge, soc_column = _given_soc(table), None, "soc"
    else:
        soc, charge = _counted_soc(table, capacity_ah)
        soc_column = "current_a"
    order = np.arange(len(table)) if soc[0] >= soc[-1] else np.arange(len(table))[::-1]
    _check_soc_monotone(table, soc, order, soc_column)
    _check_voltage_falls(table, table.columns["voltage_v"], order)
    return DischargeCurve(soc[order], table.columns["voltage_v"][order], charge, table.source)


def _check_voltage_range(table: Table, voltage: FloatArray) -> None:
    """Checked before the curve's shape: a negative log (probes swapped) was otherwise
    told that -24.9 V "rises above" -25 V, and a voltage of 1e30 V overflowed the fit."""
    bad = np.flatnonzero(voltage <= 0)
    if bad.size:
        raise table.error(int(bad[0]), "voltage_v",
                          f"must be > 0, got {voltage[bad[0]]:g} V; a battery's terminal "
                          "voltage is positive (are the probes or the sign swapped?)")
    bad = np.flatnonzero(voltage > MAX_VOLTAGE_V)
    if bad.size:
        raise table.error(int(bad[0]), "voltage_v",
                          f"{voltage[bad[0]]:g} V is not a plausible battery voltage (at "
                          f"most {MAX_VOLTAGE_V:g} V); is the column in volts?")


def _given_soc(table: Table) -> FloatArray:
    soc = table.columns["soc"]
    bad = np.flatnonzero((soc < 0) | (soc > 1))
    if bad.size:
        raise table.error(int(bad[0]), "soc", f"{soc[bad[0]]:g} is outside [0, 1]")
    return soc


def _counted_soc(table: Table, capacity_ah: float | None) -> tuple[FloatArray, float]:
    time_s, current = table.columns["time_s"], table.columns["current_a"]
    _check_increasing(table, "time_s", time_s)
    bad = np.flatnonzero(current < 0)
    if bad.size:
        raise table.error(
            int(bad[0]), "current_a",
            f"{current[bad[0]]:g} A is negative; a discharge log has current >= 0 (discharging)",
        )
    with np.errstate(over="ignore"):  # an overflow gives inf, refused below
        drawn = float(_drawn_ah(time_s, current)[-1])
    if not math.isfinite(drawn):
        raise table.error(len(table) - 1, "current_a",
                          "the charge drawn over the log is beyond floating point; are "
                          "time_s in seconds and current_a in amperes?")
    if drawn <= 0:
        raise table.error(len(table) - 1, "current_a", "no charge is drawn over the log")
    q_max = drawn if capacity_ah is None else capacity_ah
    with np.errstate(over="ignore"):  # a tiny --capacity-ah: SOC -inf, refused below
        soc = coulomb_count(time_s, current, q_max)
    bad = np.flatnonzero(soc < -1e-9)
    if bad.size:
        raise table.error(
            int(bad[0]), "current_a",
            f"Coulomb-counted SOC {soc[bad[0]]:.4g} is outside [0, 1]: the log draws "
            f"{drawn:.4g} Ah, more than the capacity {q_max:g} Ah",
        )
    return np.clip(soc, 0.0, 1.0), drawn


def _check_soc_monotone(table: Table, soc: FloatArray, order: IntArray, column: str) -> None:
    ordered = soc[order]
    steps = np.flatnonzero(np.diff(ordered) > 0)
    if steps.size:
        row = int(order[steps[0] + 1])
        raise table.error(
            row, column,
            f"SOC {soc[row]:.4g} rises again; a discharge log goes one way from full to empty",
        )


def _check_voltage_falls(table: Table, voltage: FloatArray, order: IntArray) -> None:
    ordered = voltage[order]
    if float(np.ptp(ordered)) <= 1e-9 * max(float(np.max(np.abs(ordered))), 1.0):
        # Every threshold pair fits a flat curve equally: the fitted ones would be arbitrary.
        raise table.error(len(table) - 1, "voltage_v",
                          f"the voltage stays at {ordered[0]:g} V over the whole log, so no "
                          "voltage levels can be told apart; log a discharge whose voltage falls")
    tolerance = VOLTAGE_NOISE * max(float(np.ptp(ordered)), 1e-9)
    lowest = np.minimum.accumulate(ordered)
    rises = np.flatnonzero(ordered - lowest > tolerance)
    if rises.size:
        row = int(order[rises[0]])
        raise table.error(
            row, "voltage_v",
            f"{voltage[row]:g} V rises above the {lowest[rises[0]]:g} V already reached as the "
            "battery discharges; voltage must fall (within 1% of its span) as SOC falls",
        )
