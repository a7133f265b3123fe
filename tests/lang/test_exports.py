"""The public API of veribattery.lang is what __all__ says."""

from __future__ import annotations

import veribattery.lang as lang


def test_all_names_exist() -> None:
    for name in lang.__all__:
        assert hasattr(lang, name), name


def test_public_functions_are_exported() -> None:
    expected = {
        "parse_model",
        "parse_properties",
        "parse_property",
        "flatten_model",
        "undefined_constants",
        "parse_constant_assignments",
        "resolve_property",
        "select_properties",
    }
    assert expected <= set(lang.__all__)


def test_lang_does_not_import_numpy() -> None:
    import subprocess
    import sys

    code = "import sys, veribattery.lang; print('numpy' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
