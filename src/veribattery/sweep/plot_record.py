"""Which figures a sweep drew, kept in its ``RESULTS.sweep.json``, so that a rerun
which resumes the sweep draws them again, and overwrites nothing else.

Each figure is noted with the SHA-256 of its bytes as drawn: a file the user has
replaced or edited since (same name, other bytes) is theirs now, and is overwritten
only with ``--force``. Older records noted bare paths, without a digest; such a figure
cannot be told unchanged, so it too needs ``--force`` (or to be moved away).
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

from veribattery._files import write_text
from veribattery.errors import ConfigError
from veribattery.sweep.store import fingerprint_file

__all__ = ["check_redraw", "drawn_plots", "file_digest", "record_plot"]


def drawn_plots(path: Path) -> dict[Path, str | None]:
    """The figures (``sweep --plot``; resolved paths) that the sweep whose results are
    *path* has drawn, each with the SHA-256 of the file as drawn, as :func:`record_plot`
    noted them in ``RESULTS.sweep.json``. Empty when there is no such file.

    A figure is noted relative to the record's folder, so a folder of results and
    figures moved elsewhere still resumes and redraws (older records, with absolute
    paths, are read as they are). Records of older versions noted no digest (None):
    whether such a figure changed since cannot be told."""
    meta = fingerprint_file(path)
    try:
        plots = json.loads(meta.read_text(encoding="utf-8")).get("plots", [])
    except (OSError, ValueError, AttributeError):  # (not a JSON object: no plots)
        return {}
    folder = meta.parent.resolve()
    drawn: dict[Path, str | None] = {}
    for entry in plots if isinstance(plots, list) else ():
        noted, digest = _plot_entry(entry)
        if noted is not None:
            drawn[(folder / noted).resolve()] = digest
    return drawn


def check_redraw(path: Path, plot: Path) -> bool:
    """Whether a rerun of the sweep whose results are *path* may draw the existing figure
    *plot* again: True when the sweep drew it and it is unchanged since, False when the
    sweep did not draw it (an existing file is then the user's).

    :raises ConfigError: when the sweep drew it but it has changed since (another file
        put in its place, or edited), or was noted by an older version without a digest
        (so that a change cannot be ruled out); naming ``--plot`` and ``-o``.
    """
    drawn = drawn_plots(path)
    resolved = plot.resolve()
    if resolved not in drawn:
        return False
    noted = drawn[resolved]
    if noted is not None and noted == file_digest(plot):
        return True
    what = ("changed since this sweep drew it" if noted is not None else
            "drawn by an older version, which kept no digest to tell it unchanged")
    raise ConfigError(f"--plot {plot}: {what}; use --force to overwrite it (and start "
                      f"{path} afresh), or move it away")


def record_plot(path: Path, plot: Path) -> None:
    """Note in ``RESULTS.sweep.json`` (*path* the results) that the sweep drew *plot*,
    relative to that file's folder, with the SHA-256 of its bytes (see
    :func:`drawn_plots`): a rerun redraws it only while it is unchanged.

    A sweep started afresh (a new RESULTS, or ``--force``) forgets the figures noted.
    """
    meta = fingerprint_file(path)
    data = json.loads(meta.read_text(encoding="utf-8"))
    try:
        noted = os.path.relpath(plot.resolve(), meta.parent.resolve())
    except ValueError:  # (Windows: on another drive, so only an absolute path names it)
        noted = str(plot.resolve())
    noted = Path(noted).as_posix()
    kept = [entry for entry in data.get("plots", []) if _plot_entry(entry)[0] != noted]
    entries = [*kept, {"path": noted, "sha256": file_digest(plot)}]
    data["plots"] = sorted(entries, key=lambda entry: str(_plot_entry(entry)[0]))
    write_text(meta, json.dumps(data, indent=2) + "\n")


def file_digest(path: Path) -> str:
    """The SHA-256 of the file *path*, in hex."""
    digest = hashlib.sha256()
    with path.open("rb") as stream:
        for block in iter(lambda: stream.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _plot_entry(entry: object) -> tuple[str | None, str | None]:
    """A noted figure's path and digest: ``{"path": ..., "sha256": ...}``, or a bare path
    as older versions noted it (no digest); (None, None) for anything else."""
    if isinstance(entry, str):
        return entry, None
    if isinstance(entry, dict) and isinstance(entry.get("path"), str):
        digest = entry.get("sha256")
        return entry["path"], digest if isinstance(digest, str) else None
    return None, None
