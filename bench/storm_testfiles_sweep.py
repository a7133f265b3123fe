"""veribattery against Storm (through stormpy) on the PRISM-language test models of Storm.

A correctness sweep on public models that are not copied here: point ``--root`` at a
Storm repository, a checkout (the folder that holds ``resources/``) or a bare git
directory (read at its HEAD). Every ``.pm``, ``.nm`` and ``.prism`` file under
``resources/examples/testfiles/dtmc`` and ``.../mdp`` is written into a temporary
folder and, per model:

1. Storm builds it in a fresh process (``stormpy.build_model``, every label and reward
   model) and reports its states, choices, transitions and deadlocks; veribattery
   builds it with ``--all-states`` (every reachable state, as Storm's full build) and
   the counts are compared (the ``build`` row).
2. Properties are generated from the model alone (:func:`generated_properties`): for
   every label of the model, and ``"deadlock"`` where Storm finds deadlocks,
   ``F``, ``F<=10`` and ``G`` of it (``P=?`` for a DTMC, ``Pmax=?`` and ``Pmin=?`` for an
   MDP); for every reward structure ``F`` of the first label, ``C<=10`` and ``I=5``
   (``R=?``, ``Rmax=?``/``Rmin=?``). A properties file next to the model
   (``.props``, ``.prctl``, ``.csl`` with the same stem, or the only one in the
   folder with a model of that stem) adds its properties.
3. Storm checks every property in one process per model with a sound environment at
   relative precision 1e-10; veribattery checks each in a fresh process,

       python -m veribattery prism MODEL --property TEXT --const K=V ... --json

   with this tree's ``src`` first on ``PYTHONPATH``. Values at the initial states are
   compared: relative tolerance 1e-6 (absolute 1e-9 near 0), infinities equal, truth
   values exactly; several initial states compare as the range of their values.
   Where the two disagree both are asked again in exact arithmetic (Storm's
   ``build_model[Rational]`` with its exact environment, veribattery's ``--exact``)
   and the row says which was right.

Every process runs under a wall-clock timeout and ``ulimit -v`` (8 GB), one at a time.
A refusal by veribattery (exit 2, an ``error:`` line) is a row, not a failure; a
mismatch, a count that differs, a traceback or a timeout makes the exit status 1.
The Markdown report is rewritten after every row, so a stopped run keeps its rows.

    python bench/storm_testfiles_sweep.py --root /path/to/storm [--only die]
        [--timeout 300] [--out docs/_bench/storm_testfiles.md]

Models with undefined constants take the values Storm's own tests give them
(CONSTANTS); those whose tests only parse them are skipped (SKIPPED).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from datetime import UTC, datetime
from fractions import Fraction
from pathlib import Path

import sweeps
from sweeps import ROOT, GitFolder, Number, Process, agree, read_number

TESTFILES = "resources/examples/testfiles"
FOLDERS = ("dtmc", "mdp")
MODEL_SUFFIXES = (".pm", ".nm", ".prism")
PROPS_SUFFIXES = (".props", ".prctl", ".csl")
MEMORY_BYTES = 8 * 1024**3
#: Storm's sound solvers stop at this relative precision (its default is 1e-6).
STORM_PRECISION = "1/10000000000"

#: Values of undefined constants, each from Storm's own tests (src/test/storm/...).
CONSTANTS: dict[str, dict[str, str]] = {
    # SparseDtmcMultiDimensionalRewardUnfoldingTest.cpp
    "dtmc/crowds_cost_bounded.pm": {"CrowdSize": "4"},
    # The same model as mdp/coin2-2.nm, which defines K=2.
    "mdp/coin2.nm": {"K": "2"},
    # SparseMdpPcaaMultiObjectiveModelCheckerTest.cpp ("qualitative version")
    "mdp/multiobj_memory.prism": {"p": "0"},
    # SparseMdpPcaaMultiObjectiveModelCheckerTest.cpp
    "mdp/multiobj_stairs.nm": {"N": "3"},
    # MdpPrctlModelCheckerTest / one_dim_walk_small
    "mdp/one_dim_walk.nm": {"N": "10"},
    # QuantileQueryTest.cpp
    "mdp/quantiles_firewire.nm": {"delay": "36"},
    # Multi-objective reward unfolding tests
    "mdp/resource-gathering.nm": {"GOLD_TO_COLLECT": "0", "GEM_TO_COLLECT": "0", "B": "0"},
    "mdp/uav.prism": {"B": "500", "Unf": "1", "COUNTER": "0"},
    # ExplicitPrismModelBuilderTest.cpp (N=7 is its unbounded case)
    "mdp/unbounded.nm": {"N": "-7"},
    "mdp/zeroconf_dl_not_unfolded.nm": {"N": "1000", "K": "2", "reset": "true"},
}
#: Models left out, and why.
SKIPPED: dict[str, str] = {
    "mdp/firewire.nm": "undefined `delay` and `fast`: Storm's tests only parse this model",
    "mdp/wlan0_collide.nm": "undefined `COL` and `TRANS_TIME_MAX`: Storm's tests only "
                            "parse this model",
    "dtmc/non_graph_preserving.pm": "a parametric model: `p0` has no value",
}
#: A mismatch that goes away when Storm's deadlocks keep their state rewards (Storm's
#: builder gives the self-loop it adds to a deadlock state reward 0; PRISM keeps the
#: reward structure's value there): a difference of semantics, not a failure.
DEADLOCK_REWARD = "Storm: deadlock reward 0"
#: Outcomes that make the exit status 1.
FAILURES = ("NO", "error", "timeout")



# ---------------------------------------------------------------------------
# Properties, generated from the model alone


def generated_properties(kind: str, labels: list[str], rewards: list[str]) -> list[str]:
    """The generic properties of a model of *kind* (``dtmc``/``mdp``) with these labels
    and reward structures (``""``: the unnamed one)."""
    ops = ("P=?",) if kind == "dtmc" else ("Pmax=?", "Pmin=?")
    found = [f"{op} [ {path} ]" for label in labels for op in ops
             for path in (f'F "{label}"', f'F<=10 "{label}"', f'G "{label}"')]
    r_ops = ("=?",) if kind == "dtmc" else ("max=?", "min=?")
    paths = ([f'F "{labels[0]}"'] if labels else []) + ["C<=10", "I=5"]
    for name in rewards:
        prefix = f'R{{"{name}"}}' if name else "R"
        found += [f"{prefix}{op} [ {path} ]" for path in paths for op in r_ops]
    return found


# ---------------------------------------------------------------------------
# The Storm worker (``--worker REQUEST``): one process per model


def _storm_value(value: object) -> object:
    """A Storm result value as JSON: a float, a bool, or a fraction's text."""
    if isinstance(value, bool):
        return value
    if isinstance(value, (int, float)):
        return value if math.isfinite(value) else str(value)
    return str(value)


