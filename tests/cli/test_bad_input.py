"""A corpus of bad input over every command and option: each gives one line, exit 2.

For every case: exit status 2, exactly one ``error:`` line on stderr (no traceback),
nothing on stdout, and the working folder exactly as it was (nothing written, nothing
partial, no temporary file left behind).
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from click.testing import CliRunner

from tests.cli.inputs import CASE1, SMALL, SYNTHESIS
from veribattery.cli import cli

DIE = "dtmc\nmodule m\n  s : [0..2] init 0;\n  [] s<2 -> 0.5 : (s'=s+1) + 0.5 : (s'=0);\n" \
      "  [] s=2 -> true;\nendmodule\nlabel \"two\" = s=2;\n"

#: Input files every case can use, made in the working folder.
FILES: dict[str, bytes] = {
    "die.pm": DIE.encode(),
    "die.props": b'P=? [ F "two" ]\n',
    "bad_syntax.pm": DIE.replace("init 0;", "init 0").encode(),
    "bad_props.props": b'P=? [ F "nosuch" ]\n',
    "ctmc.pm": DIE.replace("dtmc", "ctmc").encode(),
    "config.yaml": b"farm:\n  cols: 3\n  rows: 3\n  base: [0, 0]\n",
    "not_utf8.yaml": b"farm:\n  cols: 3 \xff\n",
    "duplicate.yaml": b"farm:\n  cols: 3\n  cols: 4\n",
    "unknown_key.yaml": b"farm:\n  colls: 3\n",
    "wrong_type.yaml": b"strategy:\n  safe_t: high\n",
    "out_of_range.yaml": b"strategy:\n  safe_t: 1.5\n",
    "yaml_syntax.yaml": b"farm: {cols: 3\n",
    "list.yaml": b"- 1\n- 2\n",
    "bad_property.yaml": b"properties:\n  p: 'P=? [ F \"nosuch\" ]'\n",
    "property_syntax.yaml": b"properties:\n  p: 'P=? [ F '\n",
    "requirement.yaml": b"requirements: ['nosuch >= 0.9']\n",
    "reserved_property.yaml": b"properties:\n  recharge_cap_probability: 'P=? [ F \"done\" ]'\n",
    "cycles.csv": b"cycle,capacity_ah\n0,11\n10,10.9\n20,10.8\n30,10.7\n",
    "cycles_extra_cell.csv": b"cycle,capacity_ah\n0,11\n10,10.9,7\n20,10.8\n",
    "cycles_no_column.csv": b"cycle,capacity\n0,11\n10,10.9\n",
    "cycles_not_number.csv": b"cycle,capacity_ah\n0,11\n10,ten\n",
    "discharge.csv": b"soc,voltage_v\n1,4.2\n0.5,3.7\n0,3.0\n",
    "dup_names.props": b'"a": P=? [ F "two" ];\n"b": P=? [ F s=1 ];\n"a": P>0.5 [ F s=1 ];\n',
    "walk.nm": b"mdp\nmodule m\n  s : [0..2] init 0;\n  [go] s<2 -> (s'=s+1);\n"
               b"  [stay] s<2 -> true;\n  [] s=2 -> true;\nendmodule\nlabel \"two\" = s=2;\n",
    "no_init.pm": DIE.replace("  s : [0..2] init 0;\n", "  s : [0..2];\n").replace(
        "endmodule\n", "endmodule\ninit s>5 endinit\n").encode(),
    "nul.pm": DIE.replace("endmodule", "\x00endmodule").encode(),
    "existing.png": b"not really a png",
    "existing.csv": b"a,b\n",
    "existing.html": b"<p>my notes</p>\n",
}

CASES: list[tuple[str, list[str]]] = [
    # config files
    ("missing-config", ["check", "nosuch.yaml"]),
    ("config-is-folder", ["check", "a_folder.csv"]),
    ("not-utf8", ["check", "not_utf8.yaml"]),
    ("duplicate-key", ["check", "duplicate.yaml"]),
    ("unknown-key", ["check", "unknown_key.yaml"]),
    ("wrong-type", ["check", "wrong_type.yaml"]),
    ("out-of-range", ["check", "out_of_range.yaml"]),
    ("yaml-syntax", ["check", "yaml_syntax.yaml"]),
    ("config-not-mapping", ["check", "list.yaml"]),
    ("config-bad-property", ["check", "bad_property.yaml"]),
    ("config-reserved-property", ["check", "reserved_property.yaml", "--format", "csv"]),
    ("explain-strategy-devnull", ["explain", "config.yaml", "--strategy", "/dev/null"]),
    ("explain-csv-suffix", ["explain", "config.yaml", "--csv", "p.txt"]),
    ("reproduce-no-target", ["reproduce"]),
    ("distribution-long-day", ["distribution", "config.yaml", "--working-day", "25h"]),
    ("distribution-day-unread", ["distribution", "config.yaml", "--working-day", "8h"]),
    ("check-max-states-word", ["check", "config.yaml", "--max-states", "lots"]),
    ("distribution-fractional-time", ["distribution", "config.yaml", "--set",
                                      "times_min.inspection=0.5"]),
    ("set-reserved-property", ["check", "config.yaml", "--set",
                               'properties.recharge_cap_probability=P=? [ F "done" ]']),
    ("config-property-syntax", ["check", "property_syntax.yaml"]),
    ("config-requirement", ["check", "requirement.yaml"]),
    ("emit-bad-property", ["emit", "bad_property.yaml", "-o", "out"]),
    ("emit-not-utf8", ["emit", "not_utf8.yaml", "-o", "out"]),
    # --set
    ("set-no-equals", ["check", CASE1, "--set", "farm.cols"]),
    ("set-unknown-key", ["check", CASE1, "--set", "farm.colls=3"]),
    ("set-bad-yaml", ["check", CASE1, "--set", "farm.base=[1,"]),
    ("set-bad-value", ["check", CASE1, "--set", "battery.capacity_ah=-1"]),
    ("set-base-outside", ["check", CASE1, "--set", "farm.cols=3", "--set", "farm.rows=3"]),
    ("set-property", ["check", CASE1, "--set", 'properties.x=P=? [ F "nosuch" ]']),
    # --vary and sweep options
    ("vary-range", ["sweep", CASE1, *SMALL, "--vary", "battery.capacity_ah=10:12"]),
    ("vary-letters", ["sweep", CASE1, *SMALL, "--vary", "battery.capacity_ah=a:b:c"]),
    ("vary-key", ["sweep", CASE1, *SMALL, "--vary", "battery.capacty_ah=10:12:1"]),
    ("vary-invalid-point", ["sweep", CASE1, *SMALL, "--vary", "strategy.safe_t=0.3,1.5"]),
    ("vary-empty", ["sweep", CASE1, *SMALL, "--vary", "battery.capacity_ah="]),
    ("vary-backwards", ["sweep", CASE1, *SMALL, "--vary", "battery.capacity_ah=12:10:1"]),
    ("sweep-no-vary", ["sweep", CASE1, *SMALL]),
    ("sweep-plot-property", ["sweep", CASE1, *SMALL, "--vary", "battery.capacity_ah=10,11",
                             "--plot", "p.png", "--plot-property", "nosuch"]),
    ("sweep-plot-type", ["sweep", CASE1, *SMALL, "--vary", "battery.capacity_ah=10,11",
                         "--plot", "p.xyz"]),
    ("sweep-plot-no-suffix", ["sweep", CASE1, *SMALL, "--vary", "battery.capacity_ah=10,11",
                              "--plot", "plot"]),
    ("sweep-plot-exists", ["sweep", CASE1, *SMALL, "--vary", "battery.capacity_ah=10,11",
                           "--plot", "existing.png"]),
    ("sweep-plot-x", ["sweep", CASE1, *SMALL, "--vary", "battery.capacity_ah=10,11",
                      "--plot", "p.png", "--plot-x", "battery.model"]),
    ("sweep-output-type", ["sweep", CASE1, *SMALL, "--vary", "battery.capacity_ah=10,11",
                           "-o", "results.txt"]),
    ("sweep-output-nodir", ["sweep", CASE1, *SMALL, "--vary", "battery.capacity_ah=10,11",
                            "-o", "nodir/results.csv"]),
    ("sweep-jobs", ["sweep", CASE1, *SMALL, "--vary", "battery.capacity_ah=10,11", "-j", "0"]),
    ("sweep-format", ["sweep", CASE1, "--vary", "battery.capacity_ah=10,11", "--format", "x"]),
    # Dask's parse said "invalid literal for int()": the option and the port are named now
    ("sweep-scheduler-port", ["sweep", CASE1, *SMALL, "--vary", "battery.capacity_ah=10,11",
                              "--scheduler", "tcp://host:abc"]),
    ("sweep-scheduler-no-port", ["sweep", CASE1, *SMALL, "--vary", "battery.capacity_ah=10,11",
                                 "--scheduler", "tcp://host:"]),
    ("reproduce-scheduler-port", ["reproduce", "fig6", "--scheduler", "tcp://host:70000",
                                  "-o", "out/figs"]),
    # PRISM files and properties
    ("prism-missing", ["prism", "nosuch.pm"]),
    ("prism-syntax", ["prism", "bad_syntax.pm", "--property", 'P=? [ F s=2 ]']),
    ("prism-ctmc", ["prism", "ctmc.pm", "--property", 'P=? [ F s=2 ]']),
    ("prism-bad-label", ["prism", "die.pm", "--props", "bad_props.props"]),
    ("prism-property-syntax", ["prism", "die.pm", "--property", "P=? [ F "]),
    ("prism-index", ["prism", "die.pm", "--props", "die.props", "--property", "7"]),
    ("prism-index-negative", ["prism", "die.pm", "--props", "die.props", "--property", "-1"]),
    ("prism-duplicate-name", ["prism", "die.pm", "--props", "dup_names.props"]),
    ("prism-export-same-path", ["prism", "walk.nm", "--property", 'Pmax=? [ F "two" ]',
                                "--export-strategy", "x.json", "--export-induced", "x.json"]),
    ("prism-export-conditional", ["prism", "walk.nm", "--property",
                                  'Pmax=? [ F "two" || F s=1 ]', "--export-strategy", "s.txt"]),
    ("prism-explain-mdp", ["prism", "walk.nm", "--explain", "two"]),
    ("prism-explain-and-simulate", ["prism", "die.pm", "--property", 'P=? [ F s=2 ]',
                                    "--explain", "two", "--simulate", "10"]),
    ("prism-top-alone", ["prism", "die.pm", "--property", 'P=? [ F s=2 ]', "--top", "5"]),
    ("prism-seed-alone", ["prism", "die.pm", "--property", 'P=? [ F s=2 ]', "--seed", "3"]),
    # the paths are written by -o only: --path-count alone was ignored
    ("simulate-path-count-alone", ["simulate", CASE1, *SMALL, "--runs", "5",
                                   "--path-count", "3"]),
    ("prism-path-count-without-output", ["prism", "die.pm", "--property", 'P=? [ F s=2 ]',
                                         "--simulate", "10", "--path-count", "3"]),
    ("check-force-alone", ["check", CASE1, *SMALL, "--force"]),
    ("prism-init-none", ["prism", "no_init.pm", "--property", 'P=? [ F s=2 ]']),
    ("prism-nul-byte", ["prism", "nul.pm", "--property", 'P=? [ F s=2 ]']),
    ("distribution-coverage-nan", ["distribution", CASE1, *SMALL, "--coverage", "nan"]),
    ("distribution-unknown-reward", ["distribution", CASE1, *SMALL, "--reward", "nosuch"]),
    ("explain-strategy-folder", ["explain", CASE1, *SMALL, "--strategy", "a_folder.csv"]),
    ("emit-dash", ["emit", CASE1, *SMALL, "-o", "-"]),
    ("check-endless-input", ["check", "/dev/zero"]),
    ("sweep-plot-property-alone", ["sweep", CASE1, *SMALL, "--vary",
                                   "battery.capacity_ah=10,11", "--plot-property", "p_success"]),
    ("prism-const", ["prism", "die.pm", "--property", 'P=? [ F s=2 ]', "--const", "N"]),
    ("prism-unknown-const", ["prism", "die.pm", "--property", 'P=? [ F s=2 ]',
                             "--const", "N=3"]),
    ("prism-json-and-csv", ["prism", "die.pm", "--property", 'P=? [ F s=2 ]', "--json",
                            "--format", "csv"]),
    ("prism-simulate-zero", ["prism", "die.pm", "--property", 'P=? [ F s=2 ]',
                             "--simulate", "0"]),
    ("prism-paths-exists", ["prism", "die.pm", "--property", 'P=? [ F s=2 ]',
                            "--simulate", "10", "-o", "existing.csv"]),
    ("prism-explain-label", ["prism", "die.pm", "--explain", "nosuch"]),
    # analyses
    ("explain-top", ["explain", CASE1, *SMALL, "--top", "0"]),
    ("explain-by", ["explain", CASE1, *SMALL, "--by", "nosuch"]),
    ("explain-by-empty", ["explain", CASE1, *SMALL, "--by", ""]),
    ("explain-by-empty-key", ["explain", CASE1, *SMALL, "--by", "wind,+cell"]),
    ("explain-by-twice", ["explain", CASE1, *SMALL, "--by", "cell,wind", "--by", "cell"]),
    ("explain-by-key-twice", ["explain", CASE1, *SMALL, "--by", "cell+cell"]),
    # a million paths took minutes and gigabytes: at most 1,000
    ("explain-top-huge", ["explain", CASE1, *SMALL, "--top", "1000000"]),
    ("prism-explain-top-huge", ["prism", "die.pm", "--explain", "two", "--top", "1001"]),
    ("report-top-huge", ["report", CASE1, *SMALL, "-o", "r.html", "--top", "1001"]),
    ("explain-output-exists", ["explain", CASE1, *SMALL, "-o", "existing.csv"]),
    ("explain-output-folder", ["explain", CASE1, *SMALL, "-o", "a_folder.csv"]),
    # two names of one option, or one given twice: click kept the last file, silently
    ("explain-output-and-csv", ["explain", CASE1, *SMALL, "-o", "a.csv", "--csv", "b.csv"]),
    ("explain-output-twice", ["explain", CASE1, *SMALL, "-o", "a.csv", "-o", "b.csv"]),
    ("simulate-output-and-paths", ["simulate", CASE1, *SMALL, "--runs", "5", "--paths", "a.csv",
                                   "-o", "b.csv"]),
    ("simulate-runs", ["simulate", CASE1, *SMALL, "--runs", "0"]),
    ("simulate-runs-text", ["simulate", CASE1, *SMALL, "--runs", "many"]),
    ("simulate-output-nodir", ["simulate", CASE1, *SMALL, "--runs", "5",
                               "-o", "nodir/paths.csv"]),
    ("distribution-working-day", ["distribution", CASE1, *SMALL, "--working-day", "0h"]),
    ("distribution-deadline", ["distribution", CASE1, *SMALL, "--deadline", "5 weeks"]),
    ("distribution-coverage", ["distribution", CASE1, *SMALL, "--coverage", "2"]),
    ("distribution-output-nodir", ["distribution", CASE1, *SMALL, "-o", "nodir/cdf.csv"]),
    ("distribution-output-folder", ["distribution", CASE1, *SMALL, "-o", "a_folder.csv",
                                    "--force"]),
    ("distribution-plot-type", ["distribution", CASE1, *SMALL, "--plot", "cdf.xyz"]),
    ("distribution-plot-no-suffix", ["distribution", CASE1, *SMALL, "--plot", "cdf"]),
    ("distribution-reward", ["distribution", CASE1, *SMALL, "--reward", "nosuch"]),
    ("reproduce-what", ["reproduce", "fig9"]),
    ("reproduce-all-no-dir", ["reproduce", "all"]),
    ("reproduce-dir-is-file", ["reproduce", "fig6", "-o", "existing.csv"]),
    # the folder was made before the scheduler was found unreachable, and left behind
    ("reproduce-scheduler", ["reproduce", "fig6", "--scheduler", "nosuch", "-o", "out/figs"]),
    # synthesize
    ("synthesize-require-range", ["synthesize", CASE1, *SYNTHESIS, "--require", "1.5"]),
    ("synthesize-require-text", ["synthesize", CASE1, *SYNTHESIS, "--require", "high"]),
    ("synthesize-require-nan", ["synthesize", CASE1, *SYNTHESIS, "--require", "nan"]),
    ("synthesize-format", ["synthesize", CASE1, *SYNTHESIS, "--format", "yaml"]),
    ("synthesize-exact", ["synthesize", CASE1, *SYNTHESIS, "--exact"]),
    ("synthesize-csv-exists", ["synthesize", CASE1, *SYNTHESIS, "--csv", "existing.csv"]),
    ("synthesize-csv-type", ["synthesize", CASE1, *SYNTHESIS, "--csv", "table.txt"]),
    ("synthesize-pareto-type", ["synthesize", CASE1, *SYNTHESIS, "--pareto", "front.xyz"]),
    ("synthesize-pareto-csv-exists", ["synthesize", CASE1, *SYNTHESIS, "--pareto",
                                      "existing.svg"]),
    ("synthesize-same-file", ["synthesize", CASE1, *SYNTHESIS, "--csv", "t.csv",
                              "--pareto-csv", "t.csv"]),
    # a synthesis point gives p_success_max and its interval, not BS1's p_success
    ("sweep-synthesis-plot", ["sweep", CASE1, *SMALL, "--set", "strategy.mode=synthesize",
                              "--vary", "battery.capacity_ah=10,11", "-o", "results.csv",
                              "--plot", "p.png", "--plot-property", "p_success"]),
    # report
    ("report-no-output", ["report", CASE1, *SMALL]),
    ("report-output-type", ["report", CASE1, *SMALL, "-o", "r.pdf"]),
    ("report-output-exists", ["report", CASE1, *SMALL, "-o", "existing.html"]),
    ("report-sweep-missing", ["report", CASE1, *SMALL, "-o", "r.html", "--sweep", "nosuch.csv"]),
    ("report-sweep-foreign", ["report", CASE1, *SMALL, "-o", "r.html", "--sweep",
                              "existing.csv"]),
    ("report-runs", ["report", CASE1, *SMALL, "-o", "r.html", "--runs", "-1"]),
    # battery prognostics
    ("fade-missing", ["phm", "fade", "nosuch.csv"]),
    ("fade-extra-cell", ["phm", "fade", "cycles_extra_cell.csv"]),
    ("fade-no-column", ["phm", "fade", "cycles_no_column.csv"]),
    ("fade-not-number", ["phm", "fade", "cycles_not_number.csv"]),
    ("fade-at-cycle", ["phm", "fade", "cycles.csv", "--at-cycle", "-5"]),
    ("fade-plot-type", ["phm", "fade", "cycles.csv", "--plot", "fade.xyz"]),
    ("fade-plot-no-suffix", ["phm", "fade", "cycles.csv", "--plot", "fade"]),
    ("fade-plot-exists", ["phm", "fade", "cycles.csv", "--plot", "existing.png"]),
    ("fade-model", ["phm", "fade", "cycles.csv", "--model", "cubic"]),
    ("levels-capacity", ["phm", "levels", "discharge.csv", "--capacity-ah", "0"]),
    ("levels-soc-step", ["phm", "levels", "discharge.csv", "--soc-step", "0.5"]),
    ("forecast-time-property", ["phm", "forecast", CASE1, "--cycles", "cycles.csv",
                                "--time-property", "nosuch"]),
    ("forecast-require", ["phm", "forecast", CASE1, "--cycles", "cycles.csv",
                          "--require", "p_success >> 0.9"]),
    # a probability's bound outside [0, 1]: "already fails now", exit 0
    ("forecast-require-bound", ["phm", "forecast", CASE1, "--cycles", "cycles.csv",
                                "--require", "p_success >= 2"]),
    ("forecast-plot-type", ["phm", "forecast", CASE1, "--cycles", "cycles.csv",
                            "--plot", "f.xyz"]),
    ("simulate-power", ["phm", "simulate", "--power-w", "-3"]),
    ("recheck-missing", ["recheck", CASE1, "--cycles", "nosuch.csv"]),
    # options in general
    ("unknown-option", ["check", CASE1, "--nosuch"]),
    ("unknown-command", ["chek", CASE1]),
    ("check-format", ["check", CASE1, "--format", "yaml"]),
    ("check-emit-exists", ["check", CASE1, *SMALL, "--emit", "existing.csv"]),
    # an empty path (an unset shell variable): click would read it as "." and write there
    ("check-emit-empty", ["check", CASE1, *SMALL, "--emit", ""]),
    ("emit-output-empty", ["emit", CASE1, *SMALL, "-o", ""]),
    ("check-config-empty", ["check", ""]),
    ("prism-props-empty", ["prism", "die.pm", "--props", " "]),
    # a folder no file can be made in (/proc, even for root): refused before any work
    ("explain-output-proc", ["explain", CASE1, *SMALL, "-o", "/proc/x.csv"]),
    ("simulate-output-proc", ["simulate", CASE1, *SMALL, "--runs", "5", "-o", "/proc/x.csv"]),
    ("distribution-output-proc", ["distribution", CASE1, *SMALL, "-o", "/proc/x.csv"]),
    ("report-output-proc", ["report", CASE1, *SMALL, "-o", "/proc/r.html"]),
    ("emit-output-proc", ["emit", CASE1, *SMALL, "-o", "/proc/out"]),
    ("sweep-output-proc", ["sweep", CASE1, *SMALL, "--vary", "battery.capacity_ah=10,11",
                           "-o", "/proc/r.csv"]),
    ("sweep-plot-proc", ["sweep", CASE1, *SMALL, "--vary", "battery.capacity_ah=10,11",
                         "--plot", "/proc/p.png"]),
]


@pytest.fixture()
def workdir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    for name, content in FILES.items():
        (tmp_path / name).write_bytes(content)
    (tmp_path / "a_folder.csv").mkdir()
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _snapshot(folder: Path) -> dict[str, bytes | None]:
    return {str(p.relative_to(folder)): (p.read_bytes() if p.is_file() else None)
            for p in sorted(folder.rglob("*"))}


@pytest.mark.parametrize("args", [c[1] for c in CASES], ids=[c[0] for c in CASES])
def test_bad_input_is_one_line_exit_2_nothing_written(workdir: Path, args: list[str]) -> None:
    before = _snapshot(workdir)
    result = CliRunner().invoke(cli, args)
    assert result.exit_code == 2, (result.stdout, result.stderr, result.exception)
    assert result.stdout == ""
    lines = result.stderr.splitlines()
    problems = [line for line in lines if line.startswith(("error:", "Error:"))]
    assert len(problems) == 1, result.stderr
    assert "Traceback" not in result.stderr
    assert _snapshot(workdir) == before
    assert not [name for name in os.listdir(workdir) if name.startswith(".")]


@pytest.mark.parametrize("args", [c[1] for c in CASES if c[0].endswith("-proc")],
                         ids=[c[0] for c in CASES if c[0].endswith("-proc")])
def test_an_unwritable_folder_is_named_with_its_option_before_any_work(
        workdir: Path, args: list[str]) -> None:
    """``os.access`` says yes to root in /proc: the folder is tried instead, so the refusal
    comes first and names the option, not a hidden temporary file after the work."""
    result = CliRunner().invoke(cli, args)
    assert result.exit_code == 2, result.output
    option = args[args.index(next(a for a in args if a.startswith("/proc/"))) - 1]
    assert result.stderr.startswith(f"error: {option} "), result.stderr
    assert ".tmp" not in result.stderr and "checking" not in result.stderr


@pytest.mark.parametrize("args", [
    ["check", CASE1, "--set", "farm.name=" + "x" * 100_000],  # the library's error
    ["sweep", CASE1, "--jobs", "x" * 5_000],  # click's usage error
], ids=["library", "usage"])
def test_a_huge_value_in_an_error_is_cut_in_the_middle(args: list[str]) -> None:
    """One line still, with where and what at its ends, not 100,000 characters of it."""
    result = CliRunner().invoke(cli, args)
    assert result.exit_code == 2
    (line,) = result.stderr.strip().splitlines()
    assert line.startswith("error: ") and len(line) < 1_100
    assert " characters) … " in line


@pytest.mark.parametrize(("name", "says"), [
    ("prism-index-negative", "there is no property -1 in die.props (it has 1 properties)"),
    ("prism-duplicate-name", 'dup_names.props:3:1: duplicate name "a": a property here and '
                             "a property at dup_names.props:1:1"),
    ("prism-export-same-path", "--export-strategy x.json is --export-induced's folder"),
    ("prism-export-conditional", "no strategy: conditional probabilities"),
    ("prism-explain-mdp", "this is an MDP, but this builds a DTMC and needs a 'dtmc' model: "
                          "check an MDP's properties with veribattery.check_prism_file (from "
                          "Python) or 'veribattery prism' without --explain or --simulate"),
    ("prism-explain-and-simulate", "--explain and --simulate are separate runs"),
    ("prism-top-alone", "--top is read by --explain only"),
    ("prism-seed-alone", "--seed is read by --simulate only"),
    ("sweep-scheduler-port", "--scheduler tcp://host:abc: the port must be a number "
                             "(1-65535), not 'abc'; give tcp://HOST:PORT"),
    ("sweep-scheduler-no-port", "--scheduler tcp://host:: no port after host:"),
    ("reproduce-scheduler-port", "--scheduler tcp://host:70000: the port must be a number "
                                 "(1-65535), not '70000'"),
    ("simulate-path-count-alone", "--path-count is read by -o only: give -o, or leave out "
                                  "--path-count"),
    ("prism-path-count-without-output", "--path-count is read by -o only"),
    ("check-force-alone", "--force lets --emit overwrite its files"),
    ("prism-init-none", "no_init.pm:7:6: the init block is satisfied by no state"),
    ("prism-nul-byte", r"unexpected character '\x00'"),
    ("distribution-coverage-nan", "--coverage must be in (0, 1], got nan"),
    ("distribution-unknown-reward", "--reward nosuch: the mission has no reward structure"),
    ("explain-strategy-folder", "a strategy file; a folder 'a_folder.csv'"),
    ("emit-dash", "-o -: writes a folder of files, not to standard output"),
    ("check-endless-input", "config '/dev/zero': more than 16 MB"),
    ("config-reserved-property", "reserved_property.yaml:2:3: properties.recharge_cap_"
                                 "probability: property name 'recharge_cap_probability' is "
                                 "reserved: check reports P[F rc=RC_MAX] under it; choose "
                                 "another name"),
    ("explain-strategy-devnull", "--strategy must be bs1, optimal or a strategy file; not a "
                                 "regular file '/dev/null'"),
    ("explain-csv-suffix", "--csv p.txt: unsupported file type '.txt'; name a file ending in "
                           ".csv"),
    ("reproduce-no-target", "Missing argument '{table3|fig6|fig8|all}'. Choose from: table3, "
                            "fig6, fig8, all (see '"),
    ("check-max-states-word", "'lots' is not a valid integer (see"),
    ("distribution-long-day", "--working-day 25h: a working day is at most 24h (1440 minutes)"),
    ("distribution-day-unread", "--working-day 8h is read by a --deadline in working days only "
                                "(e.g. --deadline 10d): give one, or leave out --working-day"),
    ("distribution-fractional-time", "--reward mt: the distribution counts whole units of "
                                     "'mt', but it is 0.5 in state ("),
    ("set-reserved-property", "--set properties.recharge_cap_probability: property name "
                              "'recharge_cap_probability' is reserved"),
    ("sweep-plot-property-alone", "--plot-property chooses what --plot draws"),
    ("explain-by", "--by nosuch: no key 'nosuch'; give keys comma-separated, a+b to group by "
                   "both (keys: k, cell, state, action, wind, level, recharges, s, j, wsp, b, rc)"),
    ("explain-by-empty", "--by '': an empty grouping; give keys comma-separated"),
    ("explain-by-empty-key", "--by wind,+cell: an empty key in '+cell'"),
    ("explain-by-twice", "--by cell: the grouping cell is asked for twice"),
    ("explain-by-key-twice", "--by cell+cell: cell twice in cell+cell"),
    ("explain-output-and-csv", "-o a.csv and --csv b.csv: 2 values for one option (--csv is "
                               "another name of -o); give it once"),
    ("explain-output-twice", "-o a.csv and -o b.csv: 2 values for one option; give it once"),
    ("simulate-output-and-paths", "-o b.csv and --paths a.csv: 2 values for one option (--paths "
                                  "is another name of -o)"),
])
def test_the_line_says_what_is_wrong(workdir: Path, name: str, says: str) -> None:
    [args] = [c[1] for c in CASES if c[0] == name]
    result = CliRunner().invoke(cli, args)
    assert result.exit_code == 2 and says in result.stderr, result.stderr
