"""Config → the mission as an MDP (model-spec.md, "Synthesis") and its questions.

The MDP template extends the DTMC's (``synthesis.prism.j2`` over ``model.prism.j2``): the
two models share every line but the drone's decisions. Each requirement that bounds
P(success) from below becomes the question of the fastest policy that meets it,
PRISM's ``multi(R{"mt"}min=? [ C ], P>=p [ F "success" ])``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from fractions import Fraction

from veribattery.config.params import derive_parameters
from veribattery.config.schema import MissionConfig, Requirement
from veribattery.render.render import _header, _render

__all__ = [
    "FastestQuestion",
    "SkippedRequirement",
    "render_synthesis_model",
    "render_synthesis_properties",
    "synthesis_questions",
]

SYNTHESIS_MODEL_TEMPLATE = "synthesis.prism.j2"
SYNTHESIS_PROPERTIES_TEMPLATE = "synthesis.props.j2"

#: P(success) as the config's properties may write it (whitespace aside): the paper's
#: ``P=?``, or ``Pmax=?``, which asks the same of a strategy.
_SUCCESS_FORMULAS = frozenset({'P=?[F"success"]', 'Pmax=?[F"success"]'})


@dataclass(frozen=True, slots=True)
class FastestQuestion:
    """The fastest policy whose P(success) meets *requirement*: ``P{op}{bound}``."""

    name: str
    requirement: str
    op: str
    bound: Fraction


@dataclass(frozen=True, slots=True)
class SkippedRequirement:
    """A requirement that asks no synthesis question, and why."""

    requirement: str
    reason: str


def render_synthesis_model(cfg: MissionConfig) -> str:
    """The PRISM MDP of *cfg*'s mission, whatever its ``strategy.mode``.

    :raises ConfigError: when the config's numbers overflow PRISM's integers.
    :raises RenderError: when the template fails.
    """
    return _render(SYNTHESIS_MODEL_TEMPLATE, p=derive_parameters(cfg),
                           config_lines=_header(cfg))


def render_synthesis_properties(cfg: MissionConfig) -> str:
    """The MDP's properties file: Pmax of success, the Rmin/Rmax bounds, and one ``multi``
    query per requirement on P(success) (the others listed as comments).

    :raises RenderError: when the template fails.
    """
    fastest, skipped = synthesis_questions(cfg)
    return _render(SYNTHESIS_PROPERTIES_TEMPLATE, fastest=fastest, skipped=skipped)


def synthesis_questions(
    cfg: MissionConfig,
) -> tuple[tuple[FastestQuestion, ...], tuple[SkippedRequirement, ...]]:
    """*cfg*'s requirements as fastest-policy questions, and those that ask none.

    A requirement asks one when its property is P(success) (``P=? [ F "success" ]``) and
    it bounds it from below by a probability: ``p_success >= 0.99`` asks for the fastest
    policy whose P(success) is at least 0.99. Questions are named ``fastest_<i>`` after
    the requirement's position in the config (from 1).
    """
    fastest: list[FastestQuestion] = []
    skipped: list[SkippedRequirement] = []
    for index, req in enumerate(cfg.parsed_requirements, start=1):
        reason = _not_a_question(req, cfg.properties[req.prop])
        if reason is None:
            fastest.append(FastestQuestion(f"fastest_{index}", str(req), req.op, req.bound))
        else:
            skipped.append(SkippedRequirement(str(req), reason))
    return tuple(fastest), tuple(skipped)


def _not_a_question(req: Requirement, formula: str) -> str | None:
    """Why *req* (on a property of *formula*) asks no synthesis question, or None."""
    if re.sub(r"\s+", "", formula) not in _SUCCESS_FORMULAS:
        return f'{req.prop} is {formula.strip()}, not P=? [ F "success" ]'
    if req.op not in (">=", ">"):
        return "an upper bound on P(success): aborting at once meets it"
    return None  # (a bound outside [0, 1] is refused when the config is read)
