"""The compiled templates' cache: the same text from cached code, and a cache that cannot
be read or written costs a compile, never an error."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path

import jinja2
import pytest

import veribattery.render.render as render_module
from veribattery.config import load_config
from veribattery.render import render_model, render_properties

_CONFIG = "farm: {cols: 2, rows: 2, base: [0, 0]}\nbattery: {resolution_ah: 0.5}\n"


@pytest.fixture
def cache_at(monkeypatch: pytest.MonkeyPatch) -> Iterator[Callable[[Path], None]]:
    """Point the render environment's bytecode cache at a directory of the test's."""

    def use(directory: Path) -> None:
        monkeypatch.setattr(render_module, "_bytecode_cache",
                            lambda: render_module._BestEffortBytecodeCache(str(directory)))
        render_module._environment.cache_clear()

    yield use
    render_module._environment.cache_clear()  # the next test's environment: its own


def _texts() -> tuple[str, str]:
    config = load_config(_CONFIG)
    return render_model(config), render_properties(config)


def _compiles(monkeypatch: pytest.MonkeyPatch) -> list[str | None]:
    """Record the names of the templates Jinja compiles from source from now on."""
    compiled: list[str | None] = []
    compile_source = jinja2.Environment.compile

    def recording(self: jinja2.Environment, source: str, name: str | None = None,
                  *args: object, **kwargs: object) -> object:
        compiled.append(name)
        return compile_source(self, source, name, *args, **kwargs)  # type: ignore[call-overload]

    monkeypatch.setattr(jinja2.Environment, "compile", recording)
    return compiled


def test_a_second_process_renders_the_same_text_from_the_cache(
    tmp_path: Path, cache_at: Callable[[Path], None], monkeypatch: pytest.MonkeyPatch
) -> None:
    cache_at(tmp_path)
    compiled = _compiles(monkeypatch)
    first = _texts()
    assert compiled  # the case is real: the templates were compiled ...
    assert list(tmp_path.iterdir())  # ... and their code stored
    compiled.clear()
    render_module._environment.cache_clear()  # as a new process: a new environment
    assert _texts() == first
    assert compiled == []  # read from the cache, not compiled


def test_a_damaged_cache_entry_is_compiled_again(
    tmp_path: Path, cache_at: Callable[[Path], None], monkeypatch: pytest.MonkeyPatch
) -> None:
    cache_at(tmp_path)
    _texts()
    for entry in tmp_path.iterdir():  # the right header, then garbage
        bucket_bytes = entry.read_bytes()
        entry.write_bytes(bucket_bytes[:len(jinja2.bccache.bc_magic)] + b"not a checksum")
    compiled = _compiles(monkeypatch)
    render_module._environment.cache_clear()
    config = load_config(_CONFIG)
    assert render_model(config).startswith("//")  # rendered all the same
    assert compiled != []


def test_a_cache_that_cannot_be_written_renders_all_the_same(
    tmp_path: Path, cache_at: Callable[[Path], None]
) -> None:
    expected = _texts()  # the usual environment
    not_a_folder = tmp_path / "file"
    not_a_folder.write_text("")
    cache_at(not_a_folder)  # every read and write fails
    assert _texts() == expected