def _emit(record: dict[str, object]) -> None:
    print(json.dumps(record), flush=True)


def _storm_program(path: str, constants: dict[str, str]):  # type: ignore[no-untyped-def]
    """Storm's program of the model file *path*, its undefined constants set."""
    import stormpy  # (only the worker needs stormpy)

    program = stormpy.parse_prism_program(path)
    if constants:
        text = ",".join(f"{k}={v}" for k, v in constants.items())
        program, _ = stormpy.instantiate_constants(program, text)
    return program


def _storm_build(request: dict[str, object], exact: bool):  # type: ignore[no-untyped-def]
    """The program (constants set) and the model Storm builds from *request*."""
    import stormpy

    constants = dict(request.get("constants") or {})  # type: ignore[call-overload]
    program = _storm_program(str(request["model"]), constants)
    if request.get("fix_deadlocks"):
        path = _without_deadlocks(program, str(request["model"]), constants)
        program = _storm_program(path, constants)
    # Every label and reward structure, and the expressions the properties file's
    # properties test (Storm labels those only when it is told about them). Given one
    # formula, Storm's builder stops at the states that decide it (BuilderOptions.cpp,
    # "formulas.size() == 1"): the list is doubled so that the model is built in full.
    from_file = _parsed(Path(str(request["props"])).read_text(), program) \
        if request.get("props") else []
    options = stormpy.BuilderOptions(2 * from_file if isinstance(from_file, list) and from_file
                                     else None)
    options.set_build_all_labels()
    options.set_build_all_reward_models()
    builder = stormpy.build_model[stormpy.Rational] if exact else stormpy.build_model
    return program, builder(program, options=options)


