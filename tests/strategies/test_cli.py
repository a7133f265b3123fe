"""``prism --export-strategy FILE``, ``--export-induced DIR``, ``--strategy-property``:
what is written, in which format, and the refusals (exit 2, one line, no file)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner, Result

from tests.strategies.models import ROBOT
from veribattery.cli import cli

PROPS = """"reach": Pmax=? [ F "goal" ];
Pmin=? [ F "goal" ];
"fast": Pmax=? [ F<=2 "goal" ];
"cost": R{"steps"}min=? [ F "goal" ];
"""
DTMC = "dtmc\nmodule m\n  s : [0..1] init 0;\n  [] s=0 -> (s'=1);\n  [] s=1 -> true;\nendmodule\n"


@pytest.fixture
def files(tmp_path: Path) -> tuple[Path, Path]:
    model, props = tmp_path / "robot.nm", tmp_path / "robot.props"
    model.write_text(ROBOT, encoding="utf-8")
    props.write_text(PROPS, encoding="utf-8")
    return model, props


def _prism(*args: object) -> Result:
    return CliRunner().invoke(cli, ["prism", *map(str, args)])


def _refused(result: Result) -> str:
    """The one error line of a refusal (exit 2, nothing on stdout)."""
    assert result.exit_code == 2, (result.stdout, result.stderr)
    assert result.stdout == ""
    errors = [line for line in result.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1, result.stderr
    return errors[0]


def test_prism_format_lists_each_reached_state_and_its_action(files: tuple[Path, Path],
                                                              tmp_path: Path) -> None:
    model, props = files
    out = tmp_path / "strat.txt"
    result = _prism(model, "--props", props, "--export-strategy", out)
    assert result.exit_code == 0, result.stderr
    assert f"wrote {out}" in result.stderr
    # Pmax of reaching x=3 goes east everywhere (risky may break down).
    assert out.read_text(encoding="utf-8") == (
        "(0,false)=east\n(1,false)=east\n(3,false)=stay\n(2,false)=east\n")


def test_by_name_the_minimum_takes_the_risk(files: tuple[Path, Path], tmp_path: Path) -> None:
    """Pmin (property 2): risky from x=0, which breaks down half the time; the broken
    state (x=0, done) has no command in the MDP: an unlabelled self-loop."""
    model, props = files
    out = tmp_path / "strat.txt"
    assert _prism(model, "--props", props, "--export-strategy", out,
                  "--strategy-property", "2").exit_code == 0
    assert out.read_text(encoding="utf-8") == "(0,false)=risky\n(3,false)=stay\n(0,true)=\n"


def test_storm_json_has_storms_scheduler_shape(files: tuple[Path, Path], tmp_path: Path) -> None:
    model, props = files
    out = tmp_path / "sched.json"
    assert _prism(model, "--props", props, "--export-strategy", out,
                  "--strategy-property", "cost").exit_code == 0
    entries = json.loads(out.read_text(encoding="utf-8"))
    assert entries[0] == {"s": {"x": 0, "done": False},
                          "c": [{"labels": ["east"], "index": 0, "prob": 1.0}]}
    assert [e["s"]["x"] for e in entries] == [0, 1, 3, 2]


def test_induced_folder_is_checked_by_veribattery(files: tuple[Path, Path],
                                                  tmp_path: Path) -> None:
    model, props = files
    folder = tmp_path / "new" / "induced"
    assert _prism(model, "--props", props, "--export-induced", folder,
                  "--strategy-property", "cost").exit_code == 0
    result = _prism(folder / "induced.prism", "--props", folder / "induced.props", "--json")
    assert result.exit_code == 0, result.stderr
    (entry,) = json.loads(result.stdout)["results"]
    assert entry["name"] == "cost"
    assert entry["property"] == 'R{"steps"}=? [ F "goal" ]'
    assert entry["value"] == pytest.approx(3.75, rel=1e-12)  # 3 cells, 1.25 steps each


def test_simulating_the_induced_dtmc_estimates_the_optimum(files: tuple[Path, Path],
                                                           tmp_path: Path) -> None:
    model, props = files
    folder = tmp_path / "induced"
    assert _prism(model, "--props", props, "--export-induced", folder).exit_code == 0
    result = _prism(folder / "induced.prism", "--props", folder / "induced.props",
                    "--simulate", 200, "--json")
    assert result.exit_code == 0, result.stderr
    reach = json.loads(result.stdout)["results"]["reach"]
    assert reach["value"] == 1.0  # Pmax: east never breaks down
    assert reach["estimate"] == 1.0 and reach["undecided"] == 0


def test_default_skips_properties_without_a_strategy(files: tuple[Path, Path],
                                                     tmp_path: Path) -> None:
    model, props = files
    out = tmp_path / "strat.txt"
    assert _prism(model, "--props", props, "--property", "fast", "--property", "reach",
                  "--export-strategy", out).exit_code == 0
    assert out.read_text(encoding="utf-8").startswith("(0,false)=east\n")


def test_step_bounded_property_is_refused_where_it_is_written(files: tuple[Path, Path],
                                                              tmp_path: Path) -> None:
    model, props = files
    line = _refused(_prism(model, "--props", props, "--export-strategy", tmp_path / "s.txt",
                           "--export-induced", tmp_path / "ind", "--strategy-property",
                           "fast"))
    assert line.startswith(f"error: {props}:3:1: Pmax=? [ F<=2 \"goal\" ]: ")
    assert "step-bounded" in line
    assert not (tmp_path / "s.txt").exists() and not (tmp_path / "ind").exists()


def test_no_property_with_a_strategy_names_the_first(files: tuple[Path, Path],
                                                     tmp_path: Path) -> None:
    model, _ = files
    line = _refused(_prism(model, "--property", 'Pmax=? [ F<=2 "goal" ] + 1',
                           "--export-strategy", tmp_path / "s.txt"))
    assert "no P or R operator at its top" in line
    assert not (tmp_path / "s.txt").exists()


def test_a_multi_objective_query_exports_its_randomised_strategy(
        files: tuple[Path, Path], tmp_path: Path) -> None:
    """Pmax [F goal] subject to P>=0.5 [F goal]: east everywhere, as for Pmax alone;
    the memory adds one visited bit per reachability objective (multi_export tests)."""
    model, _ = files
    out = tmp_path / "s.txt"
    result = _prism(model, "--property", 'multi(Pmax=? [ F "goal" ], P>=0.5 [ F "goal" ])',
                    "--export-strategy", out)
    assert result.exit_code == 0, result.stderr
    assert out.read_text(encoding="utf-8").startswith("(0,false,false,false)=1.0:east\n")


def test_existing_files_need_force(files: tuple[Path, Path], tmp_path: Path) -> None:
    model, props = files
    out = tmp_path / "strat.txt"
    out.write_text("mine\n", encoding="utf-8")
    assert "already exists" in _refused(_prism(model, "--props", props,
                                               "--export-strategy", out))
    assert out.read_text(encoding="utf-8") == "mine\n"
    folder = tmp_path / "ind"
    folder.mkdir()
    (folder / "induced.props").write_text("mine\n", encoding="utf-8")
    assert "induced.props already exist" in _refused(
        _prism(model, "--props", props, "--export-induced", folder))
    assert _prism(model, "--props", props, "--export-strategy", out, "--export-induced",
                  folder, "--force").exit_code == 0
    assert out.read_text(encoding="utf-8").startswith("(0,false)=east")
    assert "P=? [ F \"goal\" ]" in (folder / "induced.props").read_text(encoding="utf-8")


@pytest.mark.parametrize(("selector", "message"), [
    ("7", "--strategy-property 7: there are 4 checked properties"),
    ("nope", '--strategy-property nope: no checked property has that name (names: "reach", '
             '"fast", "cost")'),
])
def test_unknown_property_is_refused(files: tuple[Path, Path], tmp_path: Path,
                                     selector: str, message: str) -> None:
    model, props = files
    line = _refused(_prism(model, "--props", props, "--export-strategy", tmp_path / "s.txt",
                           "--strategy-property", selector))
    assert message in line
    assert not (tmp_path / "s.txt").exists()


def test_a_dtmc_has_no_strategy(tmp_path: Path) -> None:
    model = tmp_path / "chain.pm"
    model.write_text(DTMC, encoding="utf-8")
    line = _refused(_prism(model, "--property", "P=? [ F s=1 ]", "--export-strategy",
                           tmp_path / "s.txt"))
    assert "only an MDP has strategies" in line
    assert not (tmp_path / "s.txt").exists()


@pytest.mark.parametrize(("extra", "message"), [
    (("--strategy-property", "1"), "--strategy-property: give --export-strategy FILE"),
    (("--export-strategy", "s.txt", "--simulate", "10"), "--simulate does not check"),
    # (it was 'the run did not keep its model', after the whole exact check)
    (("--export-strategy", "s.txt", "--exact"), "are not available with --exact"),
    (("--export-induced", "ind", "--exact"), "are not available with --exact"),
])
def test_options_that_would_be_ignored_are_refused(files: tuple[Path, Path],
                                                   extra: tuple[str, ...], message: str) -> None:
    model, props = files
    assert message in _refused(_prism(model, "--props", props, *extra))


def test_explaining_the_induced_dtmc_shows_the_strategys_actions(files: tuple[Path, Path],
                                                                 tmp_path: Path) -> None:
    """Pmin reaches the goal only by a lucky risky jump from x=0: one path, 0.5."""
    model, props = files
    folder = tmp_path / "induced"
    assert _prism(model, "--props", props, "--export-induced", folder,
                  "--strategy-property", "2").exit_code == 0
    result = _prism(folder / "induced.prism", "--explain", "goal", "--json")
    assert result.exit_code == 0, result.stderr
    explained = json.loads(result.stdout)
    assert explained["p_goal"] == 0.5
    (path,) = explained["paths"]
    assert path["probability"] == 0.5
    assert [step["action"] for step in path["states"]] == ["risky", ""]


@pytest.fixture
def no_build(monkeypatch: pytest.MonkeyPatch) -> None:
    """Any model build fails the test: a refusal must come before the work starts."""
    def refuse(*_: object, **__: object) -> None:
        raise AssertionError("the model was built")

    import veribattery.pipeline.mdp as mdp_pipeline
    import veribattery.pipeline.session as dtmc_pipeline

    monkeypatch.setattr(mdp_pipeline, "build_mdp", refuse)
    monkeypatch.setattr(dtmc_pipeline.Session, "_build", refuse)


@pytest.mark.usefixtures("no_build")
@pytest.mark.parametrize(("args", "says"), [
    (("--strategy-property", "fast"), "step-bounded"),
    (("--property", 'Pmax=? [ F<=2 "goal" ] + 1'), "no P or R operator at its top"),
    (("--property", 'multi(R{"steps"}min=? [ C<=3 ], P>=0.5 [ F "goal" ])'),
     "a C<=k objective in multi(...)"),
    (("--property", "fast", "--property", 'R{"steps"}max=? [ I=2 ]'), "step-bounded"),
])
def test_a_hopeless_export_is_refused_before_the_build(files: tuple[Path, Path], tmp_path: Path,
                                                       args: tuple[str, ...], says: str) -> None:
    model, props = files
    line = _refused(_prism(model, "--props", props, *args,
                           "--export-strategy", tmp_path / "s.txt"))
    assert says in line
    assert not (tmp_path / "s.txt").exists()


@pytest.mark.usefixtures("no_build")
def test_a_dtmc_export_is_refused_before_the_build(tmp_path: Path) -> None:
    model = tmp_path / "chain.pm"
    model.write_text(DTMC, encoding="utf-8")
    assert "only an MDP has strategies" in _refused(
        _prism(model, "--property", "P=? [ F s=1 ]", "--export-induced", tmp_path / "ind"))


def test_a_reference_to_a_property_is_judged_once_resolved(files: tuple[Path, Path],
                                                          tmp_path: Path) -> None:
    model, props = files
    props.write_text(PROPS + '"again": "reach";\n', encoding="utf-8")
    out = tmp_path / "s.txt"
    result = _prism(model, "--props", props, "--strategy-property", "again",
                    "--export-strategy", out)
    assert result.exit_code == 0, result.stderr
    assert out.read_text(encoding="utf-8").startswith("(0,false)=east\n")


def test_a_check_builds_only_the_rewards_it_reads_an_export_every_one(
        files: tuple[Path, Path], tmp_path: Path) -> None:
    """``R{"steps"}``: "time" is not built for the check (memory, time), but the induced
    DTMC of a ``multi`` strategy, written from the built MDP, keeps both structures."""
    from veribattery.pipeline import check_prism_file

    model, _ = files
    prop = 'R{"steps"}min=? [ F "goal" ]'
    named = check_prism_file(model, props_source=prop, rewards="named")
    every = check_prism_file(model, props_source=prop, rewards="all")
    assert [r.name for r in named.mdp.rewards] == ["steps"]  # type: ignore[union-attr]
    assert [r.name for r in every.mdp.rewards] == ["steps", "time"]  # type: ignore[union-attr]
    assert named.results[0].value == every.results[0].value == pytest.approx(3.75, rel=1e-12)
    folder = tmp_path / "induced"
    multi = 'multi(R{"steps"}<=5 [ C ], P>=0.5 [ F "goal" ])'
    assert _prism(model, "--property", multi, "--export-induced", folder).exit_code == 0
    written = (folder / "induced.prism").read_text(encoding="utf-8")
    assert 'rewards "steps"' in written and 'rewards "time"' in written
