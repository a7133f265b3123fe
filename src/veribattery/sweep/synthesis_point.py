"""A sweep point in synthesis mode (``strategy.mode: synthesize``): the best return
policy's certified ``Pmax`` of success at that point.

The point's rows are ``p_success_max`` and the ends of its certified interval,
``p_success_max_lower`` and ``p_success_max_upper``. Each requirement of the config
that bounds P(success) from below (``p_success >= 0.99``) is judged on ``Pmax``: it
holds when some policy certainly meets it (the interval's lower end does), so an
undecided one counts as not holding, as in ``check``. Requirements that ask nothing of
the MDP (``synthesize`` says why) are the point's warnings.
"""

from __future__ import annotations

from collections.abc import Sequence

from veribattery.config import MissionConfig
from veribattery.lang.nodes import BOUND_RELATIONS
from veribattery.render import FastestQuestion, synthesis_questions
from veribattery.sweep.grid import Axis
from veribattery.sweep.point_result import SYNTHESIS_PROPERTIES, PointResult, PropertyValue
from veribattery.synthesis.model import Certified
from veribattery.synthesis.sweep_pmax import MissionPmax

__all__ = ["SYNTHESIS_PROPERTIES", "swept_properties", "synthesis_point"]


def synthesis_point(index: int, cfg: MissionConfig, answer: MissionPmax,
                    seconds: float) -> PointResult:
    """The result of the point *index* whose mission MDP gave *answer*."""
    value = answer.p_success_max
    questions, unasked = synthesis_questions(cfg)
    best, lower, upper = SYNTHESIS_PROPERTIES
    rows = (PropertyValue(best, value.value, *_requirements(questions, value)),
            PropertyValue(lower, value.lower, None, None),
            PropertyValue(upper, value.upper, None, None))
    skipped = tuple(f"{s.requirement} asks nothing of the MDP: {s.reason}" for s in unasked)
    return PointResult(index, rows, answer.size.states, answer.size.transitions, seconds,
                       warnings=skipped)


def _requirements(questions: Sequence[FastestQuestion],
                  value: Certified) -> tuple[str | None, bool | None]:
    """The requirements on P(success) as written, and whether some policy certainly
    meets them all (None: there are none)."""
    if not questions:
        return None, None
    met = all(BOUND_RELATIONS[q.op](value.lower, q.bound) for q in questions)
    return " and ".join(q.requirement for q in questions), met


def swept_properties(cfg: MissionConfig, axes: Sequence[Axis]) -> dict[str, str]:
    """The properties (name -> formula) a sweep of *cfg* over *axes* gives rows of: the
    config's at its BS1 points, :data:`SYNTHESIS_PROPERTIES` at its synthesis points."""
    modes: set[str] = {cfg.strategy.mode}
    for axis in axes:
        if axis.key == "strategy.mode":
            modes = {str(value) for value in axis.values}
    found = dict(cfg.properties) if modes - {"synthesize"} else {}
    return found | (SYNTHESIS_PROPERTIES if "synthesize" in modes else {})