def deadlock_guard(valuations: list[dict[str, object]]) -> str:
    """A PRISM guard that holds in exactly the states of *valuations*."""
    def atom(name: str, value: object) -> str:
        if isinstance(value, bool):
            return name if value else f"!{name}"
        return f"{name}={value}"

    return " | ".join("(" + " & ".join(atom(k, v) for k, v in state.items()) + ")"
                      for state in valuations) or "false"


def _without_deadlocks(program, path: str, constants: dict[str, str]) -> str:  # type: ignore[no-untyped-def]
    """A copy of the model file *path* with a module whose one command loops in the
    states Storm finds deadlocked: the model PRISM means (a deadlock keeps its state
    rewards), which Storm then builds without deadlocks (where it zeroes the rewards
    of the self-loops it adds: ExplicitModelBuilder.cpp). Returns the copy's path."""
    import stormpy

    model = stormpy.build_model(program, options=stormpy.BuilderOptions(build_full=True))
    dead = model.labeling.get_states("deadlock")
    valuations = [json.loads(str(model.state_valuations.to_json(s)))
                  for s in range(model.nr_states) if dead.get(s)]
    copy = Path(path).with_suffix(".no-deadlocks" + Path(path).suffix)
    copy.write_text(Path(path).read_text() + "\nmodule storm_sweep_deadlocks\n"
                    f"  [] {deadlock_guard(valuations)} -> true;\nendmodule\n"
                    f'\nlabel "storm_sweep_deadlock" = {deadlock_guard(valuations)};\n')
    return str(copy)


def _describe(program, model, kind: str) -> dict[str, object]:  # type: ignore[no-untyped-def]
    """Counts, labels and reward structures of a Storm model."""
    deadlocks = model.labeling.get_states("deadlock").get_number_of_set_bits() \
        if model.labeling.contains_label("deadlock") else 0
    labels = [label.name for label in program.labels]
    rewards = [reward.name for reward in program.reward_models]
    return {"kind": kind, "states": model.nr_states, "choices": model.nr_choices,
            "transitions": model.nr_transitions, "deadlocks": deadlocks,
            "initial_states": len(model.initial_states), "labels": labels,
            "rewards": rewards}


def _environment(exact: bool):  # type: ignore[no-untyped-def]
    import stormpy

    if exact:
        return stormpy.environments.exact()
    env = stormpy.environments.sound()
    precision = stormpy.Rational(STORM_PRECISION)
    env.solver().min_max().precision = precision
    env.solver().native().precision = precision
    return env


def _storm_check(model, prop, exact: bool) -> dict[str, object]:  # type: ignore[no-untyped-def]
    """Storm's values of the stormpy property *prop* at the initial states (or its error)."""
    import stormpy

    try:
        result = stormpy.model_checking(model, prop, environment=_environment(exact))
        return {"values": [_storm_value(result.get_value(s)) for s in model.initial_states]}
    except Exception as exc:  # (any Storm failure is that property's row)
        return {"error": _failure(exc)}


def _failure(exc: Exception) -> str:
    return f"{type(exc).__name__}: {' '.join(str(exc).split())[:300]}"


def _parsed(text: str, program) -> list[object] | str:  # type: ignore[no-untyped-def]
    """Storm's properties in *text*, or why it cannot parse them."""
    import stormpy

    try:
        return list(stormpy.parse_properties(text, program))
    except Exception as exc:
        return _failure(exc)


