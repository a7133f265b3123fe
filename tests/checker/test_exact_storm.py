"""``--exact`` against Storm's exact (rational) engine: equal fractions, not close floats.

Storm builds and checks each model with ``stormpy.Rational`` (GMP rationals);
its answer at the initial state must be *the same rational* as ours. Peer-suite
entries up to :data:`STATE_LIMIT` states run by default (a few seconds), and
two small mission models; the four paper cases (case1..4, ~176k states each,
about a minute apiece for both tools) run when ``VERIBATTERY_SLOW_TESTS=1``.
"""

from __future__ import annotations

import os
from fractions import Fraction
from pathlib import Path
from typing import Any

import pytest

stormpy = pytest.importorskip("stormpy")

from tests.conftest import PEER_TESTS, peer_harness  # noqa: E402
from tests.peer_manifests import assert_enough, fail_missing, manifest, missing  # noqa: E402
from veribattery.checker.exact import ExactCheckResult  # noqa: E402
from veribattery.config import load_config  # noqa: E402
from veribattery.mission import check_mission, is_conditional, mission_files  # noqa: E402
from veribattery.pipeline import check_prism_file  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
STATE_LIMIT = 600
SUITES = ("prism", "prism-examples")
#: Entries :func:`_peer_entries` selects from each suite (counted 2026-11-26): a floor.
SELECTED = {"prism": 143, "prism-examples": 28}
SLOW = os.environ.get("VERIBATTERY_SLOW_TESTS") == "1"


def storm_exact(model: Path, prop: str, constants: dict[str, str]) -> Fraction | bool | None:
    """Storm's exact value at the (single) initial state; None for infinity."""
    program = stormpy.parse_prism_program(str(model))
    props = stormpy.parse_properties(prop, program)
    if constants:
        definitions = ",".join(f"{k}={v}" for k, v in constants.items())
        program, props = stormpy.instantiate_constants(program, definitions, props)
    # A second formula keeps Storm from making the decided states absorbing.
    unused = stormpy.parse_properties('P=? [ F "deadlock" ]', program)
    options = stormpy.BuilderOptions([*props, *unused])
    built = stormpy.build_model[stormpy.Rational](program, options=options)
    result = stormpy.model_checking(built, props[0])
    (initial,) = built.initial_states
    if result.is_qualitative():
        return bool(result.get_truth_values_vector()[initial])
    text = str(result.get_value_vector()[initial]).strip().lower()
    return None if text in ("inf", "infinity") else Fraction(text)


def ours(result: ExactCheckResult) -> Fraction | bool | None:
    if isinstance(result.value, bool):
        return result.value
    return result.exact


def _peer_entries() -> list[Any]:
    params = []
    seen = set()
    for suite in SUITES:
        data = manifest(suite)
        if data is None:
            params.append(missing(suite, suite, None))
            continue
        for entry in data["entries"]:
            key = (entry["model"], entry["props"], entry["property_index"],
                   tuple(sorted(entry["constants"].items())))
            small = entry.get("states", STATE_LIMIT + 1) <= STATE_LIMIT
            if small and key not in seen and entry.get("initial_states", 1) == 1:
                seen.add(key)
                params.append(pytest.param(suite, entry, id=f"{suite}:{entry['id']}"))
    return params


PEER_ENTRIES = _peer_entries()


@pytest.mark.parametrize("suite", SUITES)
def test_enough_peer_entries_are_compared(suite: str) -> None:
    """The filter above (small, one initial state, distinct) keeps a real share of each suite."""
    count = sum(1 for p in PEER_ENTRIES if p.values[0] == suite and p.values[1] is not None)
    assert_enough(count, SELECTED[suite], f"{suite} entries of at most {STATE_LIMIT} states")


@pytest.mark.parametrize(("suite", "entry"), PEER_ENTRIES)
def test_peer_entry_equals_storm_exact(suite: str, entry: dict[str, Any] | None) -> None:
    if entry is None:
        fail_missing(suite)
    root = PEER_TESTS / suite
    props_file = root / entry["props"]
    run = check_prism_file(root / entry["model"], props_source=props_file,
                           selectors=[str(entry["property_index"])],
                           constants=entry["constants"], exact=True)
    (result,) = run.results
    assert isinstance(result, ExactCheckResult)
    harness = peer_harness()
    expected = harness.parse_value(entry["expected"])
    assert harness.values_match(expected, result.value, 1e-6, 1e-12)
    prop = _storm_property(props_file, entry)
    try:
        theirs = storm_exact(root / entry["model"], prop, entry["constants"])
    except RuntimeError as exc:  # a construct Storm's exact engine refuses
        pytest.skip(f"Storm (exact) cannot check this entry: {exc}")
    assert ours(result) == theirs


def _storm_property(props_file: Path, entry: dict[str, Any]) -> str:
    """The property with the properties file's constants in front (Storm's parser has no
    ``label`` definitions: entries using them are skipped)."""
    consts = [line for line in props_file.read_text().splitlines()
              if line.strip().startswith("const ")]
    return "\n".join([*consts, entry["property"]])


def _mission_case(config: Path | None, overrides: tuple[str, ...], tmp_path: Path) -> None:
    cfg = load_config(config, overrides) if config else load_config(REPO / "configs/example.yaml",
                                                                   overrides)
    report = check_mission(cfg, exact=True)
    files = mission_files(cfg)
    model = tmp_path / "model.prism"
    model.write_text(files.model)
    assert any(is_conditional(r.property.formula) for r in report.run.results)
    for result in report.run.results:  # the conditional defaults too: exact, equal to Storm's
        if is_conditional(result.property.formula) and result.value != result.value:
            # Success impossible: undefined (NaN), with a warning naming the condition.
            assert report.values["p_success"] == 0
            assert any("has probability 0" in w for w in report.warnings)
            continue
        assert isinstance(result, ExactCheckResult)
        assert ours(result) == storm_exact(model, result.property.text, {}), result.property.text


@pytest.mark.parametrize(
    "overrides",
    [
        ("farm.cols=3", "farm.rows=2", "farm.base=[0,0]", "battery.capacity_ah=6"),
        ("farm.cols=3", "farm.rows=3", "farm.base=[1,1]", "battery.model=basic_low",
         "environment.p_wsp_c=1/3", "battery.capacity_ah=8"),
    ],
    ids=["small-advanced", "small-basic-third"],
)
def test_small_mission_equals_storm_exact(overrides: tuple[str, ...], tmp_path: Path) -> None:
    _mission_case(None, overrides, tmp_path)


@pytest.mark.skipif(not SLOW, reason="paper cases take minutes: set VERIBATTERY_SLOW_TESTS=1")
@pytest.mark.parametrize("case", ["case1", "case2", "case3", "case4"])
def test_paper_case_equals_storm_exact(case: str, tmp_path: Path) -> None:
    _mission_case(REPO / "configs" / "paper" / f"{case}.yaml", (), tmp_path)
