"""The mission facade: config → rendered PRISM text → the same pipeline as any user file.

:func:`check_mission` checks one config; a :class:`MissionSession` checks configs one
after another (a sweep's task, a PHM recheck), sharing state spaces, quotients and
parses between them.
"""

from __future__ import annotations

from dataclasses import dataclass

from veribattery.checker import Workspace
from veribattery.config import MissionConfig, require_config
from veribattery.explore.dtmc import DTMC
from veribattery.lang import flatten_model, parse_model
from veribattery.lang.nodes import Model, PropertiesFile
from veribattery.mission.files import MODEL_FILE, mission_files, placed_in_config
from veribattery.mission.parses import ParseCache
from veribattery.mission.report import MissionReport, mission_report, recharge_cap_property
from veribattery.pipeline import (
    CheckOptions,
    Keep,
    ProgressCallback,
    Rewards,
    Session,
    check_model,
    check_model_exact,
)

__all__ = ["MissionSession", "RenderedMission", "check_mission", "mission_dtmc", "reuse_key"]


@dataclass(frozen=True, slots=True)
class RenderedMission:
    """A mission config and the PRISM model and properties texts rendered from it.

    What a sweep point carries, so that it is rendered once: for its reuse key in the
    sweep's process, and for its check wherever that runs.
    """

    config: MissionConfig
    model: str
    properties: str

    @classmethod
    def of(cls, cfg: MissionConfig) -> RenderedMission:
        """Render *cfg* (Jinja: imported late).

        :raises ConfigError: when the config's numbers overflow PRISM's integers, or it
            asks for synthesis (an MDP).
        :raises ArgumentError: for anything but a loaded config.
        """
        from veribattery.render import render_model, render_properties

        cfg = require_config(cfg)  # not a notebook's file name, or its text
        cfg.require_bs1()
        return cls(cfg, render_model(cfg), render_properties(cfg))

    @classmethod
    def of_point(cls, cfg: MissionConfig) -> RenderedMission:
        """*cfg* rendered as a sweep point of either mode: as :meth:`of`, or in synthesis
        mode the mission MDP and no properties (such a point is asked ``Pmax`` of success).

        :raises ConfigError: when the config's numbers overflow PRISM's integers.
        """
        if cfg.strategy.mode != "synthesize":
            return cls.of(cfg)
        from veribattery.render import render_synthesis_model

        return cls(cfg, render_synthesis_model(cfg), "")

    @property
    def is_mdp(self) -> bool:
        """Whether the model is the mission MDP (``strategy.mode: synthesize``)."""
        return self.config.strategy.mode == "synthesize"


def check_mission(
    cfg: MissionConfig, *, progress: ProgressCallback | None = None, exact: bool = False,
    keep: Keep = "states",
) -> MissionReport:
    """Render *cfg*, parse and check the text like any PRISM file, and judge the requirements.

    A property without a value here (the conditional defaults of a mission that never
    succeeds, or under ``--exact``) is NaN with a warning instead of stopping the check.

    :param exact: check in exact rational arithmetic and judge requirements exactly.
    :param keep: what each result keeps: ``"states"``, or ``"answers"`` only (what the
        CLI prints needs no more; see :class:`~veribattery.pipeline.CheckOptions`).
    :raises ArgumentError: for anything but a loaded config (a file's name, say).
    """
    mission = RenderedMission.of(cfg)
    if not exact:
        return MissionSession(keep=keep, reuse=False).check(mission, progress=progress)
    model, props = _parsed(ParseCache(), mission)
    with placed_in_config(cfg, props):
        run = check_model_exact(model, props.properties, props_file=props, progress=progress,
                                options=CheckOptions(keep, undefined_as_nan=True),
                                internal=(recharge_cap_property(cfg),))
    return mission_report(cfg, run)