def _storm_properties(request: dict[str, object], program,  # type: ignore[no-untyped-def]
                      described: dict[str, object]) -> list[tuple[str, object]]:
    """(name, stormpy property or why it does not parse) for the requested names: the
    request's, else the generated properties and those of the properties file. A name
    ``#i`` is the properties file's *i*-th property (1-based), any other a property's
    text."""
    names = request.get("properties")
    from_file = _parsed(Path(str(request["props"])).read_text(), program) \
        if request.get("props") else []
    if names is None:
        labels = list(described["labels"])  # type: ignore[call-overload]
        if described["deadlocks"]:
            labels.append("deadlock")
        names = generated_properties(str(described["kind"]), labels,
                                     list(described["rewards"]))  # type: ignore[call-overload]
        names += ["#1"] if isinstance(from_file, str) else \
            [f"#{i}" for i in range(1, len(from_file) + 1)]
    found: list[tuple[str, object]] = []
    for name in names:  # type: ignore[attr-defined]
        if name.startswith("#"):
            prop = from_file if isinstance(from_file, str) else from_file[int(name[1:]) - 1]
        else:
            text = name.replace('"deadlock"', '"storm_sweep_deadlock"') \
                if request.get("fix_deadlocks") else name
            parsed = _parsed(text, program)
            prop = parsed if isinstance(parsed, str) else parsed[0]
        found.append((name, prop))
    return found


def worker(request_path: Path) -> None:
    """Build the requested model with Storm; print its description and then one JSON
    line per property (generated ones unless the request names them)."""
    request = json.loads(request_path.read_text())
    exact = bool(request.get("exact"))
    try:
        program, model = _storm_build(request, exact)
    except Exception as exc:  # (a model Storm cannot build is a skip)
        _emit({"build_error": _failure(exc)})
        return
    kind = model.model_type.name.lower()
    described = _describe(program, model, kind)
    props = _storm_properties(request, program, described)
    texts = {name: (name if not name.startswith("#") or isinstance(prop, str)
                    else str(prop.get_raw_formula())) for name, prop in props}  # type: ignore[attr-defined]
    _emit({"model": described, "properties": texts})
    for name, prop in props:
        start = time.perf_counter()
        outcome = {"error": prop} if isinstance(prop, str) else _storm_check(model, prop, exact)
        _emit({"property": name, **outcome, "wall_s": time.perf_counter() - start})


# ---------------------------------------------------------------------------
# Running processes


def run_capped(command: list[str], cwd: Path, timeout: float) -> Process:
    """:func:`sweeps.run_process` under the memory cap."""
    return sweeps.run_process(command, cwd, timeout, MEMORY_BYTES)


def storm_run(request: dict[str, object], folder: Path, timeout: float) -> tuple[
        list[dict[str, object]], Process]:
    """The JSON lines the Storm worker prints for *request*, and its process."""
    path = folder / f"request-{os.getpid()}.json"
    path.write_text(json.dumps(request))
    done = run_capped([sys.executable, str(Path(__file__).resolve()), "--worker",
                        str(path)], folder, timeout)
    lines = [json.loads(line) for line in done.stdout.splitlines() if line.startswith("{")]
    return lines, done


# ---------------------------------------------------------------------------
# The models


def models_and_props(files: list[str]) -> list[tuple[str, str | None]]:
    """The PRISM-language models among *files*, each with its properties file, if any:
    one with the model's stem and a properties suffix."""
    found = []
    for path in files:
        if not path.endswith(MODEL_SUFFIXES):
            continue
        stem = path.rsplit(".", 1)[0]
        props = [stem + suffix for suffix in PROPS_SUFFIXES if stem + suffix in files]
        found.append((path, props[0] if props else None))
    return found


# ---------------------------------------------------------------------------
# Values and their comparison


def fraction(value: object) -> Fraction | float | None:
    """An exact value (``"p/q"``; infinities as floats), or None."""
    if isinstance(value, str) and "inf" in value.lower():
        return float(value.lower().replace("infinity", "inf"))
    try:
        return Fraction(str(value))
    except (ValueError, ZeroDivisionError):
        return None


def storm_answer(values: list[object]) -> tuple[Number, Number]:
    """Storm's answer at the initial states: a truth value holding in all of them (twice),
    or the lowest and highest number."""
    read = [read_number(v) for v in values]
    if read and all(isinstance(v, bool) for v in read):
        return all(read), all(read)
    floats = [v for v in read if isinstance(v, float)]
    if not floats or len(floats) != len(read):
        return None, None
    return min(floats), max(floats)


def our_answer(result: dict[str, object]) -> tuple[Number, Number]:
    """veribattery's answer: its value twice, or the range over the initial states."""
    span = result.get("range")
    if isinstance(span, list) and len(span) == 2:
        return read_number(span[0]), read_number(span[1])  # type: ignore[return-value]
    value = read_number(result.get("value"))
    return value, value  # type: ignore[return-value]


