"""The synthesis package's public names: each importable, loaded on first use."""

from __future__ import annotations

import subprocess
import sys

import pytest

import veribattery.synthesis as synthesis


def test_every_export_resolves() -> None:
    for name in synthesis.__all__:
        assert getattr(synthesis, name) is not None
    with pytest.raises(AttributeError, match="no attribute 'nothing'"):
        _ = synthesis.nothing


def test_emitting_needs_neither_pandas_nor_matplotlib() -> None:
    code = ("import sys, veribattery.synthesis; "
            "print(sorted(m for m in ('pandas', 'matplotlib') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "[]"
