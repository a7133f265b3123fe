"""Config → PRISM model and properties text, from the Jinja templates in ``prism_templates/``."""

from veribattery.render.render import render_model, render_properties, template_dir

__all__ = ["render_model", "render_properties", "template_dir"]