def show(value: object) -> str:
    """A value to 12 significant digits (truth values as ``true``/``false``)."""
    if value is None:
        return "-"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float):
        return f"{value:.12g}"
    return str(value)


def show_pair(pair: tuple[object, object]) -> str:
    low, high = pair
    return show(low) if low == high or low is None else f"[{show(low)}, {show(high)}]"


# ---------------------------------------------------------------------------
# Rows


@dataclass
class Row:
    """One model's build, or one property of it."""

    model: str
    prop: str  # "(build)" for the counts
    outcome: str  # yes, NO, refused, error, timeout, storm error, skipped
    wall_s: float = 0.0
    storm_s: float | None = None
    states: tuple[object, object] = ("-", "-")
    ours: str = "-"
    storm: str = "-"
    message: str = ""
    command: list[str] = field(default_factory=list)
    stderr: str = ""
    verdict: str = ""  # after a mismatch: the exact values
    ours_pair: tuple[Number, Number] = (None, None)


def _json_output(done: Process) -> dict[str, object] | None:
    lines = [line for line in done.stdout.splitlines() if line.startswith("{")]
    try:
        output = json.loads(lines[-1])
    except (IndexError, ValueError):
        return None
    return output if isinstance(output, dict) else None


def failed(row: Row, done: Process) -> bool:
    """Set *row*'s outcome from a run that did not finish normally; whether it did not."""
    if done.returncode is None:
        row.outcome = "timeout"
    elif "Traceback" in done.stderr or done.returncode not in (0, 2):
        refusal = sweeps.error_line(done.stderr)
        row.outcome, row.message = "error", f"exit {done.returncode}: {refusal}"
    elif done.returncode == 2:
        row.outcome, row.message = "refused", sweeps.error_line(done.stderr)
    elif _json_output(done) is None:
        row.outcome, row.message = "error", "exit 0 without JSON"
    else:
        return False
    row.stderr = done.stderr
    return True


COUNTS = ("states", "choices", "transitions", "deadlocks")


def build_row(model: str, described: dict[str, object], command: list[str],
              done: Process, storm_s: float) -> Row:
    """Compare veribattery's full build (``--all-states``) with Storm's counts."""
    row = Row(model, "(build)", "", done.wall_s, storm_s, command=command)
    if failed(row, done):
        return row
    ours = _json_output(done)["model"]  # type: ignore[index]
    theirs = dict(described)
    if theirs["kind"] == "dtmc":
        theirs.pop("choices")
    keys = [k for k in COUNTS if k in theirs]
    row.ours = " / ".join(f"{ours.get(k, '-')}" for k in keys)  # type: ignore[union-attr]
    row.storm = " / ".join(f"{theirs[k]}" for k in keys)
    row.prop = f"(build: {' / '.join(keys)})"
    row.states = (ours.get("states"), theirs["states"])  # type: ignore[union-attr]
    differ = [k for k in keys if ours.get(k) != theirs[k]]  # type: ignore[union-attr]
    row.outcome = "NO" if differ else "yes"
    row.message = f"differ: {', '.join(differ)}" if differ else ""
    return row


def property_row(model: str, name: str, storm: dict[str, object], command: list[str],
                 done: Process) -> Row:
    """Compare veribattery's value of one property with Storm's."""
    row = Row(model, name, "", done.wall_s, read_number(storm.get("wall_s")),  # type: ignore[arg-type]
              command=command)
    if "error" in storm:
        row.storm = "error"
        row.message = f"Storm: {storm['error']}"
    else:
        row.storm = show_pair(storm_answer(storm["values"]))  # type: ignore[arg-type]
    if failed(row, done):
        return row
    output = _json_output(done)
    result = output["results"][0]  # type: ignore[index]
    ours = our_answer(result)
    row.ours, row.ours_pair = show_pair(ours), ours
    row.states = (output["model"].get("states"), "-")  # type: ignore[index, union-attr]
    if "error" in storm:
        row.outcome = "storm error"
        return row
    theirs = storm_answer(storm["values"])  # type: ignore[arg-type]
    row.outcome = "yes" if agree(ours[0], theirs[0]) and agree(ours[1], theirs[1]) else "NO"
    return row