class MissionSession:
    """Checks mission configs one after another in floating point, sharing what it can.

    It owns a pipeline :class:`~veribattery.pipeline.Session` (the state space re-used,
    the quotients' partitions, the checker's workspace) and a
    :class:`~veribattery.mission.parses.ParseCache` (consecutive configs' texts differ
    in a constant or two). Reports are those of :func:`check_mission`: the same values,
    to the last bit unless checked on a quotient (then within a few ulps, inside the
    same bounds).

    When a config's model shares the structure of the last one built in full -- the
    varied keys change only transition probabilities, not which transitions exist
    (e.g. ``environment.p_wsp_c`` strictly inside (0, 1)) -- the state space is kept
    and only probabilities, rewards and labels are evaluated again before solving;
    :attr:`MissionReport.reused` says which way each config ran. Configs with equal
    :func:`reuse_key` share one state space unless a probability becomes 0 or 1 at one
    of them; order configs by key to build each space once.

    :param keep: what each result keeps (``"states"`` or ``"answers"``).
    :param reuse: keep each full build's structure for the configs after it. False for
        a session that checks one config (a sweep task of one point): it then builds as
        :func:`check_mission` does, without the pass that records every branch's kind
        for re-pricing (a tenth of a build), which it would never use.
    :param lump: check on each DTMC's bisimulation quotient where it has one
        (:mod:`veribattery.explore.reuse.lumping`); only with ``keep="answers"``.
    :param rewards: ``"named"``: build only the reward structures the properties name.
    :param parses: the parse cache to use (a sweep's worker gives every task its own).
    :param workspace: the checker's caches (see :class:`~veribattery.pipeline.Session`).
    :raises ArgumentError: for *lump* without ``keep="answers"`` (also a ValueError).
    """

    def __init__(self, *, keep: Keep = "states", reuse: bool = True, lump: bool = False,
                 rewards: Rewards = "all", parses: ParseCache | None = None,
                 workspace: Workspace | None = None) -> None:
        options = CheckOptions(keep, undefined_as_nan=True)
        self.session = Session(options, reuse=reuse, lump=lump, rewards=rewards,
                               workspace=workspace)
        self.parses = parses or ParseCache()

    def __repr__(self) -> str:
        inner = self.session
        return (f"MissionSession(keep={inner.options.keep!r}, reuse={inner.builder is not None}, "
                f"lump={inner.lumper is not None}, rewards={inner.rewards!r})")

    @classmethod
    def for_sweep(cls, *, reuse: bool = True, lump: bool = False,
                  parses: ParseCache | None = None,
                  workspace: Workspace | None = None) -> MissionSession:
        """A session for sweep points, which keep values, not models: answers only, and
        only the reward structures the properties name.

        :param lump: check on quotients. A sweep decides it per run of points sharing a
            state space, so that a point's values do not depend on how the run was cut
            into tasks.
        :param workspace: the checker's caches (a sweep worker keeps one across tasks).
        """
        return cls(keep="answers", reuse=reuse, lump=lump, rewards="named", parses=parses,
                   workspace=workspace)

    def check(
        self, mission: MissionConfig | RenderedMission, *,
        progress: ProgressCallback | None = None,
    ) -> MissionReport:
        """Check *mission* (a config is rendered first) as :func:`check_mission` does."""
        if not isinstance(mission, RenderedMission):
            mission = RenderedMission.of(mission)
        model, props = _parsed(self.parses, mission)
        with placed_in_config(mission.config, props):
            run = self.session.check(model, props.properties, props_file=props,
                                     progress=progress,
                                     internal=(recharge_cap_property(mission.config),))
        return mission_report(mission.config, run)


def _parsed(parses: ParseCache, mission: RenderedMission) -> tuple[Model, PropertiesFile]:
    """*mission*'s model and properties, parsed, the properties validated against the
    model before anything is built."""
    model = parses.model(mission.model)
    parses.validate(mission.config, model)
    return model, parses.properties(mission.properties)


def mission_dtmc(cfg: MissionConfig, *, progress: ProgressCallback | None = None) -> DTMC:
    """Render *cfg* and build its DTMC, checking no property (for the analyses)."""
    files = mission_files(cfg)
    return check_model(parse_model(files.model, name=MODEL_FILE), (), progress=progress).dtmc


def reuse_key(mission: RenderedMission, parses: ParseCache | None = None) -> str | None:
    """A key equal for missions whose models may share one state space.

    Decided from the rendered model itself: the key digests the flattened model's
    variables, initial states, guards and assignments (every constant they use
    appears by value), and leaves out update probabilities, rewards and labels.
    Equal keys are necessary for re-use; a :class:`MissionSession` still falls back
    to a full build where a probability becomes 0 or 1. The mission MDP has no key.

    :param parses: the parse cache to use (a sweep asks for the keys of many similar
        missions in a row).
    """
    from veribattery.explore.reuse.structure import structure_key  # sweeps only

    if mission.is_mdp:
        return None  # an MDP's build is not re-used
    model = (parses or ParseCache()).model(mission.model)
    return structure_key(flatten_model(model))
