"""What makes two sweeps the same sweep, so a RESULTS file is resumed only by its own sweep.

A fingerprint holds the resolved base config (every key, defaults filled in, ``--set``
applied, the ``sweep:`` section left out because the axes are kept on their own), the
``--set`` strings, the axes and the model version (veribattery's version and a digest of
the PRISM templates). It is kept beside the results as JSON.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from dataclasses import dataclass

from veribattery.config import MissionConfig, config_to_yaml
from veribattery.config.schema import SweepConfig
from veribattery.sweep.grid import Axis, yaml_text

__all__ = ["SweepFingerprint", "fingerprint", "model_version"]


@dataclass(frozen=True, slots=True)
class SweepFingerprint:
    """The identity of a sweep: base config digest, ``--set`` strings, axes, model version."""

    config: str
    sets: tuple[str, ...]
    axes: tuple[str, ...]
    model: str

    def as_json(self) -> str:
        """The fingerprint as one JSON object (what the ``.sweep.json`` file holds)."""
        return json.dumps({"veribattery_sweep": 1, "config_sha256": self.config,
                           "sets": list(self.sets), "axes": list(self.axes),
                           "model": self.model}, indent=2) + "\n"

    @classmethod
    def from_json(cls, text: str) -> SweepFingerprint:
        """Read :meth:`as_json` back.

        :raises ValueError: when *text* is not a sweep fingerprint.
        """
        data = json.loads(text)
        if not isinstance(data, dict) or data.get("veribattery_sweep") != 1:
            raise ValueError("not a veribattery sweep fingerprint")
        return cls(str(data["config_sha256"]), tuple(map(str, data["sets"])),
                   tuple(map(str, data["axes"])), str(data["model"]))

    def difference(self, other: SweepFingerprint) -> str | None:
        """What differs from *other* (the first of sets, axes, config, model), or None."""
        if self.sets != other.sets:
            return f"--set differs ({_listed(other.sets)} there, {_listed(self.sets)} here)"
        if self.axes != other.axes:
            return f"the axes differ ({_listed(other.axes)} there, {_listed(self.axes)} here)"
        if self.config != other.config:
            return "the resolved base config differs (a config value changed)"
        if self.model != other.model:
            return f"the model version differs ({other.model} there, {self.model} here)"
        return None


def fingerprint(
    base: MissionConfig, sets: Sequence[str], axes: Sequence[Axis]
) -> SweepFingerprint:
    """The fingerprint of sweeping *axes* over *base* (already loaded with *sets*)."""
    text = config_to_yaml(base.model_copy(update={"sweep": SweepConfig()}))
    return SweepFingerprint(
        hashlib.sha256(text.encode()).hexdigest(),
        tuple(sets),
        tuple(f"{a.key}={','.join(yaml_text(v) for v in a.values)}" for a in axes),
        model_version(),
    )


def model_version() -> str:
    """veribattery's version and a digest of the PRISM templates the model is rendered from."""
    from importlib.metadata import version

    from veribattery.render.render import template_dir

    digest = hashlib.sha256()
    for path in sorted(template_dir().iterdir()):
        if path.is_file():
            digest.update(path.name.encode() + b"\0" + path.read_bytes())
    return f"veribattery {version('veribattery')}, templates {digest.hexdigest()[:12]}"


def _listed(items: Sequence[str]) -> str:
    text = " ".join(items) or "none"
    return text if len(text) <= 80 else text[:77] + "..."
