"""The mission's states in the paper's terms: cells, drone states, actions, charge, voltage level.

The general analyses see only variables. This view names states as the paper's
Fig. 7 does, from the config's farm layout and battery numbers and from the
rendered model's own formulas (``cap``, ``volt``, ``go_*``), so the view and
the model cannot disagree.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

import numpy as np
import numpy.typing as npt

from veribattery._types import IntArray
from veribattery.analyses.actions import ActionLabeller, action_labeller
from veribattery.config import MissionConfig, ModelParameters, derive_parameters
from veribattery.explore import DTMC, build_dtmc, compile_expr
from veribattery.explore.compile.expr import CompiledExpr
from veribattery.lang import FlatModel, flatten_model, parse_model
from veribattery.pipeline import ProgressCallback

__all__ = ["DEFAULT_GROUPINGS", "GROUP_KEYS", "MissionModel", "MissionView", "build_mission"]

#: Drone states (variable ``s``) by number, as in the spec.
DRONE_STATES = ("ground", "airborne", "at cell", "inspected", "above base", "landed",
                "failed", "success")
LEVELS = ("low", "medium", "high")
WINDS = ("low", "high")
#: The Drone's decisions (formulas ``go_*``) that ``oob`` can cut short.
INTENDED = ("takeoff", "fly", "land", "inspect", "back", "next", "backnext")
#: Recharges per bucket in the ``recharges`` grouping.
RECHARGE_BUCKET = 10
#: The columns the view names, then the mission model's variables it also gives (as
#: they are): every key :meth:`MissionView.columns` has.
GROUP_KEYS = ("k", "cell", "state", "action", "wind", "level", "recharges", "s", "j", "wsp",
              "b", "rc")
#: The breakdown's default groupings.
DEFAULT_GROUPINGS: tuple[tuple[str, ...], ...] = (
    ("k", "cell"), ("state", "action"), ("wind",), ("level",), ("recharges",),
)

Column = npt.NDArray[np.generic]


@dataclass(frozen=True, slots=True)
class MissionModel:
    """A mission's flat model and its built DTMC."""

    config: MissionConfig
    flat: FlatModel
    dtmc: DTMC


def build_mission(cfg: MissionConfig, *, progress: ProgressCallback | None = None) -> MissionModel:
    """Render, flatten and build the DTMC of *cfg* (no property is checked)."""
    from veribattery.mission import MODEL_FILE, mission_files

    flat = flatten_model(parse_model(mission_files(cfg).model, name=MODEL_FILE))
    return MissionModel(cfg, flat, build_dtmc(flat, progress=progress))


class MissionView:
    """Per-state columns of a mission DTMC in the paper's terms.

    :param mission: the built mission.
    """

    def __init__(self, mission: MissionModel) -> None:
        self.dtmc = mission.dtmc
        self.params: ModelParameters = derive_parameters(mission.config)
        self.resolution = Fraction(mission.config.battery.resolution_ah)
        names = mission.dtmc.variable_names
        formulas = {f.name: f.expr for f in mission.flat.formulas}
        self._formula: dict[str, CompiledExpr] = {
            name: compile_expr(formulas[name], names)
            for name in ("cap", "volt", *(f"go_{a}" for a in INTENDED)) if name in formulas
        }
        self._labels: ActionLabeller = action_labeller(mission.flat)

    def _var(self, rows: IntArray, name: str) -> IntArray:
        return rows[:, self.dtmc.variable_names.index(name)]

    def _eval(self, name: str, rows: IntArray) -> npt.NDArray[np.int64]:
        value = np.asarray(self._formula[name](rows))
        return np.broadcast_to(value, (rows.shape[0],)).astype(np.int64)

    def actions(self, rows: IntArray) -> npt.NDArray[np.str_]:
        """The action of each state; ``oob`` is qualified with the step it cut short."""
        labels = self._labels(rows).astype(object)
        cut = labels == "oob"
        intended = np.full(rows.shape[0], "recharge cap", dtype=object)
        for action in reversed(INTENDED):
            if f"go_{action}" in self._formula:
                intended[self._eval(f"go_{action}", rows).astype(bool)] = action
        labels[cut] = "oob (" + intended[cut] + ")"
        return labels.astype(np.str_)

    def cells(self, k: IntArray) -> npt.NDArray[np.str_]:
        """Route cell ``[x,y]`` of each route index (``done`` past the last)."""
        names = [f"[{x},{y}]" for x, y in self.params.layout.route] + ["done"]
        return np.asarray(names, dtype=np.str_)[k]

    def columns(self, idx: IntArray) -> dict[str, Column]:
        """Grouping columns of the states *idx*: route, state, action, wind, level, recharges."""
        rows = self.dtmc.states[idx]
        k, rc = self._var(rows, "k"), self._var(rows, "rc")
        low = rc // RECHARGE_BUCKET * RECHARGE_BUCKET
        buckets = np.char.add(np.char.add(low.astype(str), "-"),
                              (low + RECHARGE_BUCKET - 1).astype(str))
        return {
            "k": k,
            "cell": self.cells(k),
            "state": np.asarray(DRONE_STATES, dtype=np.str_)[self._var(rows, "s")],
            "action": self.actions(rows),
            "wind": np.asarray(WINDS, dtype=np.str_)[self._var(rows, "wsp")],
            "level": np.asarray(LEVELS, dtype=np.str_)[self._eval("volt", rows)],
            "recharges": buckets,
            **{name: rows[:, i] for i, name in enumerate(self.dtmc.variable_names)},
        }

    def steps(self, idx: IntArray) -> list[dict[str, object]]:
        """One Fig. 7 row per state of a path: the action taken there and the state's readings."""
        rows = self.dtmc.states[idx]
        cols = self.columns(idx)
        cap = self._eval("cap", rows)
        n = np.asarray((*self.params.layout.n, 0))[cols["k"].astype(np.int64)]
        actions = cols["action"].astype(object)
        actions[-1] = ""  # the path ends on entering the target
        return [
            {
                "step": i, "action": str(actions[i]), "state": str(cols["state"][i]),
                "cell": str(cols["cell"][i]), "turbines": f"{int(cols['j'][i])}/{int(n[i])}",
                "wind": str(cols["wind"][i]),
                "charge_ah": float(int(cols["b"][i]) * self.resolution),
                "soc": float(Fraction(int(cols["b"][i]), max(int(cap[i]), 1))),
                "level": str(cols["level"][i]),
                **{name: int(rows[i, c]) for c, name in enumerate(self.dtmc.variable_names)},
            }
            for i in range(len(idx))
        ]
