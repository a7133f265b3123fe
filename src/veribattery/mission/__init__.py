"""The mission facade: config → rendered PRISM text → the same pipeline as any user file.

::

    report = check_mission(load_config("configs/paper/case1.yaml"))
    report.values["p_success"], report.recharge_cap_probability

    session = MissionSession.for_sweep(lump=True)    # many configs of one structure
    reports = [session.check(RenderedMission.of(cfg)) for cfg in configs]

Modules: :mod:`~veribattery.mission.session` (checks: :func:`check_mission`,
:class:`MissionSession`), :mod:`~veribattery.mission.report` (what a check reports:
values, requirements, the recharge cap's probability), :mod:`~veribattery.mission.files`
(the files ``emit`` writes, and the check of a config's properties against its model),
:mod:`~veribattery.mission.parses` (the last texts parsed, for sweeps).
"""

from veribattery.mission.files import (
    CONFIG_FILE,
    EMITTED_FILES,
    MODEL_FILE,
    PROPERTIES_FILE,
    STORM_ONLY_FILE,
    MissionFiles,
    is_storm_only,
    mission_files,
    validate_properties,
    write_files,
)
from veribattery.mission.parses import ParseCache
from veribattery.mission.report import (
    CAP_CONSEQUENCE,
    RECHARGE_CAP,
    RECHARGE_CAP_WARN_AT,
    MissionReport,
    RequirementOutcome,
    is_conditional,
    mission_report,
    recharge_cap_message,
    recharge_cap_property,
)
from veribattery.mission.session import (
    MissionSession,
    RenderedMission,
    check_mission,
    mission_dtmc,
    reuse_key,
)

__all__ = [
    "CAP_CONSEQUENCE",
    "CONFIG_FILE",
    "EMITTED_FILES",
    "MODEL_FILE",
    "PROPERTIES_FILE",
    "RECHARGE_CAP",
    "RECHARGE_CAP_WARN_AT",
    "STORM_ONLY_FILE",
    "MissionFiles",
    "MissionReport",
    "MissionSession",
    "ParseCache",
    "RenderedMission",
    "RequirementOutcome",
    "check_mission",
    "is_conditional",
    "is_storm_only",
    "mission_dtmc",
    "mission_files",
    "mission_report",
    "recharge_cap_message",
    "recharge_cap_property",
    "reuse_key",
    "validate_properties",
    "write_files",
]
