"""Write CSV tables all at once: a failed run leaves no partial file and the old one intact."""

from __future__ import annotations

import csv
import os
import tempfile
from collections.abc import Iterable, Sequence
from pathlib import Path

__all__ = ["write_csv"]


def write_csv(path: Path, header: Sequence[str], rows: Iterable[Sequence[object]]) -> None:
    """Write *header* and *rows* to *path* through a temporary file renamed into place."""
    directory = path.parent if str(path.parent) else Path(".")
    handle, name = tempfile.mkstemp(dir=directory, prefix=".veribattery-", suffix=".tmp")
    try:
        with os.fdopen(handle, "w", encoding="utf-8", newline="") as stream:
            writer = csv.writer(stream)
            writer.writerow(header)
            writer.writerows(rows)
        os.replace(name, path)
    except BaseException:
        Path(name).unlink(missing_ok=True)
        raise
