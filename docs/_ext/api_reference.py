"""``.. api-packages::`` and ``.. api-modules::``: the Python API from docstrings.

``api-packages`` lists veribattery's public packages and modules (those without a
leading underscore) with the first line of each one's docstring, and the names of
``veribattery.__all__`` with a link to where each is documented. ``api-reference``
documents one module: its docstring, then every name of its ``__all__`` through
autodoc, in that order.
"""

from __future__ import annotations

import importlib
import inspect
import pkgutil
from types import ModuleType

from docutils import nodes
from docutils.statemachine import StringList
from sphinx.application import Sphinx
from sphinx.util.docutils import SphinxDirective
from sphinx.util.nodes import nested_parse_with_titles

ROOT = "veribattery"
#: Documented elsewhere on the site: the click objects (see the CLI reference).
SKIPPED = frozenset({"veribattery.cli"})


def public_modules() -> list[ModuleType]:
    """veribattery's direct sub-packages and modules without a leading underscore."""
    root = importlib.import_module(ROOT)
    found = []
    for info in pkgutil.iter_modules(root.__path__, ROOT + "."):
        if not info.name.rsplit(".", 1)[1].startswith("_"):
            found.append(importlib.import_module(info.name))
    return sorted(found, key=lambda m: m.__name__)


def documented_modules() -> list[ModuleType]:
    """The public modules whose ``__all__`` the API page documents."""
    return [m for m in public_modules() if hasattr(m, "__all__") and m.__name__ not in SKIPPED]


def summary(obj: object) -> str:
    """The first paragraph of *obj*'s docstring, on one line."""
    doc = (inspect.getdoc(obj) or "").strip()
    return " ".join(doc.split("\n\n", 1)[0].split())


def home(name: str, modules: list[ModuleType]) -> str | None:
    """The documented module that exports the root's *name* as the same object."""
    obj = getattr(importlib.import_module(ROOT), name)
    owner = getattr(obj, "__module__", "") or ""
    candidates = [m for m in modules if name in m.__all__ and getattr(m, name, None) is obj]
    best = [m for m in candidates if owner.startswith(m.__name__)]
    chosen = (best or candidates or [None])[0]
    return None if chosen is None else chosen.__name__


def _directive(obj: object) -> str:
    if inspect.isclass(obj):
        return "autoexception" if issubclass(obj, BaseException) else "autoclass"
    if inspect.isfunction(obj) or inspect.isbuiltin(obj):
        return "autofunction"
    return "autodata"


def module_text(module: ModuleType) -> list[str]:
    """reST documenting *module*: its docstring, then each name of ``__all__``."""
    lines = [f".. automodule:: {module.__name__}", "   :no-members:", ""]
    for name in module.__all__:
        obj = getattr(module, name)
        directive = _directive(obj)
        lines += [f".. {directive}:: {module.__name__}.{name}", *_options(directive), ""]
    return lines


def packages_text() -> list[str]:
    """A table of the public modules, and the root's names: a link to each one's home
    module, or its documentation here when no documented module exports it."""
    modules = documented_modules()
    documented = {m.__name__ for m in modules}
    lines = [".. list-table::", "   :header-rows: 1", "   :widths: 25 75", "",
             "   * - module", "     - what it is"]
    for module in public_modules():
        name = module.__name__
        shown = f":py:mod:`{name}`" if name in documented else f"``{name}``"
        lines += [f"   * - {shown}", f"     - {summary(module)}"]
    root = importlib.import_module(ROOT)
    lines += ["", f"``{ROOT}`` itself exports these names (``{ROOT}.__all__``):", ""]
    own = []
    for name in root.__all__:
        where = home(name, modules)
        if where is None:
            own.append(name)
        target = f"{where}.{name}" if where else f"{ROOT}.{name}"
        lines.append(f"- :py:obj:`{name} <{target}>`: {summary(getattr(root, name))}")
    lines += ["", f".. py:module:: {ROOT}", ""]
    if own:
        lines += ["The names whose module has no ``__all__`` of its own are documented here:", ""]
    for name in own:
        obj = getattr(root, name)
        directive = _directive(obj)
        lines += [f".. {directive}:: {ROOT}.{name}", *_options(directive), ""]
    return [*lines, ""]


def _options(directive: str) -> list[str]:
    if directive in ("autoclass", "autoexception"):
        return ["   :members:"]
    return ["   :no-value:"] if directive == "autodata" else []


class _Generated(SphinxDirective):
    def _parse(self, text: list[str], source: str) -> list[nodes.Node]:
        container = nodes.section()
        nested_parse_with_titles(self.state, StringList(text, source=source), container)
        return list(container.children)


class ApiPackages(_Generated):
    """The table of public modules and the root package's names."""

    def run(self) -> list[nodes.Node]:
        return self._parse(packages_text(), ROOT)


class ApiModules(_Generated):
    """A section per documented module: its docstring and its ``__all__``."""

    def run(self) -> list[nodes.Node]:
        text: list[str] = []
        for module in documented_modules():
            title = f"``{module.__name__}``"
            text += [title, "-" * len(title), "", *module_text(module)]
        return self._parse(text, ROOT)


def setup(app: Sphinx) -> dict[str, object]:
    app.add_directive("api-packages", ApiPackages)
    app.add_directive("api-modules", ApiModules)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
