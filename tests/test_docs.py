"""The documentation: the site builds without a warning, and the README stays short and
links only to files that exist.

Sphinx and myst-parser come with the ``dev`` extra, which ``make test`` installs, so
a missing generator fails these tests instead of skipping them.
"""

from __future__ import annotations

import ast
import fractions
import importlib.util
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
#: The README is an introduction; everything else lives in docs/.
README_MAX_LINES = 250
#: ``[text](target)`` and ``![alt](target)``, the target up to a space or ``)``.
LINK = re.compile(r"!?\[[^\]]*\]\(\s*([^)\s]+)(?:\s+\"[^\"]*\")?\s*\)")
#: The build takes about 10 s; the limit only stops a hung build (a busy machine is slower).
BUILD_TIMEOUT_S = 180


def test_docs_build_without_warnings(tmp_path: Path) -> None:
    """`make docs`'s build, into a temporary folder, with warnings as errors."""
    for module in ("sphinx", "myst_parser"):
        assert importlib.util.find_spec(module) is not None, (
            f"{module} is missing: install the dev extra (pip install -e '.[dev]')")
    proc = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html",
         "-d", str(tmp_path / "doctrees"), str(ROOT / "docs"), str(tmp_path / "html")],
        capture_output=True, text=True, timeout=BUILD_TIMEOUT_S, check=False,
    )
    assert proc.returncode == 0, proc.stderr[-4000:]
    assert proc.stderr.strip() == "", proc.stderr[-4000:]
    html = tmp_path / "html"
    # The references are generated from the code: the commands' help, the config
    # schema with configs/example.yaml's comments, the docstrings.
    generated = {
        "cli.html": (r"Usage: veribattery check \[OPTIONS\] CONFIG", r"veribattery phm fade"),
        "config.html": (r"farm\.cols", r"BS1: act only if"),
        "api.html": (r'id="veribattery(\.\w+)*\.check_mission"',
                     r'id="veribattery(\.\w+)*\.MissionConfig"'),
    }
    for page, patterns in generated.items():
        text = (html / page).read_text(encoding="utf-8")
        for pattern in patterns:
            assert re.search(pattern, text), f"{page} lacks {pattern!r}"


def test_readme_is_short() -> None:
    lines = README.read_text(encoding="utf-8").splitlines()
    assert len(lines) <= README_MAX_LINES, (
        f"README.md has {len(lines)} lines (at most {README_MAX_LINES}): "
        "move the detail into docs/")


def _relative_links(text: str) -> list[str]:
    targets = (m.group(1) for m in LINK.finditer(text))
    return [t for t in targets if not re.match(r"[a-z][a-z0-9+.-]*:|#", t)]


def test_readme_links_point_to_files() -> None:
    links = _relative_links(README.read_text(encoding="utf-8"))
    assert links, "no relative link found: the pattern no longer matches the README"
    missing = [t for t in links if not (ROOT / t.split("#", 1)[0]).exists()]
    assert missing == [], f"README.md links to files that do not exist: {missing}"


@pytest.mark.parametrize(("text", "expected"), [
    ("see [a](docs/a.md) and ![b](docs/b.png)", ["docs/a.md", "docs/b.png"]),
    ("[x](https://example.org) [y](#anchor) [z](docs/z.md#part)", ["docs/z.md#part"]),
    ('[t](docs/t.md "title")', ["docs/t.md"]),
], ids=["plain-and-image", "external-anchor-fragment", "title"])
def test_link_pattern(text: str, expected: list[str]) -> None:
    assert _relative_links(text) == expected


def test_the_layout_page_names_every_package() -> None:
    # docs/layout.md is written by hand: a new package must be added to it.
    root = Path(__file__).resolve().parents[1]
    page = (root / "docs" / "layout.md").read_text(encoding="utf-8")
    src = root / "src" / "veribattery"
    packages = sorted(str(p.parent.relative_to(src)) + "/" for p in src.rglob("__init__.py")
                      if p.parent != src)
    assert packages and [p for p in packages if f"`{p}`" not in page] == []


#: A ``.. code-block:: python`` of an .rst page, or a fenced python block of a .md page.
CODE_BLOCK = re.compile(r"\.\. code-block:: python\n\n((?:   [^\n]*\n|\n)+)|```python\n(.*?)```",
                        re.S)


@pytest.mark.parametrize("page", ["docs/api.rst", "README.md"])
def test_the_python_examples_run_as_written_and_give_what_they_say(
        page: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """Each block runs from the repository's root, statement by statement as in a
    notebook; an expression whose comment is a value (``# 0.1666…``, ``# Fraction(1,
    6)``, ``# Strategy(states=272)``) gives that value, or a repr of that text."""
    monkeypatch.chdir(ROOT)
    blocks = CODE_BLOCK.finditer((ROOT / page).read_text(encoding="utf-8"))
    compared = _run(page, [textwrap.dedent(m.group(1) or m.group(2)) for m in blocks], {})
    assert compared > 0 or page == "README.md"


#: A reST literal block of a docstring: the indented lines after a paragraph ending in ``::``.
LITERAL_BLOCK = re.compile(r"::\n\n((?:    [^\n]*\n|\n)+)")


def test_the_package_docstring_examples_run_as_written(monkeypatch: pytest.MonkeyPatch) -> None:
    """``help(veribattery)`` is the first page a notebook user reads: its pipeline ran on
    a ``die.pm`` that does not exist. Its names are the package's exports."""
    import veribattery

    monkeypatch.chdir(ROOT)
    namespace: dict[str, object] = {"Path": Path}
    namespace.update({name: getattr(veribattery, name) for name in veribattery.__all__})
    blocks = [textwrap.dedent(m.group(1))
              for m in LITERAL_BLOCK.finditer(veribattery.__doc__ or "")]
    assert len(blocks) == 2 and _run("veribattery.__doc__", blocks, namespace) == 2


def _run(page: str, blocks: list[str], namespace: dict[str, object]) -> int:
    """Run *blocks* statement by statement; the number of values compared."""
    compared = 0
    for code in blocks:
        lines = code.splitlines()
        for node in ast.parse(code).body:
            said = _said(lines[(node.end_lineno or node.lineno) - 1])
            if isinstance(node, ast.Expr) and said is not None:
                value = eval(compile(ast.Expression(node.value), page, "eval"), namespace)
                _assert_says(value, said)
                compared += 1
            else:
                exec(compile(ast.Module([node], []), page, "exec"), namespace)
    return compared


def _said(line: str) -> str | None:
    """The comment of *line* if it is a Python expression (a value), else None."""
    comment = line.partition("  # ")[2].strip()
    try:
        ast.parse(comment, mode="eval")
    except SyntaxError:
        return None
    return comment or None


def _assert_says(value: object, said: str) -> None:
    try:
        expected = eval(said, {"Fraction": fractions.Fraction})
    except NameError:  # a repr such as Strategy(states=272)
        assert repr(value) == said
        return
    assert value == pytest.approx(expected, rel=1e-6)
