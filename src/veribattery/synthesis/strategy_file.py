"""A strategy file read back onto the mission MDP (``--strategy FILE``).

The files are those ``synthesize --export-strategy`` (and ``prism --export-strategy``)
writes: PRISM's actions form, ``(v1,...,vn)=action`` per line, or Storm's scheduler
JSON (``.json``), each listing the states reachable under the strategy by their
variables' values with the action taken (:mod:`veribattery.strategies.formats`).
A file fits the MDP when every state it names is a state of the MDP, its action is
exactly one choice there, the initial state is named, and every successor of a named
state under its choice is named too (so the induced chain is closed).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from veribattery._text import decode_text
from veribattery._types import IntArray
from veribattery.checker.mdp import MDP
from veribattery.synthesis.strategy import StrategyError

__all__ = ["read_strategy_file"]

#: A file's entries: per named state its variables' values (the MDP's order), its action,
#: and where it is written (``FILE:LINE``, or ``FILE: entry N`` in a JSON list).
Entries = tuple[IntArray, list[str], list[str]]


def read_strategy_file(path: Path, mdp: MDP) -> IntArray:
    """Per state of *mdp*, the choice (row) the strategy in *path* takes; -1 where the
    file names no state (states it never reaches).

    :raises StrategyError: when the file cannot be read or does not fit *mdp*.
    :raises OSError: when the file cannot be opened.
    """
    text = decode_text(path.read_bytes(), str(path), StrategyError)
    values, actions, places = (_storm_entries(text, mdp, path)
                               if path.suffix.lower() == ".json"
                               else _prism_entries(text, mdp, path))
    states = _states_of(values, places, mdp)
    choices = np.full(mdp.num_states, -1, dtype=np.int64)
    choices[states] = _choices_of(states, actions, places, mdp)
    _require_closed(choices, states, places, mdp, path)
    return choices


def _prism_entries(text: str, mdp: MDP, path: Path) -> Entries:
    rows, actions, places = [], [], []
    for number, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        valuation, equals, action = line.strip().partition(")=")
        if not valuation.startswith("(") or not equals:
            raise StrategyError(f"{path}:{number}: not a strategy line '(v1,...,vn)=action'")
        rows.append([_number(v, path, number) for v in valuation[1:].split(",")])
        actions.append(action.strip())
        places.append(f"{path}:{number}")
    return _table(rows, len(mdp.variable_names), places, path), actions, places


def _storm_entries(text: str, mdp: MDP, path: Path) -> Entries:
    try:
        entries = json.loads(text)
    except ValueError as exc:
        raise StrategyError(f"{path}: not JSON ({exc})") from None
    if not isinstance(entries, list):
        raise StrategyError(f"{path}: not a Storm scheduler: expected a list of entries "
                            '{"s": {variable: value, ...}, "c": [{"labels": [action]}]}')
    rows = [_storm_state(entry, mdp, path, n) for n, entry in enumerate(entries, 1)]
    actions = [_storm_action(entry, path, n) for n, entry in enumerate(entries, 1)]
    places = [f"{path}: entry {n}" for n in range(1, len(entries) + 1)]
    return _table(rows, len(mdp.variable_names), places, path), actions, places


def _storm_state(entry: object, mdp: MDP, path: Path, number: int) -> list[int]:
    """Entry *number*'s valuation ``"s"``, in the model's variable order."""
    state = entry.get("s") if isinstance(entry, dict) else None
    if not isinstance(state, dict):
        raise StrategyError(f'{path}: entry {number} has no "s" (the state\'s valuation, '
                            '{variable: value, ...})')
    missing = [name for name in mdp.variable_names if name not in state]
    if missing:
        raise StrategyError(f'{path}: entry {number}\'s "s" has no value of '
                            f"{', '.join(missing)} (the model's variables: "
                            f"{', '.join(mdp.variable_names)})")
    return [_number(state[name], path, number) for name in mdp.variable_names]


def _storm_action(entry: dict[str, object], path: Path, number: int) -> str:
    """Entry *number*'s action: the first label of its first choice ``"c"`` ('' if none)."""
    choices = entry.get("c")
    first = choices[0] if isinstance(choices, list) and choices else None
    labels = first.get("labels", None) if isinstance(first, dict) else ()
    if not (labels is None or isinstance(labels, list)):
        raise StrategyError(f'{path}: entry {number} has no choice "c": '
                            '[{"labels": [action]}]')
    return str((labels or [""])[0])


