"""Reward structures looked up as PRISM's ``R{key}`` names them: by name, by index, or
the first when the operator names none. One rule for every model kind and engine."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol, TypeVar


class Named(Protocol):
    @property
    def name(self) -> str | None: ...


N = TypeVar("N", bound=Named)


def by_key(structures: Sequence[N], key: str | int | None) -> N:
    """The structure named *key*, at index *key*, or the first (None).

    :raises KeyError: no structure has that name.
    :raises IndexError: no structure at that index (or none at all).
    """
    if key is None or isinstance(key, int):
        return structures[key or 0]
    for structure in structures:
        if structure.name == key:
            return structure
    raise KeyError(key)
