"""Durable sweep results: rows appended as points finish, resumable, one sweep per file.

``.csv`` and ``.jsonl`` files are appended to directly: each point's rows go out in one
``write`` followed by ``flush`` and ``fsync``, so a crash, Ctrl-C or a killed worker
leaves whole points only (a torn last line, which only a power cut, a full disk or a
copy cut short can leave, is cut off when the file is reopened; the sweep checks such
a point again). Parquet cannot be appended to, so a ``.parquet``
sweep journals its rows to ``RESULTS.partial.jsonl`` and writes the Parquet file
(atomically) when the sweep ends. When a sweep ends the file is rewritten, atomically,
in grid order. The sweep's fingerprint is kept beside the results in
``RESULTS.sweep.json``, with the figures (``sweep --plot``) the sweep has drawn
(:mod:`~veribattery.sweep.plot_record`). That file is an output too: it is never
written over a file of the user's without ``--force``.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path
from typing import IO

from veribattery._files import can_create_in, staged, write_text
from veribattery.errors import ConfigError
from veribattery.sweep.fingerprint import SweepFingerprint

__all__ = ["FORMATS", "ResultsFileError", "ResultsStore", "Row", "RowCheck", "check_target",
           "csv_text", "fingerprint_file", "open_results", "read_results"]

#: One row: column → value.
Row = dict[str, object]

#: Why a well-formed row is still not one of this sweep's (its point is not in the grid,
#: its property is not the point's), or None when it is.
RowCheck = Callable[[Row], str | None]

FORMATS = (".csv", ".jsonl", ".parquet")

_INT_COLUMNS = frozenset({"point", "states", "transitions"})
_FLOAT_COLUMNS = frozenset({"seconds", "recharge_cap_probability"})
_TEXT_COLUMNS = frozenset({"property", "requirement", "error"})
_OTHER_COLUMNS = "its columns are not those of the sweep its fingerprint describes"
#: Booleans as CSV cells: ``true``/``false``, and ``True``/``False`` as sweeps wrote them
#: before (a results file of theirs still resumes).
_BOOLEANS = {"true": True, "false": False, "True": True, "False": False}


class ResultsFileError(ConfigError):
    """A results file holds what its sweep did not write: *problem* says where (``line
    12 is not a row this sweep wrote (...)``); each reader words it for its option."""

    def __init__(self, file: Path, problem: str) -> None:
        super().__init__(f"{file}: {problem}")
        self.file = file
        self.problem = problem


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
    path: Path, columns: Sequence[str], mark: SweepFingerprint, *, force: bool,
    check: RowCheck | None = None,
) -> tuple[ResultsStore, list[Row]]:
    """Open (or create) *path* for the sweep *mark*; return it and the rows already there.

    :param check: what else makes a row foreign to this sweep (see :data:`RowCheck`).
    :raises ConfigError: on an unsupported suffix, a file of another sweep (unless
        *force*), or a file that is not a sweep's results (unless *force*), naming the
        first line that is not a row this sweep wrote.
    :raises OSError: when the file cannot be written.
    """
    _suffix(path)
    journal = _journal(path)
    meta = fingerprint_file(path)
    exists = _resumable(path)
    try:
        rows = [] if force or not exists else _resume(path, journal, meta, mark, columns, check)
    except ResultsFileError as exc:
        raise ConfigError(f"-o {exc.file}: {exc.problem}; use --force to start afresh, "
                          "or pick another -o") from None
    _check_writable(path)
    if force or not exists:  # (resumed, it holds this sweep's fingerprint and plots)
        _write_new(meta, mark)
    stream = _reopen(journal, columns) if rows else _create(journal, columns)
    return ResultsStore(path, columns, journal, stream), rows


def read_results(path: Path, columns: Sequence[str],
                 check: RowCheck | None = None) -> list[Row]:
    """The rows of the results file *path*, read as a resumed sweep reads them: every
    line must be a row the sweep wrote (``report --sweep`` draws only such rows).

    :param columns: the sweep's columns, in order.
    :param check: what else makes a row foreign to the sweep (see :data:`RowCheck`).
    :raises ResultsFileError: naming the first line that is not such a row (or the
        columns, or a Parquet file that cannot be read).
    :raises OSError: when the file cannot be read.
    """
    if _suffix(path) == ".parquet":
        return _read_parquet(path, columns, check)
    return _read_rows(path, columns, check)


def check_target(path: Path, *, force: bool = False) -> None:
    """Check *path* as the results of a sweep, before any work is done: a results file
    whose folder exists and may be written, and a fingerprint file beside it that
    is not in the way.

    :param force: the sweep may start afresh, replacing what is there.
    :raises ConfigError: on a folder, an unsupported suffix, an unwritable place, or a
        ``RESULTS.sweep.json`` that is a folder or (unless *force*) that exists without
        results it fingerprints.
    """
    _refuse_folder(path)  # (before its suffix: a folder is no file of any type)
    _suffix(path)
    _check_writable(path)
    _check_meta(path, force=force)


def _suffix(path: Path) -> str:
    suffix = path.suffix.lower()
    if suffix not in FORMATS:
        kind = f"unsupported results type '{path.suffix}'" if path.suffix else "no file type"
        raise ConfigError(f"-o {path}: {kind}; name a file ending in {_choices(FORMATS)}")
    return suffix


def _choices(suffixes: Sequence[str]) -> str:
    return ", ".join(suffixes[:-1]) + " or " + suffixes[-1]


def _check_writable(path: Path) -> None:
    folder = path.parent
    if not folder.is_dir():
        raise ConfigError(f"-o {path}: folder {folder} does not exist; create it first")
    _refuse_folder(path)
    target = path if path.exists() else folder
    if (not os.access(target, os.W_OK) or not can_create_in(folder)  # the journal, meta
            or (path.exists() and not path.is_file())):
        raise ConfigError(f"-o {path}: cannot write there (read-only or permission denied)")


def _refuse_folder(path: Path) -> None:
    if path.is_dir():
        raise ConfigError(f"-o {path}: is a folder; name a results file "
                          f"({_choices(FORMATS)}) in it")


def _check_meta(path: Path, *, force: bool) -> None:
    """The fingerprint file is an output too: never a folder, and overwritten without
    *force* only by resuming the results it fingerprints (a file of the user's that
    happens to have its name, or one whose results were deleted, is refused)."""
    meta = fingerprint_file(path)
    if meta.is_dir():
        raise ConfigError(f"-o {path}: {meta}, where the sweep keeps its fingerprint, is a "
                          "folder; move it away, or choose another name")
    if meta.exists() and not force and not _resumable(path):
        raise ConfigError(f"-o {path}: {meta} already exists (and {path} does not); use "
                          "--force to overwrite it, or choose another name")


def _resumable(path: Path) -> bool:
    """Whether the results *path* (or, for Parquet, its journal) exist to be resumed."""
    return path.exists() or _journal(path).exists()


def _journal(path: Path) -> Path:
    """Where rows go as points finish: *path* itself, or a journal beside a Parquet file."""
    if path.suffix.lower() == ".parquet":
        return path.with_name(path.name + ".partial.jsonl")
    return path


def _resume(
    path: Path, journal: Path, meta: Path, mark: SweepFingerprint, columns: Sequence[str],
    check: RowCheck | None,
) -> list[Row]:
    """The rows of an earlier run of this same sweep, or a one-line refusal."""
    try:
        theirs = SweepFingerprint.from_json(meta.read_text(encoding="utf-8"))
    except (OSError, ValueError, KeyError, TypeError):
        raise ConfigError(
            f"-o {path} exists and is not the results of a veribattery sweep "
            f"(no readable {meta.name}); use --force to replace it, or pick another -o"
        ) from None
    difference = mark.difference(theirs)
    if difference is not None:
        raise ConfigError(f"-o {path} holds another sweep's results: {difference}; "
                          "use --force to start afresh, or pick another -o")
    rows = _read_parquet(path, columns, check) if journal != path and path.exists() else []
    return rows + _read_rows(journal, columns, check) if journal.exists() else rows


def fingerprint_file(path: Path) -> Path:
    """Where the results *path* keep their sweep's fingerprint (and, as
    :mod:`~veribattery.sweep.plot_record` notes them, the figures drawn):
    ``RESULTS.sweep.json``."""
    return path.with_name(path.name + ".sweep.json")


def _write_new(meta: Path, mark: SweepFingerprint) -> None:
    write_text(meta, mark.as_json())


def _create(journal: Path, columns: Sequence[str]) -> IO[str]:
    stream = journal.open("w", encoding="utf-8", newline="")
    if _is_csv(journal):
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
    if _is_csv(journal):
        return "".join(_csv_line([_csv_cell(row.get(c)) for c in columns]) for row in rows)
    return "".join(json.dumps({c: row.get(c) for c in columns}) + "\n" for row in rows)


def _is_csv(path: Path) -> bool:
    """CSV (else JSON lines): by the suffix, in any case, as :func:`_suffix` reads it."""
    return path.suffix.lower() == ".csv"


def _csv_line(cells: Sequence[object]) -> str:
    buffer = io.StringIO()
    csv.writer(buffer, lineterminator="\n").writerow(cells)
    return buffer.getvalue()


def csv_text(columns: Sequence[str], rows: Iterable[Row]) -> str:
    """*rows* as CSV under a header of *columns*, as a CSV results file holds them: floats
    by repr, booleans ``true``/``false`` (as in JSON), None as an empty cell."""
    return _csv_line(columns) + "".join(_csv_line([_csv_cell(row.get(c)) for c in columns])
                                        for row in rows)


def _csv_cell(value: object) -> object:
    """CSV text that reads back to the same value (floats by repr, None as empty)."""
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    return repr(value) if isinstance(value, float) else value


def _read_rows(journal: Path, columns: Sequence[str], check: RowCheck | None) -> list[Row]:
    """The rows of *journal*; a line that is not one this sweep wrote is a one-line
    refusal naming it (a row edited by hand, a byte that is not UTF-8, a torn cell)."""
    try:
        text = journal.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise _not_ours(journal, _text_line(exc), "not UTF-8 text") from None
    lines = text[: text.rfind("\n") + 1]
    numbered = (_csv_rows(journal, lines, columns) if _is_csv(journal) else
                ((number, _json_row(journal, number, line, columns))
                 for number, line in enumerate(lines.splitlines(), 1) if line.strip()))
    return [_checked(journal, f"line {number}", row, check) for number, row in numbered]


def _csv_rows(journal: Path, lines: str, columns: Sequence[str]) -> Iterator[tuple[int, Row]]:
    """Each CSV row parsed, with its line; a cell that does not parse is a refusal."""
    reader = csv.DictReader(io.StringIO(lines))
    try:
        if reader.fieldnames is not None and tuple(reader.fieldnames) != tuple(columns):
            raise ResultsFileError(journal, _OTHER_COLUMNS)
        for row in reader:
            yield reader.line_num, _csv_row(journal, reader.line_num, row, columns)
    except csv.Error as exc:  # a NUL byte, a cell over csv's field size limit
        raise _not_ours(journal, reader.line_num, f"not CSV: {exc}") from None


def _csv_row(journal: Path, line: int, row: dict[str | None, object],
             columns: Sequence[str]) -> Row:
    try:
        if None in row or None in row.values():  # cells beyond the header, or missing
            cells = sum(v is not None for k, v in row.items() if k is not None)
            extra = row.get(None)
            raise ValueError(f"{cells + len(extra) if isinstance(extra, list) else cells} "
                             f"cells, the header has {len(columns)}")
        return {c: _parse_cell(c, str(row[c])) for c in columns}
    except ValueError as exc:
        raise _not_ours(journal, line, str(exc)) from None


def _checked(file: Path, where: str, row: Row, check: RowCheck | None) -> Row:
    why = check(row) if check is not None else None
    if why is not None:
        raise ResultsFileError(file, f"{where} is not a row this sweep wrote ({why})")
    return row


def _json_row(journal: Path, number: int, line: str, columns: Sequence[str]) -> Row:
    try:
        row = json.loads(line)
    except ValueError as exc:
        raise _not_ours(journal, number, f"not JSON ({exc.args[0]})") from None
    if not isinstance(row, dict) or set(row) != set(columns) or type(row["point"]) is not int:
        raise _not_ours(journal, number, "not an object with this sweep's columns")
    wrong = next((c for c in columns if not _json_cell_fits(c, row[c])), None)
    if wrong is not None:
        raise _not_ours(journal, number, f"{wrong} {json.dumps(row[wrong])[:40]} is not a "
                        f"value this sweep writes there")
    return row


def _json_cell_fits(column: str, value: object) -> bool:
    """Whether *value* has a type the sweep writes in *column* (axis cells: any)."""
    if value is None:
        return True
    if column in _INT_COLUMNS:
        return type(value) is int
    if column in _FLOAT_COLUMNS:
        return type(value) in (int, float)
    if column == "value":
        return type(value) in (int, float, bool)
    if column == "holds":
        return type(value) is bool
    return column not in _TEXT_COLUMNS or type(value) is str


def _not_ours(journal: Path, line: int, why: str) -> ResultsFileError:
    return ResultsFileError(journal, f"line {line} is not a row this sweep wrote ({why})")


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
    if text in _BOOLEANS:  # a boolean property's value, or holds
        return _BOOLEANS[text]
    if column == "value":
        return float(text)
    if column == "holds":
        raise ValueError(f"holds is {text!r}, not true, false or empty")
    return text


def _read_parquet(path: Path, columns: Sequence[str], check: RowCheck | None) -> list[Row]:
    import pandas as pd

    try:
        frame = pd.read_parquet(path)
    except (OSError, ValueError) as exc:  # pyarrow's ArrowInvalid is a ValueError
        raise ResultsFileError(path, f"cannot read it as Parquet ({exc})") from None
    if list(frame.columns) != list(columns):
        raise ResultsFileError(path, _OTHER_COLUMNS)
    rows: list[Row] = frame.astype(object).where(frame.notna(), None).to_dict("records")
    return [_checked(path, f"row {number}", row, check) for number, row in enumerate(rows, 1)]


def _replace(path: Path, columns: Sequence[str], rows: list[Row]) -> None:
    with staged(path, suffix=path.suffix) as temporary:
        if path.suffix.lower() == ".parquet":
            _write_parquet(temporary, columns, rows)
            return
        with open(temporary, "w", encoding="utf-8", newline="") as stream:
            if _is_csv(path):
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
