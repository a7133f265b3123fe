"""Durable sweep results: rows appended as points finish, resumable, one sweep per file.

``.csv`` and ``.jsonl`` files are appended to directly: each point's rows go out in one
``write`` followed by ``flush`` and ``fsync``, so a crash, Ctrl-C or a killed worker
leaves whole points only (a torn last line, which only a power cut can leave, is cut
off when the file is reopened). Parquet cannot be appended to, so a ``.parquet``
sweep journals its rows to ``RESULTS.partial.jsonl`` and writes the Parquet file
(atomically) when the sweep ends. When a sweep ends the file is rewritten, atomically,
in grid order. The sweep's fingerprint is kept beside the results in
``RESULTS.sweep.json``.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import IO

from veribattery._files import can_create_in, staged, write_text
from veribattery.errors import ConfigError
from veribattery.sweep.fingerprint import SweepFingerprint

__all__ = ["FORMATS", "ResultsStore", "Row", "check_target", "open_results"]

#: One row: column → value.
Row = dict[str, object]

FORMATS = (".csv", ".jsonl", ".parquet")

_INT_COLUMNS = frozenset({"point", "states", "transitions"})
_FLOAT_COLUMNS = frozenset({"seconds", "recharge_cap_probability"})


class ResultsStore:
    """An open RESULTS file: :meth:`append` one point's rows, :meth:`finish` in grid order."""

    def __init__(self, path: Path, columns: Sequence[str], journal: Path, stream: IO[str]):
        self.path = path
        self.columns = tuple(columns)
        self._journal = journal
        self._stream = stream

    def append(self, rows: Sequence[Row]) -> None:
        """Write one point's rows durably, all of them or (after a crash) none."""
        self._stream.write(_text(self._journal, self.columns, rows))
        self._stream.flush()
        os.fsync(self._stream.fileno())

    def finish(self, rows: Iterable[Row]) -> None:
        """Replace the file by *rows* (every point's, in grid order), atomically."""
        self._stream.close()
        _replace(self.path, self.columns, list(rows))
        if self._journal != self.path:
            self._journal.unlink(missing_ok=True)

    def close(self) -> None:
        """Close without rewriting (an interrupted sweep: the rows so far stay)."""
        self._stream.close()


def open_results(
    path: Path, columns: Sequence[str], mark: SweepFingerprint, *, force: bool
) -> tuple[ResultsStore, list[Row]]:
    """Open (or create) *path* for the sweep *mark*; return it and the rows already there.

    :raises ConfigError: on an unsupported suffix, a file of another sweep (unless
        *force*), or a file that is not a sweep's results (unless *force*).
    :raises OSError: when the file cannot be written.
    """
    suffix = _suffix(path)
    journal = path.with_name(path.name + ".partial.jsonl") if suffix == ".parquet" else path
    meta = path.with_name(path.name + ".sweep.json")
    exists = path.exists() or journal.exists()
    rows = [] if force or not exists else _resume(path, journal, meta, mark, columns)
    _check_writable(path)
    if not rows:
        _write_new(meta, mark)
        stream = _create(journal, columns)
    else:
        stream = _reopen(journal, columns)
    return ResultsStore(path, columns, journal, stream), rows


def check_target(path: Path) -> None:
    """Check the suffix and that *path* could be written, before any work is done.

    :raises ConfigError: on an unsupported suffix or an unwritable place.
    """
    _suffix(path)
    _check_writable(path)


def _suffix(path: Path) -> str:
    suffix = path.suffix.lower()
    if suffix not in FORMATS:
        raise ConfigError(f"-o {str(path)!r}: unsupported results type; use "
                          + ", ".join(FORMATS))
    return suffix


def _check_writable(path: Path) -> None:
    folder = path.parent
    if not folder.is_dir():
        raise ConfigError(f"-o {str(path)!r}: folder {str(folder)!r} does not exist")
    target = path if path.exists() else folder
    if (not os.access(target, os.W_OK) or not can_create_in(folder)  # the journal, meta
            or (path.exists() and not path.is_file())):
        raise ConfigError(f"-o {str(path)!r}: cannot write there (read-only or permission denied)")


def _resume(
    path: Path, journal: Path, meta: Path, mark: SweepFingerprint, columns: Sequence[str]
) -> list[Row]:
    """The rows of an earlier run of this same sweep, or a one-line refusal."""
    try:
        theirs = SweepFingerprint.from_json(meta.read_text(encoding="utf-8"))
    except (OSError, ValueError, KeyError, TypeError):
        raise ConfigError(
            f"-o {str(path)!r} exists and is not the results of a veribattery sweep "
            f"(no readable {meta.name}); use --force to replace it, or pick another -o"
        ) from None
    difference = mark.difference(theirs)
    if difference is not None:
        raise ConfigError(f"-o {str(path)!r} holds another sweep's results: {difference}; "
                          "use --force to start afresh, or pick another -o")
    rows = _read_parquet(path) if journal != path and path.exists() else []
    return rows + _read_rows(journal, columns) if journal.exists() else rows


def _write_new(meta: Path, mark: SweepFingerprint) -> None:
    write_text(meta, mark.as_json())


def _create(journal: Path, columns: Sequence[str]) -> IO[str]:
    stream = journal.open("w", encoding="utf-8", newline="")
    if journal.suffix == ".csv":
        stream.write(_csv_line(columns))
        stream.flush()
    return stream


