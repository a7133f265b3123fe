"""Reading the user's text files: UTF-8, one rule and one message for every file kind.

Configs, PRISM models and properties, and PHM logs all decode the same way: a UTF-8
byte-order mark (as Windows editors and spreadsheets' "CSV UTF-8" write it) is
dropped, newlines become ``\\n`` (as :meth:`pathlib.Path.read_text` gives them), and
the first byte that is not UTF-8 is reported at its line and column, counted in
characters as an editor counts them. And the one way messages count things
(:func:`count_of`: ``1 state``, ``1,234 states``).
"""

from __future__ import annotations

import codecs

from veribattery.errors import Span, VeribatteryError

__all__ = ["count_of", "decode_text"]


def decode_text(data: bytes, source: str, error: type[VeribatteryError]) -> str:
    """*data* as text.

    :param source: the file's name, for the error's place.
    :param error: the error class of the caller's kind of file.
    :raises error: at the first byte that is not UTF-8.
    """
    data = data.removeprefix(codecs.BOM_UTF8)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        before = _newlines(data[: exc.start].decode("utf-8"))
        where = Span(before.count("\n") + 1, len(before) - before.rfind("\n"), source)
        raise error(f"not UTF-8 text (byte 0x{data[exc.start]:02x}); save the file as UTF-8",
                    where) from None
    return _newlines(text)


def _newlines(text: str) -> str:
    return text.replace("\r\n", "\n").replace("\r", "\n")


def count_of(count: int, noun: str) -> str:
    """``1 state``, ``2 states``: *count* and *noun*, in the plural unless it is one."""
    return f"{count:,} {noun if count == 1 else noun + 's'}"