# ---------------------------------------------------------------------------
# The sweep


@dataclass
class Case:
    """One model, its properties file, its constants and the folder they are in."""

    model: str
    props: str | None
    constants: dict[str, str]
    folder: Path

    def veribattery(self, *extra: str) -> list[str]:
        """The veribattery command for this model, then *extra*."""
        consts = [a for k, v in self.constants.items() for a in ("--const", f"{k}={v}")]
        return [sys.executable, "-m", "veribattery", "prism", self.model, *consts,
                "--json", *extra]

    def request(self, **more: object) -> dict[str, object]:
        """A request for the Storm worker."""
        return {"model": str(self.folder / self.model), "constants": self.constants,
                "props": str(self.folder / self.props) if self.props else None, **more}

    def prop_args(self, name: str) -> list[str]:
        """veribattery's options for the property *name* (``#i``: the file's i-th)."""
        if name.startswith("#"):
            return ["--props", str(self.props), "--property", name[1:]]
        return ["--property", name]


def exact_verdict(case: Case, name: str, timeout: float, row: Row,
                  deadlocks: int) -> None:
    """After a mismatch: both tools in exact arithmetic. For a reward property of a model
    with deadlocks, Storm again on the model with its deadlocks made self-loops in PRISM
    (:func:`_without_deadlocks`); where that agrees with veribattery the row's outcome is
    DEADLOCK_REWARD, a difference of semantics rather than of numbers."""
    storm_text, _ = _storm_exact(case, name, timeout)
    parts = [f"Storm exact: {storm_text}"]
    done = run_capped(case.veribattery(*case.prop_args(name), "--exact"), case.folder,
                       timeout)
    output = _json_output(done) if done.returncode == 0 else None
    ours = fraction(output["results"][0].get("exact")) if output else None  # type: ignore[index]
    shown = ours if ours is not None else sweeps.error_line(done.stderr)
    parts.append(f"veribattery --exact: {shown}")
    if deadlocks and name.startswith(("R", "#")):
        fixed_text, fixed = _storm_exact(case, name, timeout, fix_deadlocks=True)
        parts.append(f"Storm exact with the {deadlocks} deadlock state(s) looping in PRISM, "
                     f"so keeping their state rewards: {fixed_text}")
        answer = storm_answer([float(f) for f in map(fraction, fixed) if f is not None])
        low, high = row.ours_pair
        if fixed and agree(low, answer[0]) and agree(high, answer[1]):
            row.outcome = DEADLOCK_REWARD
    row.verdict = "; ".join(parts)


def _storm_exact(case: Case, name: str, timeout: float,
                 **more: object) -> tuple[str, list[object]]:
    """Storm's exact values of *name* at the initial states (as text, and as given), or
    its error and no values."""
    lines, done = storm_run(case.request(exact=True, properties=[name], **more), case.folder,
                            timeout)
    found = next((line for line in lines if line.get("property") == name), None)
    if found is None:
        return ("timeout" if done.returncode is None else sweeps.error_line(done.stderr)), []
    values = list(found.get("values") or [])  # type: ignore[call-overload]
    return (", ".join(map(str, values)) if values else str(found.get("error"))), values


def skipped_row(case: Case, why: str, timeout: float, storm_s: float | None = None) -> Row:
    """A model left out, with what veribattery makes of it (building it as it stands)."""
    probe = "P=? [ X true ]" if case.model.startswith("dtmc/") else "Pmax=? [ X true ]"
    command = case.veribattery("--property", probe, "--all-states")
    done = run_capped(command, case.folder, timeout)
    seen = Row(case.model, "-", "")
    ours = (f"refuses too: {seen.message}" if failed(seen, done) and seen.outcome == "refused"
            else seen.outcome or "builds it")
    return Row(case.model, "-", "skipped", done.wall_s, storm_s, command=command,
               message=f"{why}; veribattery {ours}", stderr=seen.stderr)


