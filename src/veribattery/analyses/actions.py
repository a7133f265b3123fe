"""The action label of the step taken from each state, recovered from the model's commands.

The DTMC keeps no action labels. They are recovered in a separate, vectorised
pass: a choice group (an action label, or a module's unlabelled commands) is
enabled in a state when every participating module has an enabled command
there, exactly as the builder decides. Unlabelled commands are named after
their module, as in PRISM's simulator.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from veribattery._types import BoolArray, IntArray
from veribattery.explore.compile.program import ChoiceGroup, compile_program
from veribattery.lang.nodes import FlatModel

__all__ = ["ActionLabeller", "action_labeller"]

#: Rows of variable values (one per state) → the action label of each row.
ActionLabeller = Callable[[IntArray], npt.NDArray[np.str_]]


def action_labeller(flat: FlatModel) -> ActionLabeller:
    """A function from state rows to the action label(s) enabled there.

    States with several enabled groups get their labels joined by ``|``;
    states with none (deadlocks, given a self-loop) get ``"-"``.
    """
    program = compile_program(flat)
    names = [_group_name(g) for g in program.groups]

    def label(rows: IntArray) -> npt.NDArray[np.str_]:
        result = np.full(rows.shape[0], "", dtype=object)
        for name, group in zip(names, program.groups, strict=True):
            on = _enabled(group, rows)
            joined = np.where(result[on] == "", name, result[on] + "|" + name)
            result[on] = joined
        result[result == ""] = "-"
        return result.astype(np.str_)

    return label


def _group_name(group: ChoiceGroup) -> str:
    if group.action is not None:
        return group.action
    return group.parts[0][0].module if group.parts and group.parts[0] else "-"


def _enabled(group: ChoiceGroup, rows: IntArray) -> BoolArray:
    on = np.ones(rows.shape[0], dtype=bool)
    for part in group.parts:
        any_command = np.zeros(rows.shape[0], dtype=bool)
        for command in part:
            any_command |= np.broadcast_to(np.asarray(command.guard(rows), dtype=bool),
                                           any_command.shape)
        on &= any_command
    return on
