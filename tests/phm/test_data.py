"""CSV readers: comments, Coulomb counting (Eq. 1), and every bad-input case, one line each."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests.phm.helpers import write_csv
from veribattery.phm.data import PhmDataError, coulomb_count, read_cycles, read_discharge


def test_comments_and_blank_lines_skipped(tmp_path: Path) -> None:
    path = tmp_path / "c.csv"
    path.write_text("# made by hand\n\ncycle,capacity_ah\n0,11\n# mid-file note\n10,10.9\n"
                    "20,10.8\n")
    log = read_cycles(path)
    assert log.cycle.tolist() == [0, 10, 20]
    assert log.table.lines == (4, 6, 7)


def test_extra_columns_and_any_order(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "c.csv", "temp_c,capacity_ah,cycle",
                     [(25, 11, 1), (25, 10.9, 2), (26, 10.7, 3)])
    assert read_cycles(path).capacity_ah.tolist() == [11, 10.9, 10.7]


def test_coulomb_counting_by_hand() -> None:
    # 2 A for 1800 s then 4 A for 900 s: 1 Ah + 1 Ah drawn of Q_max 2 Ah.
    soc = coulomb_count(np.array([0.0, 1800.0, 2700.0]), np.array([2.0, 4.0, 4.0]), 2.0)
    assert soc.tolist() == pytest.approx([1.0, 0.5, 0.0])


def test_discharge_from_current_uses_logged_charge(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "d.csv", "time_s,voltage_v,current_a",
                     [(0, 25, 2), (1800, 22, 4), (2700, 20, 4)])
    curve = read_discharge(path)
    assert curve.charge_ah == pytest.approx(2.0)
    assert curve.soc.tolist() == pytest.approx([1.0, 0.5, 0.0])
    assert read_discharge(path, capacity_ah=4.0).soc.tolist() == pytest.approx([1, 0.75, 0.5])


def test_discharge_soc_ascending_is_reordered(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "d.csv", "soc,voltage_v", [(0.0, 20), (0.5, 22), (1.0, 25)])
    curve = read_discharge(path)
    assert curve.soc.tolist() == [1.0, 0.5, 0.0]
    assert curve.voltage_v.tolist() == [25, 22, 20]


BAD_CYCLES = [
    ("cycle,capacity\n0,11\n1,10\n2,9\n",
     r"c.csv:1: header: missing column 'capacity_ah'"),
    ("cycle,capacity_ah\n0,11\n1,abc\n2,9\n",
     r"c.csv:3: row 2, column 'capacity_ah': not a number: 'abc'"),
    ("cycle,capacity_ah\n0,11\n1,nan\n2,9\n",
     r"c.csv:3: row 2, column 'capacity_ah': 'nan' is not a finite number"),
    ("cycle,capacity_ah\n0,11\n1,\n2,9\n",
     r"c.csv:3: row 2, column 'capacity_ah': empty cell"),
    ("cycle,capacity_ah\n0,11\n1,10.9\n",
     r"c.csv: 2 data row\(s\); a fade fit needs at least 3 cycles"),
    ("cycle,capacity_ah\n0,11\n5,10.9\n5,10.8\n",
     r"c.csv:4: row 3, column 'cycle': 5 does not increase .* strictly increasing"),
    ("cycle,capacity_ah\n# note\n0,11\n5,10.9\n3,10.8\n",
     r"c.csv:5: row 3, column 'cycle'"),
    ("cycle,capacity_ah\n0,10\n5,10.5\n10,10.9\n",
     r"c.csv:4: row 3, column 'capacity_ah': capacity increases overall"),
    ("cycle,capacity_ah\n0,11\n5,-1\n10,10.9\n",
     r"c.csv:3: row 2, column 'capacity_ah': must be > 0"),
    ("cycle,capacity_ah\n-5,11\n0,10.9\n10,10.8\n",
     r"c.csv:2: row 1, column 'cycle': must be a cycle number >= 0, got -5"),
    ("# only a comment\n", r"c.csv: no header line"),
]


@pytest.mark.parametrize(("text", "message"), BAD_CYCLES, ids=[m[:40] for _, m in BAD_CYCLES])
def test_bad_cycles(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "c.csv"
    path.write_text(text)
    with pytest.raises(PhmDataError, match=message) as info:
        read_cycles(path)
    assert "\n" not in str(info.value)


BAD_DISCHARGE = [
    ("soc,volts\n1,25\n0.5,22\n0,20\n", r"d.csv:1: header: missing column 'voltage_v'"),
    ("soc,voltage_v\n1,25\n1.5,22\n0,20\n", r"d.csv:3: row 2, column 'soc': 1.5 is outside"),
    ("soc,voltage_v\n1,25\n-0.1,22\n0,20\n", r"d.csv:3: row 2, column 'soc': -0.1 is outside"),
    ("soc,voltage_v\n1,25\n0.5,22\n0.2,24\n0,20\n",
     r"d.csv:4: row 3, column 'voltage_v': 24 V rises above the 22 V"),
    ("soc,voltage_v\n1,25\n0.5,22\n0.7,21\n0,20\n",
     r"d.csv:4: row 3, column 'soc': SOC 0.7 rises again"),
    ("soc,voltage_v\n1,25\n0.5,x\n0,20\n", r"d.csv:3: row 2, column 'voltage_v': not a number"),
    ("time_s,voltage_v,current_a\n0,25,2\n10,24,-1\n20,23,2\n",
     r"d.csv:3: row 2, column 'current_a': -1 A is negative"),
    ("time_s,voltage_v,current_a\n0,25,2\n10,24,2\n10,23,2\n",
     r"d.csv:4: row 3, column 'time_s'"),
    ("time_s,voltage_v,current_a\n0,25,2\n10,24,2\n20,23,NaN\n",
     r"d.csv:4: row 3, column 'current_a': 'NaN' is not a finite number"),
    ("soc,voltage_v\n1,25\n0,20\n", r"d.csv: 2 data row\(s\); need at least 3"),
    # probes swapped: this was "-24.9 V rises above the -25 V already reached"
    ("soc,voltage_v\n1,-25\n0.5,-24.9\n0,-20\n",
     r"d.csv:2: row 1, column 'voltage_v': must be > 0, got -25 V"),
    ("time_s,voltage_v,current_a\n0,25,2\n10,0,2\n20,23,2\n",
     r"d.csv:3: row 2, column 'voltage_v': must be > 0, got 0 V"),
    # the step fit squared 1e30 and wrote its levels as decimals: a traceback
    ("soc,voltage_v\n1,1e30\n0.5,9e29\n0,8e29\n",
     r"d.csv:2: row 1, column 'voltage_v': 1e\+30 V is not a plausible battery voltage"),
    # the charge drawn overflowed: numpy's warnings, then a fit of nonsense
    ("time_s,voltage_v,current_a\n0,25,1e300\n1e300,24,1e300\n2e300,23,1e300\n",
     r"d.csv:4: row 3, column 'current_a': the charge drawn over the log is beyond"),
]


@pytest.mark.parametrize(("text", "message"), BAD_DISCHARGE,
                         ids=[m[:40] for _, m in BAD_DISCHARGE])
def test_bad_discharge(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "d.csv"
    path.write_text(text)
    with pytest.raises(PhmDataError, match=message) as info:
        read_discharge(path)
    assert "\n" not in str(info.value)


def test_coulomb_soc_below_zero_with_given_capacity(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "d.csv", "time_s,voltage_v,current_a",
                     [(0, 25, 2), (1800, 22, 4), (2700, 20, 4)])
    with pytest.raises(PhmDataError, match=r"d.csv:4: row 3, column 'current_a': "
                                           r"Coulomb-counted SOC -1 is outside \[0, 1\]"):
        read_discharge(path, capacity_ah=1.0)


def test_small_voltage_noise_is_accepted(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "d.csv", "soc,voltage_v",
                     [(1, 25), (0.75, 23), (0.5, 23.02), (0.25, 21), (0, 20)])
    assert len(read_discharge(path).soc) == 5


def test_utf8_bom_before_the_header_is_accepted(tmp_path: Path) -> None:
    # Spreadsheet programs save "CSV UTF-8" with a byte-order mark before the header.
    path = tmp_path / "c.csv"
    path.write_bytes(b"\xef\xbb\xbfcycle,capacity_ah\n0,11\n1,10.9\n2,10.8\n")
    log = read_cycles(path)
    assert log.cycle.tolist() == [0, 1, 2] and log.table.lines == (2, 3, 4)


@pytest.mark.parametrize(("data", "where"), [
    (b"cycle,capacity_ah\n0,11\n1,10\xff9\n2,10.8\n", "c.csv:3:5:"),
    (b"\xef\xbb\xbfcycle,capacity_ah\n0,11\n\xe9,10.8\n", "c.csv:3:1:"),
    (b"cycle,capacity_\xe9h\n0,11\n", "c.csv:1:16:"),
    (b"# r\xc3\xa9sum\xc3\xa9 \xff\n", "c.csv:1:10:"),  # columns count characters, not bytes
], ids=["mid-line", "after-a-bom", "header", "after-multibyte"])
def test_non_utf8_byte_is_located(tmp_path: Path, data: bytes, where: str) -> None:
    path = tmp_path / "c.csv"
    path.write_bytes(data)
    with pytest.raises(PhmDataError) as info:
        read_cycles(path)
    message = str(info.value)
    assert message.startswith(f"{path}:{where.partition(':')[2]}")
    assert "UTF-8" in message and "\n" not in message


BAD_ROWS = [
    ("cycle,capacity_ah\n0,11\n1,10.9,7\n2,10.8\n",
     "c.csv:3:8: row 2 has 3 cells, the header has 2 (cycle,capacity_ah)"),
    ("cycle,capacity_ah\n0,11\n1,10.9,\n2,10.8\n",
     "c.csv:3:8: row 2 has 3 cells, the header has 2"),
    ("cycle,capacity_ah,temp_c\n0,11,25\n1,10.9\n2,10.8,25\n",
     "c.csv:3:7: row 2 has 2 cells, the header has 3 (cycle,capacity_ah,temp_c)"),
    ('cycle,capacity_ah\n0,11\n1,"10,9",7\n2,10.8\n',
     "c.csv:3:10: row 2 has 3 cells"),
    ("# note\ncycle,capacity_ah\n\n0,11\n# more\n1,10.9\n2,10.8,1\n",
     "c.csv:7:8: row 3 has 3 cells"),
    ("cycle,capacity_ah,cycle\n0,11,0\n1,10.9,1\n2,10.8,2\n",
     "c.csv:1:19: header: column 'cycle' appears twice"),
]


@pytest.mark.parametrize(("text", "message"), BAD_ROWS, ids=[m[:30] for _, m in BAD_ROWS])
def test_row_cell_count_must_match_the_header(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "c.csv"
    path.write_text(text)
    with pytest.raises(PhmDataError) as info:
        read_cycles(path)
    assert str(info.value).startswith(f"{tmp_path}/{message}")
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("capacity", [0.0, -2.0, float("nan"), float("inf")])
def test_discharge_capacity_must_be_positive(tmp_path: Path, capacity: float) -> None:
    path = write_csv(tmp_path / "d.csv", "time_s,voltage_v,current_a",
                     [(0, 25, 2), (1800, 22, 4), (2700, 20, 4)])
    with pytest.raises(PhmDataError, match="capacity_ah must be a positive number"):
        read_discharge(path, capacity_ah=capacity)