def sweep_model(case: Case, timeout: float, add: callable) -> None:  # type: ignore[valid-type]
    """Every row of one model, each passed to *add* when done."""
    if case.model in SKIPPED:
        add(skipped_row(case, SKIPPED[case.model], timeout))
        return
    lines, done = storm_run(case.request(), case.folder, timeout)
    head = lines[0] if lines else {}
    if "model" not in head:
        why = head.get("build_error") or ("timeout" if done.returncode is None
                                          else sweeps.error_line(done.stderr))
        add(skipped_row(case, f"Storm cannot build it: {why}", timeout, done.wall_s))
        return
    described = head["model"]
    storm_s = sum(float(line.get("wall_s", 0)) for line in lines[1:])
    probe = "P=? [ X true ]" if described["kind"] == "dtmc" else "Pmax=? [ X true ]"
    command = case.veribattery("--property", probe, "--all-states")
    add(build_row(case.model, described, command,
                  run_capped(command, case.folder, timeout), done.wall_s - storm_s))
    answers = {line["property"]: line for line in lines[1:] if "property" in line}
    for name in head["properties"]:
        storm = answers.get(name, {"error": "timeout" if done.returncode is None
                                   else sweeps.error_line(done.stderr)})
        command = case.veribattery(*case.prop_args(name))
        row = property_row(case.model, name, storm, command,
                           run_capped(command, case.folder, timeout))
        row.states = (row.states[0], described["states"])
        if name.startswith("#"):
            row.prop = f"{case.props} {name}: `{head['properties'][name]}`"
        if row.outcome == "NO":
            exact_verdict(case, name, timeout, row, int(described["deadlocks"]))
        add(row)


def _cell(text: object) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def table_row(row: Row) -> str:
    """One Markdown table row."""
    outcome = f"**{row.outcome}**" if row.outcome in FAILURES else row.outcome
    storm_s = "-" if row.storm_s is None else f"{row.storm_s:.1f}"
    states = f"{row.states[0]} / {row.states[1]}"
    return (f"| {row.model} | {_cell(row.prop)} | {states} | {_cell(row.ours)} "
            f"| {_cell(row.storm)} | {outcome} | {row.wall_s:.1f} / {storm_s} |")


def counts(rows: list[Row]) -> dict[str, int]:
    """How many rows of each outcome."""
    names = {"yes": "agree", "NO": "mismatch", "refused": "refused", "error": "errors",
             "timeout": "timeouts", "storm error": "Storm errors", "skipped": "skipped",
             DEADLOCK_REWARD: "Storm's deadlock rewards"}
    tally = dict.fromkeys(names.values(), 0)
    for row in rows:
        tally[names[row.outcome]] += 1
    return tally


def _notes(rows: list[Row]) -> list[str]:
    """The report's sections after the table: problems, refusals, Storm's errors, skips."""
    lines: list[str] = []
    sections = (("Mismatches, errors and timeouts", FAILURES),
                ("Storm's zero rewards in deadlock states", (DEADLOCK_REWARD,)),
                ("veribattery's refusals", ("refused",)),
                ("Storm's errors", ("storm error",)), ("Skipped models", ("skipped",)))
    for title, outcomes in sections:
        chosen = [row for row in rows if row.outcome in outcomes]
        if not chosen:
            continue
        lines.append(f"\n## {title}\n")
        for row in chosen:
            lines.append(f"- {row.model} `{_cell(row.prop)}`: {row.outcome}"
                         + (f" — `{_cell(row.message)}`" if row.message else ""))
            if row.verdict:
                lines.append(f"  - exact: {row.verdict}")
            if row.outcome in ("error", "timeout") and row.command:
                tail = row.stderr.strip().splitlines()[-10:]
                lines.append("  ```\n  " + " ".join(["python", *row.command[1:]])
                             + "".join(f"\n  {t}" for t in tail) + "\n  ```")
    return lines


