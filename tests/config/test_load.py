"""Loading: files and text, YAML syntax errors with line:col, --set overrides, YAML out."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from veribattery.config import config_to_yaml, load_config, parse_override, set_value
from veribattery.errors import ConfigError

REPO = Path(__file__).resolve().parents[2]
PAPER = sorted((REPO / "configs" / "paper").glob("*.yaml"))


def test_the_paper_configs_are_all_there() -> None:
    """The corpus the round-trip and emitter tests run over: the paper's seven cases."""
    assert [path.stem for path in PAPER] == [
        "basic_high", "basic_low", "basic_medium", "case1", "case2", "case3", "case4"]


def test_yaml_syntax_error_names_file_line_and_column(tmp_path: Path) -> None:
    path = tmp_path / "broken.yaml"
    path.write_text("farm:\n  cols: 6\n  base: [1, 2\nbattery: {}\n")
    with pytest.raises(ConfigError, match="YAML syntax error") as info:
        load_config(path)
    assert info.value.span is not None
    assert info.value.span.source == str(path)
    assert info.value.span.line == 4
    assert str(info.value).startswith(f"{path}:4:")


def test_validation_error_points_at_the_key(tmp_path: Path) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text("# comment\nstrategy:\n  safe_t: 1.5\n")
    with pytest.raises(ConfigError) as info:
        load_config(str(path))
    assert str(info.value) == f"{path}:3:3: strategy.safe_t: must be in (0, 1), got 1.5"


def test_missing_file() -> None:
    with pytest.raises(ConfigError, match=r"cannot read config 'nowhere\.yaml'"):
        load_config("nowhere.yaml")


def test_overrides_parse_values_as_yaml() -> None:
    cfg = load_config("", ["farm.base=[1,1]", "battery.model=basic_high", "strategy.safe_t=0.25"])
    assert cfg.farm.base == (1, 1)
    assert cfg.battery.model == "basic_high"
    assert str(cfg.strategy.safe_t) == "1/4"


def test_overrides_win_over_the_file() -> None:
    cfg = load_config(REPO / "configs" / "paper" / "case1.yaml", ["environment.p_wsp_c=0.3"])
    assert str(cfg.environment.p_wsp_c) == "3/10"


def test_override_may_add_a_property() -> None:
    cfg = load_config("", ['properties.p_fail=P=? [ F "failure" ]'])
    assert cfg.properties["p_fail"] == 'P=? [ F "failure" ]'


@pytest.mark.parametrize(
    ("item", "message"),
    [
        ("farm.base", "--set 'farm.base': expected KEY=VALUE"),
        ("=3", "--set '=3': expected KEY=VALUE"),
        (
            "farm.bse=[1,1]",
            "--set 'farm.bse=[1,1]': unknown key 'farm.bse' (did you mean 'farm.base'?)",
        ),
        ("farm.base=[1,", "--set 'farm.base=[1,': value is not valid YAML"),
    ],
)
def test_malformed_override(item: str, message: str) -> None:
    with pytest.raises(ConfigError) as info:
        parse_override(item)
    assert info.value.message.startswith(message)


def test_bad_override_value_has_no_file_position() -> None:
    with pytest.raises(ConfigError) as info:
        load_config("farm:\n  cols: 6\n", ["farm.base=[9,9]"])
    assert info.value.span is None
    assert info.value.message.startswith("--set farm.base: cell [9, 9] is outside")


def test_set_value_copies_and_creates_sections() -> None:
    base = {"farm": {"cols": 6}}
    new = set_value(base, "farm.base", [1, 1])
    newer = set_value(new, "battery.consumption.high_wind_factor", 3)
    assert base == {"farm": {"cols": 6}}
    assert new == {"farm": {"cols": 6, "base": [1, 1]}}
    assert newer["battery"] == {"consumption": {"high_wind_factor": 3}}


@pytest.mark.parametrize("path", PAPER, ids=lambda p: p.stem)
def test_resolved_yaml_round_trips(path: Path) -> None:
    cfg = load_config(path)
    assert load_config(config_to_yaml(cfg)) == cfg


