"""Bad configs a user meets in the first hour: each gives one located line, as a
:class:`~veribattery.errors.VeribatteryError` from the library and, through the CLI,
``error: ...`` on stderr with exit status 2, no traceback and nothing written.

Each case is a config file (bytes, so that a stray byte can be in it), ``--set``
overrides, and the message expected, ``{path}`` standing for the file's path.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import pytest
from click.testing import CliRunner, Result

from veribattery.cli import cli
from veribattery.config import MissionConfig, load_config
from veribattery.errors import ConfigError, VeribatteryError
from veribattery.mission import check_mission, mission_files, validate_properties

SMALL = b"farm: {cols: 3, rows: 3, base: [0, 0]}\n"
LABELS = "(known labels: deadlock, done, failure, init, success)"


@dataclass(frozen=True, slots=True)
class Bad:
    """One bad config: its file, its overrides and the start of the expected message."""

    name: str
    content: bytes
    expected: str
    overrides: tuple[str, ...] = ()

    def __str__(self) -> str:
        return self.name


ENCODING = [
    Bad("byte-0xff", b"farm:\n  cols: 6 \xff\n", "{path}:2:11: not UTF-8 text (byte 0xff)"),
    # Columns count characters: the two-byte e-acute before the bad byte is one column.
    Bad("after-accent", "farm:\n  # caf\u00e9 ".encode() + b"\xe9t\xe9\n",
        "{path}:2:10: not UTF-8 text (byte 0xe9)"),
    Bad("latin-1-file", "# Stra\u00dfe\n".encode("latin-1"),
        "{path}:1:7: not UTF-8 text (byte 0xdf)"),
    Bad("nul-character", b"farm:\n  cols: 6\x00\n",
        "{path}:2:10: YAML does not allow the control character U+0000"),
]

DUPLICATES = [
    Bad("nested", b"farm:\n  cols: 3\n  rows: 3\n  cols: 4\n",
        "{path}:4:3: duplicate key 'farm.cols' (first at line 2, column 3)"),
    Bad("top-level", b"farm:\n  cols: 3\nstrategy: {safe_t: 0.2}\nfarm:\n  rows: 3\n",
        "{path}:4:1: duplicate key 'farm' (first at line 1, column 1)"),
    Bad("flow", b"farm: {cols: 3, rows: 3, cols: 4}\n",
        "{path}:1:26: duplicate key 'farm.cols' (first at line 1, column 8)"),
    Bad("property", SMALL + b"properties:\n  p: P=? [ F \"done\" ]\n  p: P=? [ F \"success\" ]\n",
        "{path}:4:3: duplicate key 'properties.p' (first at line 3, column 3)"),
    Bad("in-set", SMALL, "--set 'farm={cols: 3, cols: 4}': value is not valid YAML: "
        "duplicate key 'farm.cols' at column 11 (first at column 2)", ("farm={cols: 3, cols: 4}",)),
]

PROPERTIES = [
    # The formula is a plain or simply quoted scalar: the position is the file's own.
    Bad("unknown-label", SMALL + b'properties:\n  bad: P=? [ F "nosuch" ]\n',
        '{path}:3:16: properties.bad: unknown label "nosuch" ' + LABELS),
    Bad("unknown-label-quoted", SMALL + b"properties:\n  bad: 'P=? [ F \"nosuch\" ]'\n",
        '{path}:3:17: properties.bad: unknown label "nosuch" ' + LABELS),
    Bad("unknown-reward", SMALL + b'properties:\n  bad: R{"nosuch"}=? [ F "done" ]\n',
        '{path}:3:8: properties.bad: unknown reward structure "nosuch" '
        '(the model has "mt", "rc")'),
    Bad("syntax-end", SMALL + b"properties:\n  bad: P=? [ F\n",
        "{path}:3:15: properties.bad: unexpected end of input (expected "),
    Bad("syntax-token", SMALL + b"properties:\n  ok: P=? [ F \"done\" ]\n  bad: P=? [ F ) ]\n",
        "{path}:4:16: properties.bad: unexpected token ')' (expected "),
    Bad("unsupported", SMALL + b'properties:\n  bad: P=? [ (X "done") + 1 ]\n',
        '{path}:3:8: properties.bad: unsupported property P=? [ (X "done") + 1 ]: temporal '
        "operator X (next) inside an operator that takes a state formula or a number"),
    Bad("named-formula", SMALL + b"properties:\n  bad: '\"x\": P=? [ F \"done\" ]'\n",
        '{path}:3:9: properties.bad: the key names the property: write the formula '
        'without "x":'),
    # A literal block: the formula's lines are the file's lines.
    Bad("block", SMALL + b'properties:\n  bad: |\n    P=? [\n      F "nosuch" ]\n',
        '{path}:5:9: properties.bad: unknown label "nosuch" ' + LABELS),
    # Escapes or folded lines: the key's place, and the column inside the formula.
    Bad("escaped", SMALL + b'properties:\n  bad: "P=? [ F \\"nosuch\\" ]"\n',
        '{path}:3:3: properties.bad: column 9 of the formula: unknown label "nosuch" '
        + LABELS),
    Bad("folded", SMALL + b'properties:\n  bad: >\n    P=? [ F\n    "nosuch" ]\n',
        '{path}:3:3: properties.bad: column 9 of the formula: unknown label "nosuch" '
        + LABELS),
    Bad("set-label", SMALL, '--set properties.bad: column 9 of the formula: unknown label '
        '"nosuch" ' + LABELS, ('properties.bad="P=? [ F \\"nosuch\\" ]"',)),
    Bad("set-syntax", SMALL, "--set properties.bad: column 8 of the formula: unexpected end "
        "of input (expected ", ("properties.bad=P=? [ F",)),
    # A --set replaces the file's formula: the file's position no longer applies.
    Bad("set-over-file", SMALL + b'properties:\n  bad: P=? [ F "done" ]\n',
        '--set properties.bad: column 15 of the formula: unknown label "nosuch" ' + LABELS,
        ('properties.bad=R{"mt"}=? [ F "nosuch" ]',)),
]

#: Numbers the model holds as PRISM ints (decimals are exact: 1e-30 is 1/10^30, and the
#: guards multiply the charge by that denominator), refused before anything is rendered.
NUMBERS = [
    Bad("safe-t-too-fine", b"", "--set strategy.safe_t: 1e-30 is too fine: BS1's guards multiply "
        "the charge (up to 246 units) by safe_t's denominator (10^30), and PRISM's 32-bit "
        "integers hold products below 2^31; give a denominator of at most 8729608 (e.g. at "
        "most 6 decimal places)", ("strategy.safe_t=1e-30",)),
    # In the file: placed there, as every other range error is.
    Bad("safe-t-subnormal", b"strategy: {safe_t: 1e-320}\n", "{path}:1:12: strategy.safe_t: "
        "1e-320 is too fine: BS1's guards multiply the charge (up to 246 units) by safe_t's "
        "denominator (10^320), and"),
    # A YAML float as written, not its nearest double (0.1, and 0 below the subnormals).
    Bad("safe-t-past-doubles", b"strategy: {safe_t: 0.1000000000000000000001}\n",
        "{path}:1:12: strategy.safe_t: 0.1000000000000000000001 is too fine: BS1's guards "
        "multiply the charge (up to 246 units) by safe_t's denominator (10^22), and"),
    Bad("safe-t-below-doubles", b"strategy: {safe_t: 1.0e-330}\n", "{path}:1:12: "
        "strategy.safe_t: 1e-330 is too fine: BS1's guards multiply the charge (up to 246 "
        "units) by safe_t's denominator (10^330), and"),
    Bad("safe-t-past-doubles-set", b"", "--set strategy.safe_t: 0.1000000000000000000001 is too "
        "fine:", ("strategy.safe_t=0.1000000000000000000001",)),
    Bad("safe-t-7-places", b"", "--set strategy.safe_t: 0.0000001 is too fine: BS1's guards "
        "multiply the charge (up to 246 units) by safe_t's denominator (10000000), and",
        ("strategy.safe_t=0.0000001",)),
    Bad("threshold-too-fine", b"", "--set battery.voltage_thresholds.low: 1e-320 is too fine: the "
        "voltage guards multiply the charge (up to 110 units) by the thresholds' common "
        "denominator (10^320), and PRISM's 32-bit integers hold products below 2^31; give a "
        "denominator of at most 19522578 (e.g. at most 7 decimal places)",
        ("battery.voltage_thresholds.low=1e-320",)),
    Bad("cell-cost", b"", "--set battery.consumption.cell.low: 1e+308 is too large: a take-off, "
        "the flight to the farthest cell (4 cells) and an inspection would need about 8e+309 units "
        "of resolution_ah (0.1), which must stay below 2^30 for PRISM's 32-bit integers",
        ("battery.consumption.cell={low: 1e308, medium: 0.4, high: 0.3}",)),
    Bad("high-wind-factor", b"", "--set battery.consumption.high_wind_factor: 1e+300 is too "
        "large: a take-off, the flight to the farthest cell (4 cells) and an inspection would need "
        "about 6.8e+301 units", ("battery.consumption.high_wind_factor=1e300",)),
    # One cell: no decision flies a cell, but its cost is still an int constant of the model.
    Bad("unused-cell-cost", b"farm: {cols: 2, rows: 2, base: [0, 0]}\n",
        "--set battery.consumption.cell.low: 1e+300 is too large: one action would cost about "
        "2e+301 units of resolution_ah (0.1), an int constant of the model, which must stay "
        "below 2^30 for PRISM's 32-bit integers", ("battery.consumption.cell.low=1e300",)),
    Bad("eq2-energy", b"", "--set battery.consumption.energy_wh: too large: a take-off, the "
        "flight to the farthest cell (4 cells) and an inspection would need about 8e+299 units",
        ("battery.consumption.energy_wh=1e300",)),
    Bad("time-beyond-64-bits", b"", "--set times_min.recharge: 9223372036854775808 is too large: "
        "minutes must stay at most 2147483647 for PRISM's 32-bit integers",
        ("times_min.recharge=9223372036854775808",)),
    Bad("time-1e308", b"", "--set times_min.wait: 1e+308 is too large: minutes must stay at most "
        "2147483647 for PRISM's 32-bit integers", ("times_min.wait=1e308",)),
    Bad("time-per-cell", b"", "--set times_min.per_cell: 1000000000 is too large: minutes x the "
        "longest flight in cells must stay at most 536870911 for PRISM's 32-bit integers",
        ("times_min.per_cell=1000000000",)),
    Bad("time-denominator", b"", "--set times_min.wait: 1/3000000000000000000000 has a denominator "
        "too large for PRISM's 32-bit integers: give a decimal, or p/q with q at most "
        "2147483647", ("times_min.wait=1/3000000000000000000000",)),
    Bad("max-recharges", b"battery: {model: basic_low}\n", "--set battery.max_recharges: must be "
        "below 2^31 - 1 for PRISM's 32-bit integers, got 100000000000000000000",
        ("battery.max_recharges=100000000000000000000",)),
]

#: Farms too large to lay out (deriving the route of 10^12 turbines never ended).
SIZES = [
    Bad("farm-too-large", b"farm: {cols: 1000000000000, rows: 3, base: [0, 0]}\n",
        "{path}:1:8: farm.cols: 1000000000000 x 3 turbines is too large a farm: cols x rows "
        "must be at most 100,000"),
    Bad("farm-too-large-set", b"", "--set farm.cols: 1000 x 101 turbines is too large a farm",
        ("farm.cols=1000", "farm.rows=101")),
]

#: Keys YAML allows but a config cannot name: they said '{path}:1:1: [1]: Keys should be
#: strings', at the file's start, naming no key.
KEYS = [
    Bad("number-key", SMALL + b"1: 2\n", "{path}:2:1: 1: a key must be a name, got 1 "
        "(allowed: battery, environment, farm, properties, requirements, strategy, sweep, "
        "times_min)"),
    Bad("number-key-in-section", b"farm: {cols: 3, rows: 3, base: [0, 0], 7: 1}\n",
        "{path}:1:40: farm.7: a key must be a name, got 7 (allowed: base, cols, route, rows, "
        "spacing_m)"),
    Bad("number-property-name", SMALL + b"properties: {1: 'P=? [ F \"success\" ]'}\n",
        "{path}:2:14: properties.1: a key must be a name, got 1"),
]

#: Numbers too large or too long to read: 10^5000 was a traceback (Python writes no int of
#: more than 4,300 digits), 1.0e-5000 silently 0; each is now refused by the size rule.
OUT_OF_RANGE = ("is out of range: a number must be 0 or between 1e-400 and 1e400 in size, "
                "with at most 400 significant digits")
HUGE = [
    Bad("exponent-in-file", b"times_min: {per_cell: 1e5000}\n",
        f"{{path}}:1:13: times_min.per_cell: 1e5000 {OUT_OF_RANGE}"),
    Bad("exponent-set", SMALL, f"--set battery.resolution_ah: 1e-5000 {OUT_OF_RANGE}",
        ("battery.resolution_ah=1e-5000",)),
    Bad("float-exponent", b"strategy: {safe_t: 1.0e-5000}\n",
        f"{{path}}:1:20: strategy.safe_t: 1.0e-5000 {OUT_OF_RANGE}"),
    Bad("int-digits", b"farm:\n  cols: " + b"9" * 5000 + b"\n",
        f"{{path}}:2:9: farm.cols: 999999999999\u2026999999 (5,000 characters) {OUT_OF_RANGE}"),
    Bad("requirement-bound", SMALL, f"--set requirements[0]: bound 1e-5000 {OUT_OF_RANGE}",
        ("requirements=['p_success >= 1e-5000']",)),
    # Within the rule, but the model's derived integers are not: shown short.
    Bad("capacity-1e300", SMALL, "--set battery.capacity_ah: capacity_ah/resolution_ah x the "
        "fade's denominator (10^301 x 500) must stay below 2^30", ("battery.capacity_ah=1e300",)),
]

#: A check across keys names the key the user gave (a --set before the file's), where it
#: was given; it blamed a key the file never held, placed at its section's line.
ACROSS = [
    Bad("threshold-set", SMALL + b"battery: {capacity_ah: 6}\n",
        "--set battery.voltage_thresholds.high: must be >= low (0.25), got 0.1",
        ("battery.voltage_thresholds.high=0.1",)),
    Bad("recharges-set", SMALL + b"battery: {capacity_ah: 6}\n",
        "--set battery.max_recharges: must be at most 499 so that fade_per_recharge (0.002) x "
        "max_recharges stays < 1 (the capacity positive), got 99999999999999999999",
        ("battery.max_recharges=99999999999999999999",)),
    Bad("resolution-set", SMALL + b"battery: {capacity_ah: 6}\n",
        "--set battery.resolution_ah: must divide capacity_ah (6) into whole units, got 0.7",
        ("battery.resolution_ah=0.7",)),
    Bad("base-by-default", b"farm: {cols: 2, rows: 2}\n", "{path}:1:8: farm.cols: 2 x 2 "
        "turbines leave farm.base's cell [2, 2] outside the 1 x 1 cells"),
    Bad("thresholds-in-file", b"battery:\n  voltage_thresholds: {low: 0.5, high: 0.4}\n",
        "{path}:2:24: battery.voltage_thresholds.low: must be <= high (0.4), got 0.5"),
]

#: A requirement on a probability with a bound outside [0, 1] holds always or never: bad
#: input before any work (it was a check, then exit 1), as PRISM refuses P>1.5 [ ... ].
REQUIREMENTS = [
    Bad("probability-bound-set", SMALL, "--set requirements[0]: p_success is a probability "
        '(P=? [ F "success" ]): the bound must be in [0, 1], got 1.5',
        ('requirements=["p_success >= 1.5"]',)),
    Bad("probability-bound-file", SMALL + b"requirements: ['p_success > -0.5']\n",
        "{path}:2:16: requirements[0]: p_success is a probability (P=? [ F \"success\" ]): the "
        "bound must be in [0, 1], got -0.5"),
    Bad("pmax-bound", SMALL + b"properties: {best: 'Pmax=? [ F \"done\" ]'}\n"
        b"requirements: ['best < 2']\n", "{path}:3:16: requirements[0]: best is a probability"),
]

#: YAML aliases: one that holds itself, and values shown short in a message (an alias
#: repeats a whole list).
ALIASES = [
    Bad("alias-holds-itself", b"farm: &a {cols: 3, rows: 3, x: [*a]}\n",
        "{path}:1:7: the alias at 'farm.x[0]' stands for a list or mapping that holds it"),
    Bad("alias-in-a-message", b"sweep:\n  vary: &v ['x', 'x', 'x', 'x', 'x', 'x']\n"
        b"properties:\n  a: [*v, *v, *v, *v, *v, *v]\n", "{path}:4:3: properties.a: must be a "
        "string, got [['x', 'x', 'x', 'x', 'x', 'x'], ['x', 'x', 'x', 'x', 'x', 'x'], \u2026 "
        "(6 items)]"),
    Bad("property-name-set", SMALL, "--set 'properties.1bad=P=? [ F \"success\" ]': property "
        "name '1bad' must be an identifier (letters, digits and _, not starting with a digit)",
        ('properties.1bad=P=? [ F "success" ]',)),
]

CASES = (ENCODING + DUPLICATES + PROPERTIES + NUMBERS + SIZES + KEYS + HUGE + ACROSS
         + REQUIREMENTS + ALIASES)


def _write(tmp_path: Path, case: Bad) -> Path:
    path = tmp_path / "mission.yaml"
    path.write_bytes(case.content)
    return path


def _expected(case: Bad, path: Path) -> str:
    return case.expected.replace("{path}", str(path))


def _load_and_validate(path: Path, overrides: tuple[str, ...]) -> None:
    validate_properties(load_config(path, overrides))


@pytest.mark.parametrize("case", CASES, ids=str)
def test_library_error_names_the_place(tmp_path: Path, case: Bad) -> None:
    path = _write(tmp_path, case)
    with pytest.raises(VeribatteryError) as info:
        _load_and_validate(path, case.overrides)
    assert isinstance(info.value, ConfigError)
    assert str(info.value).startswith(_expected(case, path))
    assert "\n" not in str(info.value)


def _one_error_line(result: Result, case: Bad, path: Path) -> None:
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output + result.stderr
    assert result.stdout == ""
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("error: " + _expected(case, path))


@pytest.mark.parametrize("case", CASES, ids=str)
def test_check_prints_one_line_and_exits_2(tmp_path: Path, case: Bad) -> None:
    path = _write(tmp_path, case)
    sets = [arg for item in case.overrides for arg in ("--set", item)]
    out = tmp_path / "out"
    result = CliRunner().invoke(cli, ["check", str(path), *sets, "--emit", str(out)])
    _one_error_line(result, case, path)
    assert not out.exists()


@pytest.mark.parametrize("case", CASES, ids=str)
def test_emit_refuses_and_writes_nothing(tmp_path: Path, case: Bad) -> None:
    path = _write(tmp_path, case)
    sets = [arg for item in case.overrides for arg in ("--set", item)]
    out = tmp_path / "out"
    result = CliRunner().invoke(cli, ["emit", str(path), *sets, "-o", str(out)])
    _one_error_line(result, case, path)
    assert not out.exists()


def test_emit_into_an_existing_directory_leaves_it_empty(tmp_path: Path) -> None:
    case = PROPERTIES[0]
    path = _write(tmp_path, case)
    out = tmp_path / "out"
    out.mkdir()
    result = CliRunner().invoke(cli, ["emit", str(path), "-o", str(out)])
    assert result.exit_code == 2
    assert list(out.iterdir()) == []


def test_bad_property_is_refused_before_any_model_is_built(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def never(*_args: object, **_kwargs: object) -> None:
        raise AssertionError("a model was built for a config with a bad property")

    monkeypatch.setattr("veribattery.pipeline.Session.check", never)
    path = _write(tmp_path, PROPERTIES[0])
    cfg = load_config(path)
    for step in (check_mission, mission_files):
        with pytest.raises(ConfigError, match=r'properties\.bad: unknown label "nosuch"'):
            step(cfg)


@pytest.mark.parametrize(("key", "value"), [("strategy.safe_t", "0.000001"),
                                            ("battery.voltage_thresholds.low", "0.0000001"),
                                            ("times_min.per_cell", "536870911"),
                                            ("times_min.wait", "1/2147483647")])
def test_numbers_just_within_prisms_ints_are_rendered(key: str, value: str) -> None:
    validate_properties(load_config("", [f"{key}={value}"]))


def test_config_built_in_python_names_the_key() -> None:
    cfg = MissionConfig(properties={"bad": 'P=? [ F "nosuch" ]'})
    with pytest.raises(ConfigError) as info:
        validate_properties(cfg)
    assert str(info.value) == (
        f'properties.bad: column 9 of the formula: unknown label "nosuch" {LABELS}'
    )


def test_where_a_config_came_from_does_not_change_it(tmp_path: Path) -> None:
    path = tmp_path / "baseline.yaml"
    path.write_text("# the paper's baseline\nproperties:\n  p: P=? [ F \"done\" ]\n")
    from_file = load_config(path)
    from_text = load_config('properties:\n  p: P=? [ F "done" ]\n')
    from_set = load_config("", ["properties={p: 'P=? [ F \"done\" ]'}"])
    assert from_file == from_text == from_set == MissionConfig(
        properties={"p": 'P=? [ F "done" ]'})


@pytest.mark.parametrize(("content", "overrides", "expected"), [
    (("a: " + "[" * 2000 + "]" * 2000 + "\n").encode(), (),
     r"{path}:1:\d+: YAML nested too deeply: "),
    (b"farm:\n" + "".join("  " * i + f"a{i}:\n" for i in range(1, 600)).encode(), (),
     r"{path}:\d+:\d+: YAML nested too deeply: "),
    (b"", ("farm.base=" + "[" * 3000,),
     r"--set 'farm.base=\[+ … \(2,330 characters\) … \[+': value is not valid YAML: "
     r"YAML nested too deeply: "),  # (the value cut in its middle: a line of 3,000 [)
], ids=["flow", "block", "set"])
def test_deep_nesting_is_one_located_line(tmp_path: Path, content: bytes,
                                          overrides: tuple[str, ...], expected: str) -> None:
    """PyYAML composes nested nodes recursively: past a few hundred levels it raised
    RecursionError, a traceback; now it is a config error placed where the nesting is."""
    path = tmp_path / "mission.yaml"
    path.write_bytes(content)
    sets = [arg for item in overrides for arg in ("--set", item)]
    for command in (["check", str(path), *sets], ["emit", str(path), *sets, "-o", "out"]):
        result = CliRunner().invoke(cli, command)
        assert result.exit_code == 2, result.output
        assert result.stdout == "" and "Traceback" not in result.stderr
        assert len(result.stderr.splitlines()) == 1, result.stderr
        assert re.match("error: " + expected.replace("{path}", re.escape(str(path))),
                        result.stderr), result.stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(("content", "overrides", "expected"), [
    (SMALL + b'properties:\n  ok: P=? [ F "success" ]\n  bad: P=? [ F mod(b,0)=1 ]\n', (),
     "{path}:4:16: properties.bad: modulo with non-positive divisor"),
    (SMALL + b"properties:\n  bad: |\n    P=? [\n      F mod(b,0)=1 ]\n", (),
     "{path}:5:9: properties.bad: modulo with non-positive divisor"),
    (SMALL, ("properties.x=P=? [ F pow(b,-1)=0 ]",),
     "--set properties.x: column 9 of the formula: negative exponent in integer pow"),
], ids=["file", "block", "set"])
@pytest.mark.parametrize("exact", [False, True], ids=["float", "exact"])
def test_a_formula_failing_in_the_check_is_placed_in_the_config(
        tmp_path: Path, content: bytes, overrides: tuple[str, ...], expected: str,
        exact: bool) -> None:
    """A formula that resolves but cannot be evaluated fails in the check, where the
    error was placed in the rendered 'properties.props:3:14', a file the user never
    wrote; now at the formula's place in the config, or its --set."""
    path = tmp_path / "mission.yaml"
    path.write_bytes(content)
    sets = [arg for item in overrides for arg in ("--set", item)]
    result = CliRunner().invoke(cli, ["check", str(path), *sets, *(["--exact"] * exact)])
    assert result.exit_code == 2, result.output
    assert result.stderr.startswith("error: " + expected.replace("{path}", str(path)))
    assert "properties.props" not in result.stderr and result.stdout == ""


@pytest.mark.parametrize("written", ["1:05", "010", "0o12"])
def test_a_number_yaml_1_1_reads_otherwise_is_refused_not_misread(written: str,
                                                                    tmp_path: Path) -> None:
    """PyYAML's YAML 1.1 read ``1:05`` as 65 (base 60) and ``010`` as 8 (octal)."""
    config = tmp_path / "c.yaml"
    config.write_text(f"battery:\n  max_recharges: {written}\n", encoding="utf-8")
    with pytest.raises(ConfigError, match=f"battery.max_recharges: must be an integer, "
                                          f"got '{written}'"):
        load_config(config)


@pytest.mark.parametrize(("written", "value"), [("12", 12), ("1_2", 12), ("0x0c", 12)])
def test_decimal_and_hex_integers_are_read(written: str, value: int, tmp_path: Path) -> None:
    config = tmp_path / "c.yaml"
    config.write_text(f"battery:\n  max_recharges: {written}\n", encoding="utf-8")
    assert load_config(config).battery.max_recharges == value
    assert load_config(config, [f"battery.max_recharges={written}"]).battery.max_recharges == value
