"""Farms of real size (issue 25): 20x20 and 40x40 turbines through ``emit`` and
``prism``, and the builder's memory guard for state spaces too large for the machine.

A 20x20 farm (361 cells on the route) and a 40x40 one (1,521) give per-cell
formulas of hundreds of values: the templates halve them on ``k`` into short chains
(log2-deep), and the language and the explorer take any depth. The 20x20 counts
below were computed once and checked against Storm (the test re-checks them when
stormpy is installed): with the paper's 11 Ah battery, the cells far from the base
are beyond a full charge, so the mission fails there and the state space stops
growing (P(success) = 0).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from click.testing import CliRunner, Result

from tests.lang.helpers import expression_depth
from veribattery.cli import cli
from veribattery.config import load_config
from veribattery.errors import ModelTooLarge
from veribattery.explore.build import guard
from veribattery.explore.build.builder import build_dtmc, explore, memory_footprint
from veribattery.explore.build.guard import MemoryGuard, available_memory
from veribattery.explore.compile.program import compile_program
from veribattery.lang import FlatModel, flatten_model, parse_model, parse_properties
from veribattery.lang.evaluate import evaluate
from veribattery.render import render_model

CASE1 = Path(__file__).resolve().parents[1] / "configs" / "paper" / "case1.yaml"
#: The 20x20 farm of case 1: states, transitions (Storm agrees), P(success), E[minutes].
FARM_20 = (45_611, 89_246, 0.0, 1525.89904908)
#: One line of the route table in the model's header: k, cell, n, dist[, step].
_ROUTE_LINE = re.compile(r"^//\s+(\d+)\s+\[\d+,\d+\]\s+(\d+)\s+(\d+)(?:\s+(\d+))?\s*$")


def run(*args: str) -> Result:
    return CliRunner().invoke(cli, list(args))


def _farm(size: int) -> tuple[str, ...]:
    return ("--set", f"farm.cols={size}", "--set", f"farm.rows={size}")


def _emit(tmp_path: Path, size: int) -> Path:
    out = tmp_path / f"farm{size}"
    result = run("emit", str(CASE1), *_farm(size), "-o", str(out))
    assert result.exit_code == 0, result.output
    return out



def test_emit_of_a_40x40_farm_parses_with_the_route_values(tmp_path: Path) -> None:
    """The emitted model parses and flattens in our front end, its per-cell formulas
    give the route table's value at every k (the table is in the header), and they
    nest shallowly enough for PRISM's and Storm's parsers."""
    out = _emit(tmp_path, 40)
    text = (out / "model.prism").read_text()
    model = parse_model(text)
    flatten_model(model)
    parse_properties(out / "properties.props")
    route = [_ROUTE_LINE.match(line) for line in text.splitlines()]
    rows = [tuple(int(g) if g else None for g in m.groups()) for m in route if m]
    assert len(rows) == 1521 and [r[0] for r in rows] == list(range(1521))
    formulas = {f.name: f.expr for f in model.formulas}
    for column, name in ((1, "n"), (2, "dist"), (3, "step")):
        values = [evaluate(formulas[name], {"k": k}) for k, *_ in rows]
        expected = [r[column] for r in rows]
        if name == "step":  # none after the last cell
            values, expected = values[:-1], expected[:-1]
        assert values == expected, name
        # chains of 32 under log2(1521) halvings
        assert expression_depth(formulas[name]) < 3 * (32 + 11)


def test_a_20x20_farm_end_to_end_through_emit_and_prism(tmp_path: Path) -> None:
    out = _emit(tmp_path, 20)
    result = run("prism", str(out / "model.prism"), "--props", str(out / "properties.props"),
                 "--json")
    assert result.exit_code == 0, result.output
    doc = json.loads(result.stdout)
    states, transitions, p_success, minutes = FARM_20
    assert (doc["model"]["states"], doc["model"]["transitions"]) == (states, transitions)
    values = {r["name"]: r["value"] for r in doc["results"]}
    assert values["p_success"] == p_success
    assert values["exp_mission_time"] == pytest.approx(minutes, rel=1e-9)


def test_the_20x20_farm_agrees_with_storm(tmp_path: Path) -> None:
    try:
        import stormpy
    except ImportError:
        pytest.skip("stormpy is not installed: the 20x20 counts are not re-checked with Storm")
    out = _emit(tmp_path, 20)
    program = stormpy.parse_prism_program(str(out / "model.prism"))
    # Two formulas or more: with one, Storm makes the states that decide it absorbing.
    props = stormpy.parse_properties(
        'P=? [ F "success" ]; R{"mt"}=? [ F "done" ]; P=? [ F "deadlock" ]', program)
    model = stormpy.build_model(program, props)
    states, transitions, p_success, minutes = FARM_20
    assert (model.nr_states, model.nr_transitions) == (states, transitions)
    initial = model.initial_states[0]
    answers = [stormpy.model_checking(model, p).get_value_vector()[initial] for p in props[:2]]
    assert answers[0] == pytest.approx(p_success, abs=1e-12)
    assert answers[1] == pytest.approx(minutes, rel=1e-6)


# ---------------------------------------------------------------------------
# The memory guard
# ---------------------------------------------------------------------------

#: A battery large enough that the whole 20x20 route is feasible: 11.5 million
#: states, 2.3 GB to build (what the guard stops below).
BIG = ("--set", "battery.capacity_ah=60")


def _big_model() -> FlatModel:
    cfg = load_config(CASE1, ["farm.cols=20", "farm.rows=20", "battery.capacity_ah=60"])
    return flatten_model(parse_model(render_model(cfg)))


def test_the_guard_stops_a_search_that_outgrows_memory() -> None:
    flat = _big_model()
    program = compile_program(flat)
    asked: list[int] = []

    def small() -> int:
        asked.append(1)
        return 200 << 20  # as if the machine had 200 MB to spare

    layers: list[int] = []
    with pytest.raises(ModelTooLarge) as err:
        explore(flat, program, lambda states, _: layers.append(states),
                MemoryGuard(memory_footprint(program), small))
    message = str(err.value)
    found = re.search(r"([\d,]+) states and", message)
    assert found is not None and int(found.group(1).replace(",", "")) == layers[-1], message
    assert 200_000 < layers[-1] < 2_000_000, message
    assert "\n" not in message and "GB more" in message and "0.2 GB available" in message
    # read only once what the search adds comes near it, not on every layer
    assert 0 < len(asked) < len(layers) / 2


def test_check_says_a_model_is_too_large_before_it_runs_out(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(guard, "available_memory", lambda: 200 << 20)
    result = run("check", str(CASE1), *_farm(20), *BIG)
    assert result.exit_code != 0
    assert "model too large for the memory available" in result.output
    assert "Traceback" not in result.output


def test_a_model_that_fits_never_reads_the_memory_available() -> None:
    """Below 64 MB to add, the guard costs a few arithmetic operations per layer."""
    flat = flatten_model(parse_model(render_model(load_config(CASE1, []))))
    program = compile_program(flat)

    def unexpected() -> int:
        raise AssertionError("the memory available was read for a small model")

    states, _, _ = explore(flat, program, guard=MemoryGuard(memory_footprint(program), unexpected))
    assert states.shape[0] == 176_481


def test_progress_is_reported_per_layer_as_the_search_grows() -> None:
    flat = flatten_model(parse_model(render_model(load_config(CASE1, []))))
    seen: list[tuple[int, int]] = []
    dtmc = build_dtmc(flat, progress=lambda states, frontier: seen.append((states, frontier)))
    found = [s for s, _ in seen]
    assert len(seen) > 100 and found == sorted(found) and found[-1] == dtmc.num_states
    assert all(frontier > 0 for _, frontier in seen)


def test_the_memory_available_is_known_here() -> None:
    available = available_memory()
    assert available is not None and available > 0
