"""Process start-up: defer what libraries import but a model check does not read.

The CLI calls :func:`start_process` first. It collects the youngest generation of
garbage less often for the whole process (:mod:`veribattery._collector`), turns off
pydantic's plugin lookup (a scan of every installed distribution's entry points, ~0.1 s,
when the first model is built: the CLI has no use for plugins; setting
``PYDANTIC_DISABLE_PLUGINS`` to anything else turns it back on) and installs two kinds of deferral
(:func:`defer_unused_numpy_modules`):

- **Modules nobody reads** (:data:`DEFERRED_MODULES`). ``import scipy.sparse``
  (scipy >= 1.14) builds an array-API view of numpy with ``from numpy import *``, and
  numpy 2 lists ``f2py``, ``testing``, ``ma``, ``polynomial`` ... in its ``__all__``, so
  every process that checks a model would import numpy's Fortran wrapper generator, its
  test framework (unittest, email ...), masked arrays and polynomials. Those modules
  are handed out unexecuted and load on first attribute access
  (:class:`importlib.util.LazyLoader`): for a model check, never, or (``numpy.ma``,
  read by ``numpy.unique``) when first used. The same holds for ``numpy.fft`` (and
  scipy's array-API wrapper of it), for ``pydoc`` (imported by scipy's docstring
  parser, read only when a docstring is parsed) and for the two modules that attach
  docstrings to numpy's compiled functions and scalar types (about a twentieth of
  a small check's start-up; under ``python -OO`` numpy leaves them out too).
- **Packages whose ``__init__`` imports far more than is read**
  (:data:`LAZY_PACKAGES`). ``scipy.sparse.csgraph`` (graph traversal, SCCs) imports
  ``scipy.sparse.linalg`` for one name, and that package imports every sparse solver,
  ARPACK, LOBPCG, ``expm`` and all of ``scipy.linalg`` (~0.1 s). Such a package is set
  up without running its ``__init__`` (its ``__path__`` is there, so submodules such
  as SuperLU's import as usual); the names listed for it are served from the module
  that defines them (the very objects the package re-exports); reading any other name
  runs the ``__init__`` then, once, and the package is the ordinary one from there on.
  The direct solvers (``splu``, ``spsolve`` ...) are served too: most checks, DTMC
  and MDP, solve with SuperLU only, and the Krylov solvers' package runs when a
  large system first reads ``gmres`` or ``bicgstab``.
"""

from __future__ import annotations

import gc
import importlib
import importlib.machinery
import importlib.util
import os
import sys
import threading
from collections.abc import Callable, Mapping, Sequence
from types import ModuleType
from typing import Any, cast

from veribattery._collector import YOUNG_COLLECTION_EVERY

__all__ = ["DEFERRED_MODULES", "LAZY_PACKAGES", "defer_unused_numpy_modules", "start_process"]

#: Imported by scipy's array-API layer (``from numpy import *``), by numpy itself (its
#: docstrings) or by scipy's docstring parser (``pydoc``), never read by the engine's
#: start-up. (``numpy.random`` is not here: scipy reads it at import.)
DEFERRED_MODULES = frozenset({
    "numpy.f2py", "numpy.testing", "numpy.ma", "numpy.polynomial", "numpy.ctypeslib",
    "numpy.char", "numpy.rec", "numpy.fft", "scipy._lib.array_api_compat.numpy.fft",
    "numpy._core._add_newdocs", "numpy._core._add_newdocs_scalars", "pydoc",
})

#: Package -> {name: module defining it}: the names served without the package's
#: ``__init__``.
LAZY_PACKAGES: Mapping[str, Mapping[str, str]] = {
    # Read by scipy.sparse.csgraph's __init__ (for `laplacian`); the direct solvers
    # (SuperLU, triangular substitution) are what a check reads from it.
    "scipy.sparse.linalg": {
        "LinearOperator": "scipy.sparse.linalg._interface",
        **dict.fromkeys(("splu", "spilu", "spsolve", "spsolve_triangular", "SuperLU"),
                        "scipy.sparse.linalg._dsolve"),
    },
    # Read by scipy.sparse.linalg._dsolve (SuperLU's wrapper): numpy's exception.
    "scipy.linalg": {"LinAlgError": "numpy.linalg"},
}


