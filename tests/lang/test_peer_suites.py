"""Every model and properties file of the PRISM peer suites parses, flattens and resolves."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from typing import Any

import pytest

from tests.lang.helpers import PEER, manifest_entries, peer_files
from tests.peer_manifests import assert_enough, fail_missing
from veribattery.lang import (
    flatten_model,
    parse_model,
    parse_properties,
    resolve_property,
    select_properties,
)

pytestmark = pytest.mark.skipif(not PEER.exists(), reason=f"peer suites not found at {PEER}")


@pytest.mark.parametrize(
    ("cases", "floor", "what"),
    [
        # Counted 2026-11-26 in the three DTMC suites: floors, not exact counts.
        (peer_files(".pm", ".prism"), 76, "model files"),
        (peer_files(".props", ".pctl"), 78, "properties files"),
        (manifest_entries(), 144 + 120, "prism and prism-examples manifest entries"),
    ],
    ids=["models", "properties", "entries"],
)
def test_the_corpus_is_all_there(cases: list[Any], floor: int, what: str) -> None:
    assert_enough(sum(c.values[-1] is not None for c in cases), floor, what)


@pytest.mark.parametrize("path", peer_files(".pm", ".prism"))
def test_model_file_parses(path: Path) -> None:
    model = parse_model(path)
    assert model.modules
    assert model.source == str(path)


@pytest.mark.parametrize("path", peer_files(".props", ".pctl"))
def test_properties_file_parses(path: Path) -> None:
    props = parse_properties(path)
    assert props.properties


def _split_statements() -> Any:
    spec = importlib.util.spec_from_file_location("prism_suite", PEER / "prism_suite.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.split_statements


@pytest.mark.parametrize("path", peer_files(".props", ".pctl"))
def test_property_count_matches_reference_splitter(path: Path) -> None:
    """Indices must match PRISM's -prop N, so the property count must agree."""
    statements = _split_statements()(path.read_text(encoding="utf-8"))
    expected = [s for s in statements if s["kind"] == "property"]
    props = parse_properties(path)
    assert len(props.properties) == len(expected)
    assert [p.name for p in props.properties] == [s["name"] for s in expected]


@pytest.mark.parametrize(("root", "entry"), manifest_entries())
def test_manifest_entry_flattens_and_resolves(root: Path, entry: dict[str, Any] | None) -> None:
    if entry is None:
        fail_missing(root.name)
    model = flatten_model(parse_model(root / entry["model"]), entry["constants"])
    props = parse_properties(root / entry["props"])
    (prop,) = select_properties(props, str(entry["property_index"]))
    assert prop.name == entry["property_name"]
    expected_text = entry["property"]
    if prop.name is not None:
        expected_text = expected_text.split(":", 1)[1].strip()
    assert prop.text == expected_text
    resolved = resolve_property(prop, model, props, entry["constants"])
    assert resolved.text == prop.text
    assert len(model.variables) > 0
