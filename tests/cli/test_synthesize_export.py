"""``synthesize --export-strategy FILE --export-induced DIR``: the table's strategy and
the DTMC it induces, whose values Storm (exact) and ``veribattery prism`` confirm."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner, Result

from tests.cli.inputs import CASE1, SYNTHESIS
from veribattery.cli import cli

stormpy = pytest.importorskip("stormpy")

from tests.storm_oracle import run_storm  # noqa: E402

#: synthesize's JSON keys of the strategy's own values, as induced.props names them.
VALUES = ("p_success", "exp_mission_time", "exp_recharges")


def _synthesize(*args: object) -> Result:
    return CliRunner().invoke(cli, ["synthesize", CASE1, *SYNTHESIS, "--format", "json",
                                    *map(str, args)])


@pytest.fixture(scope="module")
def exported(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, object]]:
    """The export folder (strategy.json, induced/) and synthesize's JSON document."""
    folder = tmp_path_factory.mktemp("export")
    result = _synthesize("--export-strategy", folder / "strategy.json",
                         "--export-induced", folder / "induced")
    assert result.exit_code == 0, result.stderr
    for name in ("strategy.json", "induced/induced.prism", "induced/induced.props"):
        assert f"wrote {folder / name}" in result.stderr
    return folder, dict(json.loads(result.stdout))


def _strategy(document: dict[str, object]) -> dict[str, float]:
    own = document["strategy"]
    assert isinstance(own, dict)
    return {name: float(own[name]) for name in VALUES}


def test_storm_confirms_the_strategys_values_exactly(
        exported: tuple[Path, dict[str, object]]) -> None:
    folder, document = exported
    props = (folder / "induced" / "induced.props").read_text(encoding="utf-8")
    storm = run_storm(folder / "induced" / "induced.prism", props, exact=True)
    own = document["strategy"]
    assert isinstance(own, dict)
    assert storm.states == own["states_reached"] == 707
    start = storm.initial[0]
    found = {name: storm.values[i][start] for i, name in enumerate(VALUES)}
    assert found == pytest.approx(_strategy(document), rel=1e-9, abs=1e-12)
    # The safest strategy attains Pmax, and is faster than BS1 (case1's 3x2 farm).
    results, bs1 = document["results"], document["bs1"]
    assert isinstance(results, dict) and isinstance(bs1, dict)
    assert found["p_success"] == pytest.approx(results["p_success_max"], rel=1e-9)
    assert found["exp_mission_time"] < bs1["exp_mission_time"]


def test_prism_reads_the_induced_files_to_the_same_values(
        exported: tuple[Path, dict[str, object]]) -> None:
    folder, document = exported
    induced = folder / "induced"
    text = (induced / "induced.prism").read_text(encoding="utf-8")
    assert text.startswith("// The DTMC that veribattery synthesize's strategy (safest, then "
                           "fastest)\n// induces on model.prism")
    result = CliRunner().invoke(cli, ["prism", str(induced / "induced.prism"), "--props",
                                      str(induced / "induced.props"), "--json"])
    assert result.exit_code == 0, result.stderr
    checked = json.loads(result.stdout)
    assert checked["model"]["states"] == 707
    found = {r["name"]: r["value"] for r in checked["results"]}
    assert found == pytest.approx(_strategy(document), rel=1e-9, abs=1e-12)


def test_the_scheduler_lists_each_reached_state_once(
        exported: tuple[Path, dict[str, object]]) -> None:
    folder, _ = exported
    entries = json.loads((folder / "strategy.json").read_text(encoding="utf-8"))
    assert len(entries) == 707
    first = entries[0]
    assert first["s"] == {"s": 0, "k": 0, "j": 0, "wsp": 0, "b": 60, "rc": 0}
    assert first["c"][0]["labels"] == ["takeoff"]
    assert len({json.dumps(e["s"], sort_keys=True) for e in entries}) == 707


def test_prism_form_by_any_other_suffix(tmp_path: Path) -> None:
    out = tmp_path / "strategy.txt"
    result = _synthesize("--export-strategy", out)
    assert result.exit_code == 0, result.stderr
    lines = out.read_text(encoding="utf-8").splitlines()
    assert len(lines) == 707
    assert lines[0] == "(0,0,0,0,60,0)=takeoff"


def test_existing_files_are_refused_before_any_work(tmp_path: Path) -> None:
    strategy, induced = tmp_path / "strategy.txt", tmp_path / "induced"
    induced.mkdir()
    (induced / "induced.props").write_text("old\n", encoding="utf-8")
    result = _synthesize("--export-strategy", strategy, "--export-induced", induced)
    assert result.exit_code == 2
    assert result.stdout == ""
    assert "--export-induced" in result.stderr and "--force" in result.stderr
    assert not strategy.exists()  # all or nothing: the free file is not written either
    assert not (induced / "induced.prism").exists()
    assert (induced / "induced.props").read_text(encoding="utf-8") == "old\n"
    forced = _synthesize("--export-strategy", strategy, "--export-induced", induced, "--force")
    assert forced.exit_code == 0, forced.stderr
    assert (induced / "induced.props").read_text(encoding="utf-8").startswith("//")
    assert strategy.exists()


def test_an_existing_strategy_file_is_refused(tmp_path: Path) -> None:
    strategy = tmp_path / "strategy.json"
    strategy.write_text("[]\n", encoding="utf-8")
    result = _synthesize("--export-strategy", strategy)
    assert result.exit_code == 2
    assert "--export-strategy" in result.stderr
    assert strategy.read_text(encoding="utf-8") == "[]\n"


def test_the_strategy_file_cannot_be_the_tables(tmp_path: Path) -> None:
    same = tmp_path / "out.csv"
    result = _synthesize("--csv", same, "--export-strategy", same)
    assert result.exit_code == 2
    assert "must name other files" in result.stderr
    assert not same.exists()
