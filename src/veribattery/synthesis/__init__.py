"""Synthesis: the mission as an MDP (model-spec.md, "Synthesis"), its files and questions."""

from veribattery.synthesis.files import synthesis_files, unasked_requirements

__all__ = ["synthesis_files", "unasked_requirements"]
