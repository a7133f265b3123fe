"""Storm (stormpy) as the strategy source of the synthesis tests: build the mission MDP,
take a memoryless scheduler, follow it from the initial state, and hand the states it
reaches to the threshold table as (valuation, action).

Import this module only after ``pytest.importorskip("stormpy")``.
"""

from __future__ import annotations

import json
from collections import deque
from collections.abc import Callable, Sequence
from fractions import Fraction
from pathlib import Path
from typing import Any

import pandas as pd
import stormpy

from tests.render.spec_mdp import Choice, State
from veribattery.synthesis.decisions import GO_ON
from veribattery.synthesis.strategy import STATE_VARIABLES, strategy_frame

GO_ON_ACTIONS = frozenset(GO_ON.values())


def build(text: str, folder: Path, name: str = "model.prism") -> tuple[Any, Any]:
    """Storm's full model of the PRISM *text* (state valuations, choice labels, every
    reward model), and the parsed program (to parse properties against)."""
    path = folder / name
    path.write_text(text)
    program = stormpy.parse_prism_program(str(path))
    options = stormpy.BuilderOptions()
    options.set_build_state_valuations()
    options.set_build_choice_labels()
    options.set_build_all_labels()
    options.set_build_all_reward_models()
    return stormpy.build_model(program, options=options), program


def valuation(model: Any, state: int) -> State:
    """Storm state *state* as the spec's six variables (a constant wind is low)."""
    values = json.loads(str(model.state_valuations.to_json(state)))
    values.setdefault("wsp", 0)
    return State(*(int(values[v]) for v in State._fields))


def action(model: Any, row: int) -> str:
    """The action label of choice *row* ("" for the absorbing loop)."""
    return "".join(sorted(model.choice_labeling.get_labels_of_choice(row)))


def scheduler_rows(model: Any, scheduler: Any) -> list[int]:
    """Per state, the row of the choice a memoryless deterministic *scheduler* takes."""
    assert scheduler.memoryless and scheduler.deterministic
    matrix = model.transition_matrix
    return [matrix.get_row_group_start(s) + scheduler.get_choice(s).get_deterministic_choice()
            for s in range(model.nr_states)]


def optimal_rows(model: Any, formula: str, program: Any) -> tuple[list[int], float]:
    """Storm's optimal scheduler for *formula* (rows per state) and its value."""
    prop = stormpy.parse_properties(formula, program)[0]
    result = stormpy.model_checking(model, prop, extract_scheduler=True)
    value = float(result.get_value(model.initial_states[0]))
    return scheduler_rows(model, result.get_scheduler()), value


def reachable(model: Any, rows: Sequence[int]) -> list[int]:
    """The states reachable from the initial state when each state takes *rows*."""
    matrix = model.transition_matrix
    seen = set(model.initial_states)
    queue = deque(seen)
    while queue:
        for entry in matrix.get_row(rows[queue.popleft()]):
            if entry.column not in seen:
                seen.add(entry.column)
                queue.append(entry.column)
    return sorted(seen)


def frame(states: Sequence[State], actions: Sequence[str],
          indifferent: Sequence[bool] | None = None) -> pd.DataFrame:
    """The strategy frame of *states* choosing *actions*."""
    columns = {name: [getattr(x, name) for x in states] for name in STATE_VARIABLES}
    return strategy_frame(columns, actions, indifferent=indifferent)


def strategy_of(model: Any, rows: Sequence[int],
                indifferent: Callable[[State], bool] | None = None) -> pd.DataFrame:
    """The states reachable under *rows*, as a strategy frame."""
    states = reachable(model, rows)
    named = [valuation(model, s) for s in states]
    flags = None if indifferent is None else [indifferent(x) for x in named]
    return frame(named, [action(model, rows[s]) for s in states], flags)


def choice_values(choices: Sequence[Choice], value: dict[State, Fraction],
                  here: State) -> list[Fraction]:
    """Each choice's exact value under *value* (a self-loop solved as in spec_mdp)."""
    out = []
    for _, dist in choices:
        stay = dist.get(here, Fraction(0))
        if stay == 1:
            out.append(value[here])
            continue
        out.append(sum((p * value[y] for y, p in dist.items() if y != here), Fraction(0))
                   / (1 - stay))
    return out


def indifference(model: dict[State, list[Choice]],
                 value: dict[State, Fraction]) -> Callable[[State], bool]:
    """Whether going on and turning back are exactly equally good at a state of *model*
    (both possible, and the best of turning back -- return or abort -- worth as much as
    going on), by the exact values *value*."""
    def indifferent(x: State) -> bool:
        worth = dict(zip([a for a, _ in model[x]], choice_values(model[x], value, x),
                         strict=True))
        go_on = [v for a, v in worth.items() if a in GO_ON_ACTIONS]
        back = [v for a, v in worth.items() if a not in GO_ON_ACTIONS]
        return bool(go_on and back) and go_on[0] == max(back)
    return indifferent


def exactly_optimal(model: dict[State, list[Choice]], value: dict[State, Fraction],
                    x: State, chosen: str) -> bool:
    """Whether *chosen* is worth *value* at *x* (an optimal choice), exactly."""
    worth = dict(zip([a for a, _ in model[x]], choice_values(model[x], value, x), strict=True))
    return worth[chosen] == value[x]