def test_resolved_yaml_keeps_decimals_and_fractions() -> None:
    cfg = load_config(
        "",
        [
            "strategy.safe_t=1/3",
            "farm.cols=3",
            "farm.rows=3",
            "farm.route=[[0,0],[1,0],[1,1],[0,1]]",
            "farm.base=[0,0]",
        ],
    )
    text = config_to_yaml(cfg)
    assert "safe_t: 1/3" in text and "p_wsp_c: 0.1" in text and "base: [0, 0]" in text
    assert load_config(text) == cfg


def test_example_config_documents_the_defaults() -> None:
    assert load_config(REPO / "configs" / "example.yaml") == load_config("")


@pytest.mark.parametrize(
    ("name", "safe_t", "p_wsp_c", "model"),
    [
        ("case1", "3/10", "1/10", "advanced"),
        ("case2", "1/4", "1/10", "advanced"),
        ("case3", "3/10", "3/10", "advanced"),
        ("case4", "1/4", "3/10", "advanced"),
        ("basic_high", "3/10", "1/10", "basic_high"),
        ("basic_medium", "3/10", "1/10", "basic_medium"),
        ("basic_low", "3/10", "1/10", "basic_low"),
    ],
)
def test_paper_configs(name: str, safe_t: str, p_wsp_c: str, model: str) -> None:
    cfg = load_config(REPO / "configs" / "paper" / f"{name}.yaml")
    assert (str(cfg.strategy.safe_t), str(cfg.environment.p_wsp_c)) == (safe_t, p_wsp_c)
    assert cfg.battery.model == model
    assert cfg.battery.capacity_ah == 11


def test_resolved_yaml_is_the_text_of_pythons_emitter() -> None:
    """libyaml writes the header and the sweep fingerprint; PyYAML's own emitter must agree,
    or a resumed sweep would call its own results another sweep's."""
    if not yaml.__with_libyaml__:
        pytest.skip("PyYAML without libyaml: config_to_yaml uses the Python emitter already")
    from veribattery.config import load as loader

    class PythonDumper(yaml.SafeDumper):  # type: ignore[misc]
        pass

    PythonDumper.add_representer(list, loader._represent_list)
    odd = ('properties={"p": "P=? [ F \\"success\\" ]", "e": "R{\\"mt\\"}=? [ F s=7 ]  # ünï: ok",'
           ' "long": "' + " | ".join(f"s={i}" for i in range(60)) + '"}')
    configs = [load_config(path) for path in PAPER] + [load_config("", [odd, "farm.base=[1, 1]"])]
    for cfg in configs:
        expected = yaml.dump(loader._plain(cfg), Dumper=PythonDumper, sort_keys=False,
                             allow_unicode=True, width=100)
        assert config_to_yaml(cfg) == expected


def test_a_sub_section_given_in_part_keeps_its_other_defaults(tmp_path: Path) -> None:
    """Every key is optional: one level of a consumption row, in the file or by --set,
    leaves the row's other levels (and Eq. 2's sections) at their defaults."""
    from fractions import Fraction

    from veribattery.config.schema import ConsumptionEq2, ConsumptionTable

    baseline = load_config("").battery.consumption
    assert isinstance(baseline, ConsumptionTable)
    by_set = load_config("", ["battery.consumption.cell.low=0.6"])
    path = tmp_path / "c.yaml"
    path.write_text("battery:\n  consumption:\n    cell: {low: 0.6}\n")
    for config in (by_set, load_config(path)):
        table = config.battery.consumption
        assert isinstance(table, ConsumptionTable)
        assert (table.cell.low, table.cell.medium, table.cell.high) == (
            Fraction(3, 5), Fraction(2, 5), Fraction(3, 10))
        assert table.inspection == baseline.inspection
    eq2 = load_config("", ["battery.consumption.voltages_v.low=21"]).battery.consumption
    assert isinstance(eq2, ConsumptionEq2)
    assert (eq2.voltages_v.low, eq2.voltages_v.medium, eq2.energy_wh) == (
        Fraction(21), Fraction(22), Fraction(180))
    with pytest.raises(ConfigError, match=r"battery.consumption.cell.low: must be > 0, got -1"):
        load_config("", ["battery.consumption.cell.low=-1"])


def test_a_loaded_config_is_one_that_renders() -> None:
    # The limits of PRISM's ints are checked by load_config itself, before any work.
    with pytest.raises(ConfigError, match="safe_t: 1e-30 is too fine"):
        load_config("strategy: {safe_t: 1e-30}")
