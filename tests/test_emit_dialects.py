"""The emitted files, each read in the dialect it is for.

``properties.props`` holds only properties PRISM and Storm both read; those in Storm's
extensions of PRISM's property language (conditional ``||``, reward bounds
``F{"r"}<=T``, ``T=?``) go to ``storm-only.props``, which also repeats the properties
they refer to by name, so that Storm reads it alone. PRISM is not installed here: its
file is held to having none of Storm's constructs in our parser's AST, and both files
are read by Storm's own parser when stormpy imports.
"""

from __future__ import annotations

import os
import stat
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner

from veribattery.cli import cli
from veribattery.config import MissionConfig, load_config
from veribattery.config.schema import PAPER_PROPERTIES
from veribattery.errors import VeribatteryError
from veribattery.lang import parse_properties
from veribattery.lang.expressions import walk
from veribattery.lang.nodes import Conditional, ConditionalReach, RewardBounded, RewardOp
from veribattery.lang.property_rules import STEPS_REWARD
from veribattery.mission import (
    CONFIG_FILE,
    MODEL_FILE,
    PROPERTIES_FILE,
    STORM_ONLY_FILE,
    MissionFiles,
    mission_files,
    write_files,
)

SMALL = ("farm.cols=3", "farm.rows=3", "farm.base=[0,0]")
CONDITIONAL = ("exp_mission_time_given_success", "exp_recharges_given_success")

#: Properties beyond the paper's defaults: name -> (formula, whether only Storm reads it).
EXTRA: dict[str, tuple[str, bool]] = {
    "p_failure": ('P=? [ F "failure" ]', False),
    "p_done_within": ('P=? [ F{"mt"}<=600 "done" ]', True),
    "exp_steps": ('T=? [ F "done" ]', True),
    "few_recharges": ('P>=0.5 [ F{"rc"}<=2 "success" ]', True),
    # Refers to a Storm-only property by name: PRISM could not resolve it either.
    "p_few_recharges": ('P=? [ F "few_recharges" ]', True),
    "likely_done": ('P>=0.1 [ F "done" ]', False),
    # Refers to a property both read: storm-only.props must repeat that one.
    "exp_time_given_likely": ('R{"mt"}=? [ F "done" || F "likely_done" ]', True),
}


def _storm_constructs(formula: object) -> Iterator[str]:
    """Storm's extensions of PRISM's property grammar in *formula* (PRISM rejects each)."""
    for node in walk(formula):
        if isinstance(node, Conditional | ConditionalReach):
            yield "conditional ||"
        elif isinstance(node, RewardBounded):
            yield "reward bound"
        elif isinstance(node, RewardOp) and node.reward == STEPS_REWARD:
            yield "T=?"


def _config(extra: bool) -> MissionConfig:
    if not extra:
        return load_config("", SMALL)
    formulas = {**PAPER_PROPERTIES, **{name: formula for name, (formula, _) in EXTRA.items()}}
    return load_config("", [*SMALL, *(f"properties.{n}={f}" for n, f in formulas.items())])


def _names(text: str) -> list[str | None]:
    return [p.name for p in parse_properties(text).properties]


@pytest.mark.parametrize("extra", [False, True], ids=["paper", "extended"])
def test_properties_file_has_no_storm_construct(extra: bool) -> None:
    files = mission_files(_config(extra))
    props = parse_properties(files.properties, name=PROPERTIES_FILE).properties
    for prop in props:
        assert list(_storm_constructs(prop.formula)) == [], prop.text
    expected = ["p_success", "exp_mission_time", "exp_recharges"]
    if extra:
        expected += [name for name, (_, storm) in EXTRA.items() if not storm]
    assert [p.name for p in props] == expected


def test_storm_only_file_holds_the_rest_and_what_they_refer_to() -> None:
    files = mission_files(_config(True))
    storm = {p.name: p for p in parse_properties(files.storm_only).properties}
    assert list(storm) == [*CONDITIONAL, *(
        name for name, (_, only) in EXTRA.items() if only or name == "likely_done")]
    for name in [*CONDITIONAL, "p_done_within", "exp_steps", "few_recharges",
                 "exp_time_given_likely"]:
        assert list(_storm_constructs(storm[name].formula)), name
    assert set(_names(files.properties)) | set(storm) == set(_config(True).properties)


