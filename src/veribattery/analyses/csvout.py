"""Write CSV tables all at once: a failed run leaves no partial file and the old one intact."""

from __future__ import annotations

import csv
from collections.abc import Iterable, Sequence
from pathlib import Path

from veribattery._files import staged

__all__ = ["write_csv"]


def write_csv(path: Path, header: Sequence[str], rows: Iterable[Sequence[object]]) -> None:
    """Write *header* and *rows* to *path* through a temporary file renamed into place."""
    with staged(path) as temporary, open(temporary, "w", encoding="utf-8", newline="") as stream:
        writer = csv.writer(stream)
        writer.writerow(header)
        writer.writerows(rows)
