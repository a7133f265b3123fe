"""The public API is explicit, and config depends on nothing of veribattery but errors
and the shared base modules it reads text and numbers with."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import veribattery.config
import veribattery.render

SRC = Path(veribattery.config.__file__).resolve().parents[1]


@pytest.mark.parametrize("module", [veribattery.config, veribattery.render], ids=str)
def test_all_names_exist(module: object) -> None:
    names = module.__all__  # type: ignore[attr-defined]
    assert names == sorted(names)
    assert all(hasattr(module, name) for name in names)


def test_config_imports_only_errors() -> None:
    paths = sorted((SRC / "config").glob("*.py"))
    assert len(paths) > 1, f"no config modules under {SRC / 'config'}: nothing was checked"
    for path in paths:
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("veribattery"):
                assert node.module in ("veribattery.errors", "veribattery._text",
                                       "veribattery._numbers") or (
                    node.module.startswith("veribattery.config")
                ), f"{path.name} imports {node.module}"