def write(out: Path, rows: list[Row], header: str) -> None:
    """The whole report: header, summary, table, notes."""
    tally = ", ".join(f"{n} {name}" for name, n in counts(rows).items())
    models = len({row.model for row in rows})
    builds = sum(row.prop.startswith("(build") for row in rows)
    lines = [
        "# veribattery against Storm on Storm's PRISM-language test models\n",
        "Generated by `bench/storm_testfiles_sweep.py` (do not edit by hand). " + header,
        f"\n**{models} models ({builds} builds compared), "
        f"{len(rows) - builds - counts(rows)['skipped']} properties; rows: {tally}.**\n",
        "A `(build)` row compares veribattery's full build (`--all-states`) with Storm's: "
        "states / choices (MDPs) / transitions / deadlock states. A property row's states "
        "are veribattery's default build (states where every property is decided are not "
        "expanded, as Storm's). Values at the initial states (a range over several); "
        "`#i` is the i-th property of the model's own properties file. "
        "Wall time: veribattery's process / Storm's check (its build for a build row). "
        f"Paths are relative to `{TESTFILES}`.\n",
        "| model | property | states (ours / Storm) | veribattery | Storm | agree "
        "| wall s |",
        "|---|---|---|---|---|---|---|",
        *(table_row(row) for row in rows),
        *_notes(rows),
    ]
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(lines) + "\n")


def progress(number: int, row: Row) -> None:
    """Print *row* as a progress line, and a traceback's stderr loudly."""
    print(f"[{number}] {row.model} {row.prop}: {row.outcome} {row.ours} vs {row.storm} "
          f"{row.message} {row.verdict} ({row.wall_s:.1f} s)", flush=True)
    if row.outcome == "error" or "Traceback" in row.stderr:
        print(f"!!! {' '.join(row.command)}\n{row.stderr.rstrip()}", file=sys.stderr,
              flush=True)


def materialise(source: GitFolder, model: str, props: str | None, folder: Path) -> None:
    """Write *model* and *props* under *folder*, at their paths in the testfiles folder."""
    for name in filter(None, (model, props)):
        path = folder / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(source.read(name))


def main() -> None:
    if len(sys.argv) == 3 and sys.argv[1] == "--worker":
        worker(Path(sys.argv[2]))
        return
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", type=Path, required=True,
                        help="Storm: a checkout (holding resources/) or a bare git dir")
    parser.add_argument("--only", default="", help="models whose path contains this")
    parser.add_argument("--timeout", type=float, default=300.0, help="seconds per process")
    parser.add_argument("--out", type=Path, default=ROOT / "docs/_bench/storm_testfiles.md")
    args = parser.parse_args()
    source = GitFolder(args.root.expanduser(), TESTFILES)
    start = time.perf_counter()
    rows: list[Row] = []
    header = (f"veribattery at commit {sweeps.tree_commit()} against Storm "
              f"{_storm_version()} (stormpy, sound, relative precision "
              f"{float(Fraction(STORM_PRECISION)):g}) on Storm's commit "
              f"`{source.commit()}`; one process per property (one per model for Storm), "
              f"timeout {args.timeout:.0f} s, `ulimit -v` {MEMORY_BYTES // 1024**3} GB. "
              f"Agreement: relative tolerance {sweeps.RELATIVE_TOLERANCE:g} (absolute "
              f"{sweeps.ABSOLUTE_TOLERANCE:g} near 0), infinities equal, truth values exactly; "
              f"a mismatch is checked again in exact arithmetic by both. "
              f"Run {datetime.now(UTC):%Y-%m-%d %H:%M} UTC")

    def add(row: Row) -> None:
        rows.append(row)
        progress(len(rows), row)
        took = f"{time.perf_counter() - start:.0f} s so far"
        write(args.out, rows, f"{header}, {took}.")

    with tempfile.TemporaryDirectory() as tmp:
        for model, props in models_and_props(source.files(*FOLDERS)):
            if args.only not in model:
                continue
            materialise(source, model, props, Path(tmp))
            sweep_model(Case(model, props, CONSTANTS.get(model, {}), Path(tmp)),
                        args.timeout, add)
    write(args.out, rows, f"{header}, {time.perf_counter() - start:.0f} s in all.")
    tally = counts(rows)
    print(", ".join(f"{n} {name}" for name, n in tally.items()), flush=True)
    if tally["mismatch"] or tally["errors"] or tally["timeouts"]:
        sys.exit(1)


def _storm_version() -> str:
    done = subprocess.run([sys.executable, "-c", "import stormpy.info; "
                           "print(stormpy.info.storm_version())"],
                          capture_output=True, text=True, check=False)
    return done.stdout.strip() or "(version unknown)"


if __name__ == "__main__":
    main()
