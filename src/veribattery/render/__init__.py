"""Config → PRISM model and properties text, from the Jinja templates in ``prism_templates/``:
BS1's DTMC, and the MDP of synthesis mode with its questions."""

from veribattery.render.render import render_model, render_properties, template_dir
from veribattery.render.synthesis import (
    FastestQuestion,
    SkippedRequirement,
    render_synthesis_model,
    render_synthesis_properties,
    synthesis_questions,
)

__all__ = [
    "FastestQuestion",
    "SkippedRequirement",
    "render_model",
    "render_properties",
    "render_synthesis_model",
    "render_synthesis_properties",
    "synthesis_questions",
    "template_dir",
]
