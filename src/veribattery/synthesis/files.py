"""The files ``emit`` writes for a config in synthesis mode (``strategy.mode: synthesize``).

The same four files as for BS1 (:data:`~veribattery.mission.EMITTED_FILES`), so that a
directory never mixes a model of one mode with properties of the other: the MDP, its
questions (which PRISM and Storm both read), a Storm-only file that says there is
nothing Storm-only, and the resolved config. veribattery's own front end does not read
MDPs yet, so the texts are checked by Storm in the tests, not here.
"""

from __future__ import annotations

from veribattery.config import MissionConfig, config_to_yaml
from veribattery.mission import MODEL_FILE, PROPERTIES_FILE, MissionFiles
from veribattery.render import (
    render_synthesis_model,
    render_synthesis_properties,
    synthesis_questions,
)

__all__ = ["synthesis_files", "unasked_requirements"]

_PROPERTIES_HEADER = f"""\
// PRISM and Storm both read this file (the model is an MDP):
//   prism {MODEL_FILE} {PROPERTIES_FILE}
//   storm --prism {MODEL_FILE} --prop {PROPERTIES_FILE}
"""
_STORM_ONLY = f"""\
// Synthesis mode: every question of the mission MDP is in {PROPERTIES_FILE}, which PRISM
// and Storm both read; none is in Storm's own syntax. The config's properties are
// questions about BS1's DTMC (strategy.mode: bs1) and are not asked of the MDP.
"""


def synthesis_files(cfg: MissionConfig) -> MissionFiles:
    """The emitted texts of *cfg*'s mission MDP, whatever its ``strategy.mode``.

    :raises ConfigError: when the config's numbers overflow PRISM's integers.
    :raises RenderError: when a template fails.
    """
    properties = _PROPERTIES_HEADER + "\n" + render_synthesis_properties(cfg)
    return MissionFiles(render_synthesis_model(cfg), properties, _STORM_ONLY,
                        config_to_yaml(cfg))


def unasked_requirements(cfg: MissionConfig) -> tuple[str, ...]:
    """One warning per requirement of *cfg* that asks the MDP no question, and why."""
    return tuple(f"requirement '{q.requirement}' asks the MDP nothing: {q.reason}"
                 for q in synthesis_questions(cfg)[1])
