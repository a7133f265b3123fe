"""Storm (stormpy) as a reference checker for the differential tests.

:func:`run_storm` builds a PRISM model with Storm, in exact (rational) arithmetic
or in floating point, checks properties in *every* reachable state and returns
the values together with each state's variable valuation, so that results can be
compared with veribattery's state by state (the two tools number states
differently). :func:`compare` does that comparison.

Import this module only after ``pytest.importorskip("stormpy")``.
"""

from __future__ import annotations

import json
import math
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np
import stormpy

from veribattery.pipeline import ModelCheckRun

Value = float | bool


@dataclass(frozen=True, slots=True)
class StormRun:
    """Storm's model sizes and per-state results.

    :param valuations: per Storm state, variable name to value (bools as 0/1).
    :param values: per property, per Storm state.
    :param exact: whether the model was built and checked with rationals.
    """

    states: int
    transitions: int
    initial: tuple[int, ...]
    valuations: tuple[dict[str, int], ...]
    values: tuple[tuple[Value, ...], ...]
    exact: bool


def storm_number(value: Any) -> Value:
    """A Storm number (float, gmp Rational, "inf") as a Python float or bool."""
    if isinstance(value, bool):
        return value
    if isinstance(value, int | float):
        return float(value)
    text = str(value).strip().lower()
    if text in ("inf", "infinity", "+inf"):
        return math.inf
    if text in ("-inf", "-infinity"):
        return -math.inf
    return float(Fraction(text))


def run_storm(
    model: Path | str,
    properties: str,
    constants: Mapping[str, str] | None = None,
    *,
    exact: bool = True,
) -> StormRun:
    """Build *model* (a file, or PRISM text) with Storm and check *properties* in every state.

    :param properties: Storm property text: ``const`` declarations and formulas,
        separated by ``;``.
    :param constants: values of undefined constants (model or properties).
    :param exact: rational arithmetic (else Storm's default floating point).
    """
    if isinstance(model, str):
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "model.prism"
            path.write_text(model, encoding="utf-8")
            return run_storm(path, properties, constants, exact=exact)
    program = stormpy.parse_prism_program(str(model))
    props = stormpy.parse_properties(properties, program)
    if constants:
        definitions = ",".join(f"{k}={v}" for k, v in constants.items())
        program, props = stormpy.instantiate_constants(program, definitions, props)
    # With a single formula Storm makes the states that decide it absorbing
    # ("terminal states"), which changes the model; a second formula prevents that.
    unused = stormpy.parse_properties('P=? [ F "deadlock" ]', program)
    options = stormpy.BuilderOptions([*props, *unused])
    options.set_build_state_valuations()
    value_type = stormpy.Rational if exact else float
    built = stormpy.build_model[value_type](program, options=options)
    valuations = tuple(
        {k: int(v) for k, v in (json.loads(str(built.state_valuations.to_json(s))) or {}).items()}
        for s in range(built.nr_states)
    )
    values = []
    for prop in props:
        result = stormpy.model_checking(built, prop)
        if result.is_qualitative():
            truth = result.get_truth_values_vector()
            values.append(tuple(bool(truth[s]) for s in range(built.nr_states)))
        else:
            values.append(tuple(storm_number(v) for v in result.get_value_vector()))
    return StormRun(
        states=built.nr_states,
        transitions=built.nr_transitions,
        initial=tuple(int(s) for s in built.initial_states),
        valuations=valuations,
        values=tuple(values),
        exact=exact,
    )


def storm_initial_values(text: str, props: list[str], folder: Path) -> list[float]:
    """Storm's exact value of each of *props* at the first initial state of the PRISM
    model *text* (written into *folder*), built for those properties; only there, as
    Storm computes reward-bounded MDP objectives for the initial states only."""
    path = folder / "model.prism"
    path.write_text(text, encoding="utf-8")
    program = stormpy.parse_prism_program(str(path))
    parsed = stormpy.parse_properties(";".join(props), program)
    model = stormpy.build_model[stormpy.Rational](program, parsed)
    init = model.initial_states[0]
    return [float(storm_number(stormpy.model_checking(model, p, only_initial_states=True)
                               .get_value_vector()[init])) for p in parsed]


