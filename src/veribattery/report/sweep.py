"""A sweep's results for the report: read, matched to the config, and where requirements turn.

A results file belongs to a config when the sweep was run on it: its fingerprint
(``RESULTS.sweep.json``, kept by ``veribattery sweep -o``) names the resolved base
config by SHA-256 and the ``--set`` strings it was loaded with. The report's config
file, loaded with those same strings, must give that digest, and every key the
sweep did not vary must equal the report's (the report may sit at any point of the
varied keys, e.g. ``--set battery.capacity_ah=12.8`` on a sweep over capacity).
Anything else is one line naming what differs, before any work is done.
"""

from __future__ import annotations

import itertools
import json
import math
import numbers
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd
import yaml

from veribattery.config import MissionConfig, config_to_yaml, load_config
from veribattery.errors import OptionError, VeribatteryError
from veribattery.sweep.fingerprint import SweepFingerprint, fingerprint, model_version
from veribattery.sweep.run import FIXED_COLUMNS
from veribattery.sweep.store import FORMATS, ResultsFileError, read_results

__all__ = ["Crossing", "SweepRequirement", "SweepResults", "read_sweep", "x_key"]

_OPTION = "--sweep"


@dataclass(frozen=True, slots=True)
class SweepRequirement:
    """A requirement of the config, as a line to draw on its property's sweep figure."""

    text: str
    prop: str
    op: str
    bound: float


@dataclass(frozen=True, slots=True)
class Crossing:
    """Where a requirement turns between two neighbouring points of one line of a sweep.

    :ivar line: the other varied keys' values (empty with one varied key).
    :ivar before: the x value where it last held (or failed).
    :ivar after: the next x value, where it fails (or holds again).
    :ivar stops: True when it stops holding, False when it holds again.
    """

    requirement: str
    prop: str
    line: str
    before: float
    after: float
    after_value: float
    stops: bool


@dataclass(frozen=True, slots=True)
class SweepResults:
    """A sweep's rows (as ``run_sweep`` returns them) and what the report says about them.

    :ivar name: the file as the user typed it.
    :ivar x: the varied key drawn on x (the first numeric one, as ``sweep --plot``).
    :ivar formulas: the config's formula of each property in the results.
    :ivar here: the report's own value of the x key (None: not a number).
    :ivar note: a caveat for the reader (another veribattery version made it), or empty.
    """

    name: str
    frame: pd.DataFrame = field(compare=False, repr=False)
    axes: tuple[str, ...]
    x: str
    properties: tuple[str, ...]
    formulas: tuple[tuple[str, str], ...]
    requirements: tuple[SweepRequirement, ...]
    crossings: tuple[Crossing, ...]
    points: int
    failed: int
    sets: tuple[str, ...]
    here: float | None
    note: str


def read_sweep(path: Path, config: Path | str, cfg: MissionConfig) -> SweepResults:
    """Read the results file *path* of a sweep of *config*, matched to the report's *cfg*.

    :param config: the report's config file (or YAML text), as given to ``load_config``.
    :param cfg: the report's config (*config* with the report's ``--set`` applied).
    :raises OptionError: the file is missing, unreadable, not a sweep's results, or a
        sweep of another config (naming the first key that differs).
    """
    mark = _fingerprint(path)
    axes = tuple(a.partition("=")[0] for a in mark.axes)
    _check_config(path, mark, config, cfg, axes)
    frame = _frame(path, axes)
    note = "" if mark.model == model_version() else (
        f"These results were computed by {mark.model}; this report by {model_version()}.")
    requirements = tuple(SweepRequirement(str(r), r.prop, r.op, float(r.bound))
                         for r in cfg.parsed_requirements)
    x = x_key(frame, axes)
    properties = tuple(str(p) for p in frame["property"].dropna().drop_duplicates())
    return SweepResults(
        name=str(path), frame=frame, axes=axes, x=x, properties=properties,
        formulas=tuple((p, cfg.properties[p]) for p in properties if p in cfg.properties),
        requirements=requirements, crossings=_crossings(frame, axes, x, requirements),
        points=int(frame["point"].nunique()),
        failed=int(frame.loc[frame["error"].notna(), "point"].nunique()),
        sets=mark.sets, here=_here(cfg, x), note=note,
    )


def _here(cfg: MissionConfig, key: str) -> float | None:
    """The report's own value of the varied key *key*, if a number."""
    value = _flat(cfg).get(key)
    return float(value) if isinstance(value, int | float) and _is_number(value) else None


def x_key(frame: pd.DataFrame, axes: Sequence[str]) -> str:
    """The first varied key whose values are all finite numbers, else the first."""
    return next((k for k in axes if all(_is_number(v) for v in frame[k])), axes[0])


def _is_number(value: object) -> bool:
    return (isinstance(value, numbers.Real) and not isinstance(value, bool)
            and math.isfinite(float(value)))


def _bad(path: Path, problem: str) -> OptionError:
    return OptionError(f"{_OPTION} {path}: {problem}")


