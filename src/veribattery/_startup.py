"""Process start-up: defer numpy submodules that scipy drags in but we never use.

``import scipy.sparse`` (scipy >= 1.14) builds an array-API view of numpy with
``from numpy import *``, and numpy 2 lists ``f2py``, ``testing`` and ``ma`` in its
``__all__``, so every process that checks a model imports numpy's Fortran wrapper
generator and its test framework (which pull unittest, email, charset_normalizer ...):
about a tenth of a second and 10 MB before any work is done. (``numpy.ma`` is not
deferred: ``numpy.unique`` uses it.) The CLI installs
:func:`defer_unused_numpy_modules` first; those modules then load on first attribute
access (:class:`importlib.util.LazyLoader`), which for a model check is never.
"""

from __future__ import annotations

import importlib.abc
import importlib.machinery
import importlib.util
import sys
from collections.abc import Sequence
from types import ModuleType

__all__ = ["DEFERRED_MODULES", "defer_unused_numpy_modules"]

#: Imported by scipy's array-API layer, never used by veribattery's engine.
DEFERRED_MODULES = frozenset({"numpy.f2py", "numpy.testing"})


class _DeferringFinder(importlib.abc.MetaPathFinder):
    """Finds the deferred modules as usual, but hands them out unexecuted (lazy)."""

    def find_spec(
        self, fullname: str, path: Sequence[str] | None, target: ModuleType | None = None
    ) -> importlib.machinery.ModuleSpec | None:
        if fullname not in DEFERRED_MODULES:
            return None
        spec = importlib.machinery.PathFinder.find_spec(fullname, path)
        if spec is not None and spec.loader is not None:
            spec.loader = importlib.util.LazyLoader(spec.loader)
        return spec


def defer_unused_numpy_modules() -> None:
    """Make :data:`DEFERRED_MODULES` load lazily (idempotent; no effect once imported)."""
    if not any(isinstance(finder, _DeferringFinder) for finder in sys.meta_path):
        sys.meta_path.insert(0, _DeferringFinder())