def run_storm_exact_or_float(
    model: Path | str, properties: str, constants: Mapping[str, str] | None = None
) -> StormRun:
    """:func:`run_storm` in exact mode, or in floating point if exact mode fails."""
    try:
        return run_storm(model, properties, constants, exact=True)
    except Exception:  # Storm's exact engine lacks some functions and solvers
        return run_storm(model, properties, constants, exact=False)


def close(a: Value, b: Value, rtol: float, atol: float) -> bool:
    """Equal booleans, equal infinities, or numbers within *rtol* relative / *atol* absolute."""
    if isinstance(a, bool) or isinstance(b, bool):
        return isinstance(a, bool) and isinstance(b, bool) and a == b
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    if math.isinf(a) or math.isinf(b):
        return a == b
    return abs(a - b) <= max(rtol * max(abs(a), abs(b)), atol)


def compare(
    run: ModelCheckRun,
    storm: StormRun,
    labels: Sequence[str],
    *,
    rtol: float,
    atol: float,
    max_states: int = 3,
) -> list[str]:
    """Disagreements between veribattery's *run* and *storm* (empty if none).

    Compares the number of states, transitions and initial states, the set of
    reachable valuations, and for every property (``run.results[i]`` against
    ``storm.values[i]``, named ``labels[i]``) its value in every reachable state
    and the reported value at the initial states (for numbers, Storm's value at
    veribattery's first initial state; for booleans, "holds in all initial states").
    """
    dtmc = run.dtmc
    problems: list[str] = []
    sizes = (dtmc.num_states, dtmc.num_transitions, len(dtmc.initial))
    storm_sizes = (storm.states, storm.transitions, len(storm.initial))
    if sizes != storm_sizes:
        problems.append(f"(states, transitions, initial): veribattery {sizes}, Storm {storm_sizes}")
    # Storm leaves variables that are never assigned out of its valuations
    # (they keep their initial value): match states on the variables both know.
    known = set(storm.valuations[0]) if storm.valuations else set()
    columns = [i for i, n in enumerate(dtmc.variable_names) if n in known]
    names = tuple(dtmc.variable_names[i] for i in columns)
    index = {tuple(v[n] for n in names): s for s, v in enumerate(storm.valuations)}
    rows = [tuple(int(row[i]) for i in columns) for row in np.asarray(dtmc.states)]
    if len(set(rows)) != len(rows):
        problems.append(f"veribattery states repeat on the variables Storm keeps, {names}")
        return problems
    mapping = [index.get(row) for row in rows]
    missing = [dict(zip(names, row, strict=True)) for row, s in zip(rows, mapping, strict=True)
               if s is None]
    if missing:
        problems.append(f"{len(missing)} states unknown to Storm, e.g. {missing[:max_states]}")
        return problems
    if {mapping[i] for i in dtmc.initial} != set(storm.initial):
        problems.append("initial states differ")
    for label, result, storm_values in zip(labels, run.results, storm.values, strict=True):
        bad = [
            (dict(zip(names, rows[i], strict=True)), _plain(result.values[i]), storm_values[s])
            for i, s in enumerate(mapping)
            if not close(_plain(result.values[i]), storm_values[s], rtol, atol)
        ]
        if bad:
            shown = "; ".join(f"{v}: veribattery {a!r} Storm {b!r}" for v, a, b in bad[:max_states])
            problems.append(f"{label}: {len(bad)} states differ: {shown}")
        if isinstance(result.value, bool):
            expected: Value = all(bool(storm_values[mapping[i]]) for i in dtmc.initial)
        else:
            # PRISM's default filter: the range over the initial states (value = its low end).
            expected = min(float(storm_values[mapping[int(i)]]) for i in dtmc.initial)
        if not close(result.value, expected, rtol, atol):
            problems.append(f"{label}: value veribattery {result.value!r} Storm {expected!r}")
    return problems


def _plain(value: Any) -> Value:
    """A numpy scalar as a Python bool or float."""
    if isinstance(value, bool | np.bool_):
        return bool(value)
    return float(value)