def _fingerprint(path: Path) -> SweepFingerprint:
    """The sweep's fingerprint kept beside *path*, after checking *path* itself."""
    if not path.exists():
        raise _bad(path, "no such file")
    if not path.is_file():
        raise _bad(path, "is not a file")
    if path.suffix.lower() not in FORMATS:
        raise _bad(path, f"not a sweep's results file (expected {', '.join(FORMATS)})")
    meta = path.with_name(path.name + ".sweep.json")
    try:
        return SweepFingerprint.from_json(meta.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise _bad(path, f"no {meta.name} beside it, so it cannot be matched to the config "
                   "(keep the file that 'veribattery sweep -o' writes with it)") from None
    except OSError as exc:
        raise _bad(path, f"cannot read {meta.name}: {exc.strerror}") from None
    except (ValueError, KeyError, TypeError):
        raise _bad(path, f"{meta.name} is not a veribattery sweep fingerprint") from None


def _check_config(path: Path, mark: SweepFingerprint, config: Path | str, cfg: MissionConfig,
                  axes: Sequence[str]) -> None:
    """The sweep was run on *config* (with its own ``--set``), and agrees with *cfg* on
    every key it did not vary."""
    try:
        base = load_config(config, mark.sets)
    except VeribatteryError as exc:
        raise _bad(path, f"a sweep of another config: its --set {' '.join(mark.sets)} does "
                   f"not apply to this config ({exc.message})") from None
    if fingerprint(base, mark.sets, ()).config != mark.config:
        sets = f" with its --set {' '.join(mark.sets)}" if mark.sets else ""
        raise _bad(path, f"a sweep of another config: its base config differs from this "
                   f"config{sets} (SHA-256 {mark.config[:12]}…)")
    theirs, ours = _flat(base), _flat(cfg)
    for key in sorted(theirs.keys() | ours.keys()):
        if key == "sweep" or key.startswith("sweep.") or _varied(key, axes):
            continue
        if theirs.get(key) != ours.get(key):
            raise _bad(path, f"a sweep of another config: {key} is {_show(theirs.get(key))} "
                       f"there, {_show(ours.get(key))} here (only the varied keys "
                       f"{', '.join(axes) or '(none)'} may differ)")


def _varied(key: str, axes: Sequence[str]) -> bool:
    return any(key == a or key.startswith(a + ".") or a.startswith(key + ".") for a in axes)


def _flat(cfg: MissionConfig) -> dict[str, object]:
    """Every key of the resolved config, dotted (``battery.capacity_ah``) → value."""
    return dict(_walk(yaml.safe_load(config_to_yaml(cfg)), ""))


def _walk(node: object, prefix: str) -> Iterator[tuple[str, object]]:
    if isinstance(node, Mapping) and node:
        for key, value in node.items():
            yield from _walk(value, f"{prefix}.{key}" if prefix else str(key))
    else:
        yield prefix, node


def _show(value: object) -> str:
    return "unset" if value is None else json.dumps(value)


def _frame(path: Path, axes: Sequence[str]) -> pd.DataFrame:
    """The rows of *path* as ``run_sweep`` returns them, read and checked as a resumed
    sweep reads them (a cell the sweep did not write is refused, naming its line)."""
    expected = ["point", *axes, *FIXED_COLUMNS]
    try:
        rows = read_results(path, expected)
    except ResultsFileError as exc:
        raise _bad(path, exc.problem) from None
    except OSError as exc:
        raise _bad(path, f"cannot read it ({exc.strerror or exc})") from None
    if not rows:
        raise _bad(path, "holds no results yet (run the sweep to the end first)")
    frame = pd.DataFrame(rows, columns=expected).astype(object)
    frame = frame.where(frame.notna(), None)
    for key in axes:  # a CSV's axis cells are read back as text
        frame[key] = [_cell(v) for v in frame[key]]
    frame["holds"] = [_boolean(v) for v in frame["holds"]]
    frame["error"] = frame["error"].where(frame["error"].notna(), math.nan)
    return frame


def _cell(text: object) -> object:
    """An axis cell as the sweep wrote it: a number where it reads as one, else the text."""
    if not isinstance(text, str):
        return text
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def _boolean(value: object) -> bool | None:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return None
    return value in (True, "True", 1, 1.0)


def _crossings(frame: pd.DataFrame, axes: Sequence[str], x: str,
               requirements: Sequence[SweepRequirement]) -> tuple[Crossing, ...]:
    """Where the requirements on each property turn, along *x*, on each line (a sweep's
    ``holds`` is whether all of a property's requirements hold)."""
    if not all(_is_number(v) for v in frame[x]):
        return ()
    others = [a for a in axes if a != x]
    found: list[Crossing] = []
    for prop in dict.fromkeys(r.prop for r in requirements):
        text = " and ".join(r.text for r in requirements if r.prop == prop)
        rows = frame[(frame["property"] == prop) & frame["holds"].notna()]
        groups = rows.groupby(others, sort=False) if others else [((), rows)]
        for combo, line in groups:
            values = combo if isinstance(combo, tuple) else (combo,)
            name = ", ".join(f"{k}={v}" for k, v in zip(others, values, strict=True))
            found.extend(_turns(text, prop, name, line.sort_values(x), x))
    return tuple(found)


def _turns(text: str, prop: str, line: str, rows: pd.DataFrame, x: str) -> Iterator[Crossing]:
    points = list(zip(rows[x], rows["holds"], rows["value"], strict=True))
    for (x0, held, _), (x1, holds, value) in itertools.pairwise(points):
        if bool(held) != bool(holds):
            yield Crossing(text, prop, line, float(x0), float(x1),
                           float(value) if _is_number(value) else math.nan, bool(held))