def _reopen(journal: Path, columns: Sequence[str]) -> IO[str]:
    """Append to *journal*, first cutting off a torn last line (a crash mid-write)."""
    if not journal.exists():
        return _create(journal, columns)
    data = journal.read_bytes()
    keep = data.rfind(b"\n") + 1
    if keep != len(data):
        with journal.open("r+b") as raw:
            raw.truncate(keep)
    return journal.open("a", encoding="utf-8", newline="")


def _text(journal: Path, columns: Sequence[str], rows: Sequence[Row]) -> str:
    if journal.suffix == ".csv":
        return "".join(_csv_line([_csv_cell(row.get(c)) for c in columns]) for row in rows)
    return "".join(json.dumps({c: row.get(c) for c in columns}) + "\n" for row in rows)


def _csv_line(cells: Sequence[object]) -> str:
    buffer = io.StringIO()
    csv.writer(buffer, lineterminator="\n").writerow(cells)
    return buffer.getvalue()


def _csv_cell(value: object) -> object:
    """CSV text that reads back to the same value (floats by repr, None as empty)."""
    if value is None:
        return ""
    return repr(value) if isinstance(value, float) else value


def _read_rows(journal: Path, columns: Sequence[str]) -> list[Row]:
    """The rows of *journal*; a line that is not one this sweep wrote is a one-line
    refusal naming it (a row edited by hand, a byte that is not UTF-8, a torn cell)."""
    try:
        text = journal.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise _not_ours(journal, _text_line(exc), "not UTF-8 text") from None
    lines = text[: text.rfind("\n") + 1]
    if journal.suffix != ".csv":
        return [_json_row(journal, number, line, columns)
                for number, line in enumerate(lines.splitlines(), 1) if line.strip()]
    reader = csv.DictReader(io.StringIO(lines))
    if reader.fieldnames is not None and tuple(reader.fieldnames) != tuple(columns):
        raise ConfigError(f"-o {str(journal)!r}: its columns are not this sweep's; use --force")
    rows = []
    for row in reader:
        try:
            if None in row or None in row.values():  # cells beyond the header, or missing
                cells = sum(v is not None for k, v in row.items() if k is not None)
                raise ValueError(f"{cells + len(row.get(None) or ())} cells, the header has "
                                 f"{len(columns)}")
            rows.append({c: _parse_cell(c, row[c]) for c in columns})
        except ValueError as exc:
            raise _not_ours(journal, reader.line_num, str(exc)) from None
    return rows


def _json_row(journal: Path, number: int, line: str, columns: Sequence[str]) -> Row:
    try:
        row = json.loads(line)
    except ValueError as exc:
        raise _not_ours(journal, number, f"not JSON ({exc.args[0]})") from None
    if not isinstance(row, dict) or set(row) != set(columns) or type(row["point"]) is not int:
        raise _not_ours(journal, number, "not an object with this sweep's columns")
    return row


def _not_ours(journal: Path, line: int, why: str) -> ConfigError:
    return ConfigError(f"-o {str(journal)!r}: line {line} is not a row this sweep wrote "
                       f"({why}); use --force to start afresh, or pick another -o")


def _text_line(exc: UnicodeDecodeError) -> int:
    """The line (from 1) of the byte *exc* failed on."""
    return bytes(exc.object[: exc.start]).count(b"\n") + 1


def _parse_cell(column: str, text: str) -> object:
    """The value of a CSV cell written by :func:`_csv_cell`."""
    if text == "":
        return None
    if column in _INT_COLUMNS:
        return int(text)
    if column in _FLOAT_COLUMNS:
        return float(text)
    if text in ("True", "False"):  # a boolean property's value, or holds
        return text == "True"
    if column == "value":
        return float(text)
    return None if column == "holds" else text


def _read_parquet(path: Path) -> list[Row]:
    import pandas as pd

    try:
        frame = pd.read_parquet(path)
    except (OSError, ValueError) as exc:  # pyarrow's ArrowInvalid is a ValueError
        raise ConfigError(f"-o {str(path)!r}: cannot read it as Parquet ({exc}); use --force "
                          "to start afresh, or pick another -o") from None
    rows: list[Row] = frame.astype(object).where(frame.notna(), None).to_dict("records")
    return rows


def _replace(path: Path, columns: Sequence[str], rows: list[Row]) -> None:
    with staged(path, suffix=path.suffix) as temporary:
        if path.suffix.lower() == ".parquet":
            _write_parquet(temporary, columns, rows)
            return
        with open(temporary, "w", encoding="utf-8", newline="") as stream:
            if path.suffix.lower() == ".csv":
                stream.write(_csv_line(columns))
            stream.write(_text(path, columns, rows))
            stream.flush()
            os.fsync(stream.fileno())


def _write_parquet(path: Path, columns: Sequence[str], rows: list[Row]) -> None:
    import pandas as pd

    frame = pd.DataFrame(rows, columns=list(columns))
    # Parquet columns have one type: boolean property values are stored as 1.0 / 0.0.
    frame["value"] = [_as_float(v) for v in frame["value"]]
    frame.to_parquet(path, index=False)


def _as_float(value: object) -> float:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return math.nan
    return float(value)  # type: ignore[arg-type]