def test_paper_properties_split_as_the_issue_asks() -> None:
    files = mission_files(_config(False))
    assert _names(files.storm_only) == list(CONDITIONAL)
    assert "||" not in files.properties
    assert files.storm_only.startswith("// Storm only")
    assert dict(files.as_mapping()).keys() == {
        MODEL_FILE, PROPERTIES_FILE, STORM_ONLY_FILE, CONFIG_FILE}


def test_without_storm_properties_the_file_says_so() -> None:
    cfg = load_config("", [*SMALL, 'properties={p: \'P=? [ F "done" ]\'}'])
    files = mission_files(cfg)
    assert _names(files.properties) == ["p"]
    assert _names(files.storm_only) == []
    assert "None of this config's properties" in files.storm_only


# ---------------------------------------------------------------- Storm's own parser


@pytest.fixture(scope="module")
def stormpy() -> Any:
    try:
        import stormpy
    except ImportError:
        pytest.skip("stormpy is not installed: Storm's parser cannot read the emitted files")
    return stormpy


@pytest.mark.parametrize("extra", [False, True], ids=["paper", "extended"])
def test_storm_reads_each_file_with_the_model(stormpy: Any, tmp_path: Path, extra: bool) -> None:
    files = mission_files(_config(extra))
    written = dict(zip(files.as_mapping(), write_files(files, tmp_path), strict=True))
    program = stormpy.parse_prism_program(str(written[MODEL_FILE]))
    names: dict[str, list[str]] = {}
    for which in (PROPERTIES_FILE, STORM_ONLY_FILE):
        parsed = stormpy.parse_properties(str(written[which]), program)
        names[which] = [p.get_name() for p in parsed]
        assert names[which] == _names(written[which].read_text(encoding="utf-8"))
    assert names[PROPERTIES_FILE] and names[STORM_ONLY_FILE]
    assert set(names[PROPERTIES_FILE]) | set(names[STORM_ONLY_FILE]) == set(
        _config(extra).properties)


# ---------------------------------------------------------------- writing


def test_written_files_take_their_mode_from_the_umask(tmp_path: Path) -> None:
    old = os.umask(0o027)
    try:
        written = write_files(mission_files(_config(False)), tmp_path / "out")
    finally:
        os.umask(old)
    assert [p.name for p in written] == [MODEL_FILE, PROPERTIES_FILE, STORM_ONLY_FILE,
                                         CONFIG_FILE]
    for path in written:
        assert stat.S_IMODE(path.stat().st_mode) == 0o640, path
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == sorted(
        p.name for p in written)


def test_an_existing_storm_only_file_stops_the_whole_write(tmp_path: Path) -> None:
    (tmp_path / STORM_ONLY_FILE).write_text("// mine\n")
    with pytest.raises(VeribatteryError, match="already exist"):
        write_files(mission_files(_config(False)), tmp_path)
    assert [p.name for p in tmp_path.iterdir()] == [STORM_ONLY_FILE]
    assert (tmp_path / STORM_ONLY_FILE).read_text() == "// mine\n"


def test_a_failed_write_leaves_no_directory_behind(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def full_disk(_targets: object) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr("veribattery.mission.files.write_texts", full_disk)
    with pytest.raises(OSError, match="No space left"):
        write_files(mission_files(_config(False)), tmp_path / "new" / "out")
    assert list(tmp_path.iterdir()) == []


def test_cli_emit_writes_and_names_the_four_files(tmp_path: Path) -> None:
    out = tmp_path / "out"
    baseline = tmp_path / "baseline.yaml"
    baseline.write_text("")
    sets = [arg for item in SMALL for arg in ("--set", item)]
    result = CliRunner().invoke(cli, ["emit", str(baseline), *sets, "-o", str(out)])
    assert result.exit_code == 0, result.output
    names = [MODEL_FILE, PROPERTIES_FILE, STORM_ONLY_FILE, CONFIG_FILE]
    assert result.stdout.splitlines() == [str(out / name) for name in names]
    files: MissionFiles = mission_files(_config(False))
    assert (out / STORM_ONLY_FILE).read_text(encoding="utf-8") == files.storm_only
    assert (out / PROPERTIES_FILE).read_text(encoding="utf-8") == files.properties
