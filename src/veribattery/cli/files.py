"""Output options, checked before any work starts: one convention for every command.

Every file a command writes is named by an option; before the command computes
anything, each is checked here: its type is one the command can write, its folder
exists, it is not a folder itself, and it does not exist unless ``--force`` is given.
Writing itself goes through :mod:`veribattery._files` (atomic, modes from the umask).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import click

from veribattery._files import can_create_in
from veribattery.errors import OptionError

__all__ = [
    "CSV_SUFFIXES",
    "FIGURE_SUFFIXES",
    "OnceOption",
    "PathParam",
    "check_output_dir",
    "check_output_file",
    "typed_name",
]

#: File types matplotlib writes without outside programs (the format follows the
#: suffix; ``.pgf`` is left out: it needs a TeX installation).
FIGURE_SUFFIXES = (".png", ".pdf", ".svg", ".svgz", ".eps", ".ps", ".jpg", ".jpeg", ".tif",
                   ".tiff", ".webp")
CSV_SUFFIXES = (".csv",)


def check_output_file(path: Path | None, option: str, *, force: bool,
                      suffixes: Sequence[str] | None = None) -> None:
    """Refuse *path* (given as *option*) unless it can be written as asked.

    :param suffixes: the file types the option writes (None: any).
    :raises OptionError: naming the option, the path as typed, and what would be right.
    """
    if path is None:
        return
    where = f"{option} {path}"
    if suffixes is not None and path.suffix.lower() not in suffixes:
        kind = f"unsupported file type '{path.suffix}'" if path.suffix else "no file type"
        raise OptionError(f"{where}: {kind}; name a file ending in {_choices(suffixes)}")
    if path.is_dir():
        raise OptionError(f"{where}: is a folder; name a file in it")
    _check_folder(path.parent, where)
    if path.exists() and not force:
        raise OptionError(f"{where}: already exists; use --force to overwrite it, "
                          "or choose another name")


def check_output_dir(path: Path, option: str, *, force: bool,
                     names: Iterable[str] = ()) -> None:
    """Refuse the folder *path* unless the files *names* can be written into it.

    The folder itself may be new (it is created, with its parents, when writing).
    """
    where = f"{option} {path}"
    if str(path) == "-":  # the usual name of standard output, not a folder name
        raise OptionError(f"{where}: writes a folder of files, not to standard output; "
                          "name a folder")
    if path.exists() and not path.is_dir():
        raise OptionError(f"{where}: is a file, not a folder")
    existing = _nearest_existing(path)
    if not can_create_in(existing):
        raise OptionError(f"{where}: cannot write into {existing}")
    clashes = [name for name in names if (path / name).exists()]
    if clashes and not force:
        raise OptionError(f"{where}: {', '.join(clashes)} already exist(s) there; use --force "
                          "to overwrite, or choose another folder")


def _check_folder(folder: Path, where: str) -> None:
    folder = folder if str(folder) else Path(".")
    if not folder.is_dir():
        raise OptionError(f"{where}: folder {folder} does not exist; create it first")
    if not can_create_in(folder):
        raise OptionError(f"{where}: cannot write into folder {folder}")


def _nearest_existing(path: Path) -> Path:
    for candidate in (path, *path.parents):
        if candidate.exists():
            return candidate
    return Path(".")


def _choices(suffixes: Sequence[str]) -> str:
    if len(suffixes) == 1:
        return suffixes[0]
    return ", ".join(suffixes[:-1]) + " or " + suffixes[-1]


class PathParam(click.Path):
    """:class:`click.Path` that refuses an empty path: click reads ``""`` as ``.``, so
    ``-o "$OUT"`` with ``OUT`` unset would write into the current folder."""

    def convert(self, value: Any, param: click.Parameter | None,
                ctx: click.Context | None) -> Any:
        if isinstance(value, str) and not value.strip():
            self.fail("an empty path (is a shell variable unset?)", param, ctx)
        return super().convert(value, param, ctx)


class OnceOption(click.Option):
    """An option that takes one value, refusing two: click keeps the last of ``-o A -o B``,
    or of ``-o A --csv B`` (an old name beside the new), and the other file named would
    silently go unwritten. The same value given twice is taken, as one.

    Each name is its own entry in the parser, so that a refusal can name the option as
    typed, each time it was given.
    """

    def add_to_parser(self, parser: Any, ctx: click.Context) -> None:
        for name in self.opts:
            parser.add_option(obj=self, opts=[name], dest=self._dest(name), action="append",
                              nargs=self.nargs)

    def consume_value(self, ctx: click.Context, opts: Mapping[str, Any]) -> Any:
        given = [(name, value) for name in self.opts for value in opts.get(self._dest(name), ())]
        if len({value for _, value in given}) > 1:
            typed = " and ".join(f"{name} {value}" for name, value in given)
            raise click.UsageError(f"{typed}: {len(given)} values for one option"
                                   f"{_aliases([name for name, _ in given])}; give it once", ctx)
        if given:
            ctx.meta[_typed_key(str(self.name))] = given[0][0]
        return super().consume_value(ctx, {str(self.name): given[0][1]} if given else {})

    def _dest(self, name: str) -> str:
        return f"{self.name} {name}"  # (no parameter's name has a space)


def typed_name(parameter: str, default: str) -> str:
    """The name the user typed for the :class:`OnceOption` *parameter* (``--csv`` for
    ``-o``'s old name), so that a refusal names the option as typed; *default* if none."""
    ctx = click.get_current_context(silent=True)
    return default if ctx is None else str(ctx.meta.get(_typed_key(parameter), default))


def _typed_key(parameter: str) -> str:
    return f"veribattery.typed {parameter}"


def _aliases(names: Sequence[str]) -> str:
    """`` (--csv is another name of -o)`` when *names* spell one option differently."""
    first, *others = dict.fromkeys(names)
    if not others:
        return ""
    names = "is another name" if len(others) == 1 else "are other names"
    return f" ({', '.join(others)} {names} of {first})"
