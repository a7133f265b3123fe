"""The mission MDP of a config, built by veribattery's own engine, and certified values
at its initial state.

Whatever the config's ``strategy.mode``, the model is the one ``emit`` writes in
synthesis mode (:func:`~veribattery.render.render_synthesis_model`): parsed, flattened
and explored like any PRISM file, into the checker's
:class:`~veribattery.checker.mdp.MDP`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from veribattery.checker.mdp import MDP, MdpResult
from veribattery.checker.mdp.multi_weighted import Interval
from veribattery.config import MissionConfig
from veribattery.explore.build.mdp import build_mdp
from veribattery.lang import FlatModel, flatten_model, parse_model
from veribattery.mission import MODEL_FILE
from veribattery.pipeline import ProgressCallback
from veribattery.pipeline.mdp import as_checker_mdp
from veribattery.render import render_synthesis_model

__all__ = ["Certified", "ModelSize", "built_model", "mission_mdp", "mission_model"]


class Certified(Interval):
    """A value at the initial state inside a certified interval ``[lower, upper]``."""

    __slots__ = ()

    @classmethod
    def at_initial(cls, mdp: MDP, result: MdpResult) -> Certified:
        """*result*'s value at *mdp*'s (single) initial state."""
        start = int(mdp.initial[0])
        return cls(float(result.values[start]), float(result.lower[start]),
                   float(result.upper[start]))


@dataclass(frozen=True, slots=True)
class ModelSize:
    """How large the mission MDP is."""

    states: int
    choices: int
    transitions: int

    @classmethod
    def of(cls, mdp: MDP) -> ModelSize:
        """The sizes of *mdp*."""
        return cls(mdp.num_states, mdp.num_choices, mdp.num_transitions)


def mission_mdp(cfg: MissionConfig, *, progress: ProgressCallback | None = None) -> MDP:
    """The MDP of *cfg*'s farm, battery and wind (model-spec.md, "Synthesis").

    :param progress: told ``(states found, frontier)`` after each layer of the build.
    :raises ConfigError: when the config's numbers overflow PRISM's integers.
    :raises ModelError: when the build fails (or *progress* stops it).
    """
    return mission_model(cfg, progress=progress)[1]


def mission_model(cfg: MissionConfig, *,
                  progress: ProgressCallback | None = None) -> tuple[FlatModel, MDP]:
    """:func:`mission_mdp` and the flat PRISM model it was built from (which the
    induced DTMC's text needs: its variables, labels and rewards)."""
    return built_model(render_synthesis_model(cfg), progress=progress)


def built_model(text: str, *, progress: ProgressCallback | None = None,
                rewards: bool = True) -> tuple[FlatModel, MDP]:
    """The flat model and the MDP of the mission MDP *text* (as
    :func:`~veribattery.render.render_synthesis_model` writes it; a sweep point renders
    it once, where the point is planned).

    :param rewards: build the reward structures (``Pmax`` alone needs none: the flat
        model returned then has none either).
    """
    model = flatten_model(parse_model(text, name=MODEL_FILE))
    if not rewards:
        model = replace(model, rewards=())
    return model, as_checker_mdp(build_mdp(model, progress=progress))
