"""Writing the user's files: all or nothing, never a partial file, modes from the umask.

Every file veribattery writes goes through :func:`staged`: the content is written to a
hidden temporary name beside the target and renamed onto it only when complete, so an
error or Ctrl-C leaves the user's old file (or no file) and no temporary behind. A new
file gets the mode ``open()`` would give it (0666 less the umask), not ``mkstemp``'s
0600; a replaced file keeps its mode.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator, Mapping
from contextlib import ExitStack, contextmanager
from pathlib import Path

__all__ = ["can_create_in", "new_file_mode", "staged", "write_text", "write_texts"]


def new_file_mode() -> int:
    """The mode ``open(path, "w")`` gives a new file: 0666 less the process umask."""
    umask = os.umask(0o022)
    os.umask(umask)
    return 0o666 & ~umask


def can_create_in(folder: Path) -> bool:
    """True when a file can be made in *folder*: tried (and removed at once), since
    ``os.access`` says yes to root everywhere (``/proc``) and cannot tell a full disk."""
    if not os.access(folder, os.W_OK | os.X_OK):
        return False
    try:
        with tempfile.TemporaryFile(dir=folder):
            return True
    except OSError:
        return False


@contextmanager
def staged(path: Path, *, suffix: str | None = None) -> Iterator[Path]:
    """A temporary path beside *path*, renamed onto *path* when the block succeeds.

    :param suffix: the temporary file's suffix (writers that choose a format by the
        suffix, such as matplotlib or pandas, need the target's); default ``.tmp``.
    """
    directory = path.parent if str(path.parent) else Path(".")
    try:
        handle, name = tempfile.mkstemp(dir=directory, prefix=f".{path.name}.",
                                        suffix=suffix or ".tmp")
    except OSError as exc:  # name the user's file, not the temporary one
        raise OSError(exc.errno, exc.strerror, str(path)) from None
    os.close(handle)
    temporary = Path(name)
    try:
        yield temporary
        mode = path.stat().st_mode & 0o7777 if path.exists() else new_file_mode()
        os.chmod(temporary, mode)
        os.replace(temporary, path)
    except OSError as exc:
        if exc.filename != name:
            raise
        # The user named *path*; the temporary name would only confuse them.
        raise OSError(exc.errno, exc.strerror, str(path)) from None
    finally:
        temporary.unlink(missing_ok=True)


def write_text(path: Path, text: str) -> None:
    """Replace *path* by *text* (UTF-8) atomically."""
    write_texts({path: text})


def write_texts(targets: Mapping[Path, str]) -> None:
    """Write several files all or nothing: every one is staged before any is renamed."""
    with ExitStack() as stack:
        for path, text in targets.items():
            temporary = stack.enter_context(staged(path))
            temporary.write_text(text, encoding="utf-8", newline="")