class _DeferringFinder:
    """Finds the deferred modules and lazy packages as usual, with a deferring loader.

    (A meta path finder needs only ``find_spec``; ``importlib.abc`` is not imported
    for its base class, which pulls in ``importlib.resources``, ``tempfile`` ...)
    """

    def find_spec(
        self, fullname: str, path: Sequence[str] | None, target: ModuleType | None = None
    ) -> importlib.machinery.ModuleSpec | None:
        if fullname not in DEFERRED_MODULES and fullname not in LAZY_PACKAGES:
            return None
        spec = importlib.machinery.PathFinder.find_spec(fullname, path)
        if spec is None or spec.loader is None:
            return spec
        if fullname in DEFERRED_MODULES:
            spec.loader = importlib.util.LazyLoader(spec.loader)
        elif spec.submodule_search_locations is not None:
            spec.loader = cast(Any, _PackageLoader(spec.loader, LAZY_PACKAGES[fullname]))
        return spec


class _PackageLoader:
    """Loads a package without running its ``__init__`` until a name it defines is read."""

    def __init__(self, loader: Any, served: Mapping[str, str]) -> None:
        self.loader = loader
        self.served = served

    def __getattr__(self, name: str) -> Any:
        return getattr(self.loader, name)  # resource readers and the like: the real loader's

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType | None:
        created: ModuleType | None = self.loader.create_module(spec)
        return created

    def exec_module(self, module: ModuleType) -> None:
        module.__getattr__ = _deferred_init(module, self.loader, self.served)  # type: ignore[method-assign]


def _deferred_init(module: ModuleType, loader: Any,
                   served: Mapping[str, str]) -> Callable[[str], Any]:
    """The module ``__getattr__`` that serves *served* and otherwise runs the package."""
    lock = threading.RLock()  # re-entrant: the package's own __init__ reads itself
    running = False

    def __getattr__(name: str) -> Any:
        nonlocal running
        if name in served:
            try:
                return getattr(importlib.import_module(served[name]), name)
            except (ImportError, AttributeError):
                pass  # moved in another scipy: the package's own answer
        with lock:
            if running:  # read by the package's own __init__, not defined yet
                raise AttributeError(f"module {module.__name__!r} has no attribute {name!r}")
            if vars(module).get("__getattr__") is __getattr__:  # not run yet
                running = True
                try:
                    _run_package(module, loader, __getattr__)
                finally:
                    running = False
        return getattr(module, name)

    return __getattr__


def _run_package(module: ModuleType, loader: Any, deferred: Callable[[str], Any]) -> None:
    """Run the package's ``__init__`` in *module* and make it an ordinary package."""
    loader.exec_module(module)
    if vars(module).get("__getattr__") is deferred:  # the package defines no __getattr__
        del module.__getattr__
    module.__loader__ = loader
    if module.__spec__ is not None:
        module.__spec__.loader = loader




def start_process() -> None:
    """Prepare a CLI process (see the module): call before any import."""
    os.environ.setdefault("PYDANTIC_DISABLE_PLUGINS", "__all__")
    defer_unused_numpy_modules()
    _, *older = gc.get_threshold()
    gc.set_threshold(YOUNG_COLLECTION_EVERY, *older)


def defer_unused_numpy_modules() -> None:
    """Install the deferrals of :data:`DEFERRED_MODULES` and :data:`LAZY_PACKAGES`.

    Idempotent; a module already imported is not affected.
    """
    if not any(isinstance(finder, _DeferringFinder) for finder in sys.meta_path):
        sys.meta_path.insert(0, _DeferringFinder())
