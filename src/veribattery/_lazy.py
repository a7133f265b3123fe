"""Names of a package served on first read (a module ``__getattr__``, PEP 562).

Packages re-export what their modules define; the ones whose modules are costly to
import (the DTMC checker for an MDP run, the exact engine, pandas and matplotlib for a
model's emission) import each only when one of its names is first read.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping, Sequence
from types import MappingProxyType
from typing import Any

__all__ = ["lazy_exports"]


def lazy_exports(package: str, exports: Mapping[str, Sequence[str]]) -> Callable[[str], Any]:
    """The ``__getattr__`` of *package* that imports each of *exports*' names (module →
    names) from its module when first read, and refuses any other name as Python does.

    The table is read-only: the checker keeps no mutable module state
    (``tests/checker/test_workspace.py``).
    """
    home = MappingProxyType({name: module for module, names in exports.items()
                             for name in names})

    def __getattr__(name: str) -> Any:
        if name not in home:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        return getattr(importlib.import_module(home[name]), name)

    return __getattr__