def _number(value: object, path: Path, entry: int) -> int:
    text = str(value).strip().lower()
    if text in ("true", "false"):
        return int(text == "true")
    try:
        number = int(text)
    except ValueError:
        number = None
    if number is None or not -(2**63) <= number < 2**63:  # no int64 (numpy's states)
        raise StrategyError(f"{path}:{entry}: {value!r} is not a variable's value")
    return number


def _table(rows: list[list[int]], width: int, places: list[str], path: Path) -> IntArray:
    if not rows:
        raise StrategyError(f"{path}: names no state")
    wrong = next((i for i, row in enumerate(rows) if len(row) != width), None)
    if wrong is not None:
        raise StrategyError(f"{places[wrong]}: a state of {len(rows[wrong])} values, but the "
                            f"model has {width} variables (a strategy for another model?)")
    return np.asarray(rows, dtype=np.int64)


def _states_of(values: IntArray, places: list[str], mdp: MDP) -> IntArray:
    """The MDP's index of each named state (a mixed-radix code of the valuations)."""
    assert mdp.states is not None
    known = np.asarray(mdp.states, dtype=np.int64)
    low, high = known.min(axis=0), known.max(axis=0)
    outside = ((values < low) | (values > high)).any(axis=1)
    if outside.any():
        raise _no_state(places, values, int(np.argmax(outside)))
    dims = tuple(int(d) for d in high - low + 1)
    codes = np.ravel_multi_index(tuple((known - low).T), dims)
    wanted = np.ravel_multi_index(tuple((values - low).T), dims)
    order = np.argsort(codes)
    at = np.minimum(np.searchsorted(codes, wanted, sorter=order), codes.size - 1)
    found = order[at]
    missing = codes[found] != wanted
    if missing.any():
        raise _no_state(places, values, int(np.argmax(missing)))
    _require_distinct(found, places)
    return np.asarray(found, dtype=np.int64)


def _no_state(places: list[str], values: IntArray, entry: int) -> StrategyError:
    return StrategyError(f"{places[entry]}: {_valuation(values[entry])} is no state of the "
                         "mission MDP (a strategy exported for another config?)")


def _require_distinct(found: IntArray, places: list[str]) -> None:
    """Refuse a state named twice, naming both places."""
    order = np.argsort(found, kind="stable")
    repeated = np.flatnonzero(found[order][1:] == found[order][:-1])
    if repeated.size:
        first, again = int(order[repeated[0]]), int(order[repeated[0] + 1])
        earlier = places[first].rpartition(":")[2].strip()
        earlier = f"line {earlier}" if earlier.isdigit() else earlier
        raise StrategyError(f"{places[again]}: names the state of {earlier} again; "
                            "give each state one action")


def _valuation(values: IntArray) -> str:
    return "(" + ",".join(str(int(v)) for v in values) + ")"


def _choices_of(states: IntArray, actions: list[str], places: list[str], mdp: MDP
                ) -> IntArray:
    """The one choice of each named state with its named action."""
    assert mdp.choice_actions is not None
    index = {name: i for i, name in enumerate(mdp.actions)}
    unknown = next((i for i, a in enumerate(actions) if a not in index), None)
    if unknown is not None:
        named = ", ".join(a for a in mdp.actions if a)
        raise StrategyError(f"{places[unknown]}: action '{actions[unknown]}' is no action of "
                            f"the mission MDP (its actions: {named})")
    wanted = states * len(mdp.actions) + np.asarray([index[a] for a in actions])
    keys = mdp.choice_owner * len(mdp.actions) + mdp.choice_actions
    order = np.argsort(keys, kind="stable")
    first = np.searchsorted(keys, wanted, side="left", sorter=order)
    last = np.searchsorted(keys, wanted, side="right", sorter=order)
    if ((last - first) != 1).any():
        bad = int(np.argmax((last - first) != 1))
        raise StrategyError(f"{places[bad]}: '{actions[bad]}' is not exactly one "
                            "choice of that state")
    return np.asarray(order[first], dtype=np.int64)


def _require_closed(choices: IntArray, states: IntArray, places: list[str], mdp: MDP,
                    path: Path) -> None:
    assert mdp.states is not None
    if (choices[mdp.initial] < 0).any():
        raise StrategyError(f"{path}: does not name the mission's initial state")
    rows = mdp.transitions[choices[states]]
    unnamed = choices[rows.indices] < 0
    if unnamed.any():
        at = int(np.argmax(unnamed))
        entry = int(np.searchsorted(rows.indptr, at, side="right")) - 1
        reached = np.asarray(mdp.states[int(rows.indices[at])], dtype=np.int64)
        raise StrategyError(f"{places[entry]}: its action leads to {_valuation(reached)}, "
                            "which the file does not name; a strategy file names every "
                            "state its actions reach")
