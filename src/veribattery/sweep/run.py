"""Run the mission pipeline at every grid point and collect one tidy DataFrame.

The frame has one row per grid point x property, with columns

``point``
    the 0-based index of the grid point (grid order: the first axis varies slowest);
*each axis key* (e.g. ``battery.capacity_ah``)
    the value at that point (lists such as ``farm.base`` as their YAML text, ``[0, 0]``);
``property``, ``value``
    the property's name and its value at the initial state;
``states``, ``transitions``
    the size of the point's DTMC;
``seconds``
    wall-clock seconds for the point (load, render, parse, build, check);
``requirement``, ``holds``
    the config's requirements on this property (joined by `` and ``) and whether all of
    them hold; ``None`` and ``<NA>`` when no requirement names the property;
``recharge_cap_probability``
    P[F rc=RC_MAX] at the point: the probability that the recharge cap cuts the mission;
``error``
    why the point could not be checked (its one row then has no property), else empty.

``frame.attrs["warnings"]`` holds the model warnings, each once with the points
concerned; ``frame.attrs["failed"]`` the number of points that failed.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import pandas as pd

from veribattery.config import ConfigDocument, MissionConfig, read_config
from veribattery.errors import ArgumentError, VeribatteryError
from veribattery.mission import ParseCache, RenderedMission, validate_properties
from veribattery.sweep.execute import Executor, open_executor
from veribattery.sweep.fingerprint import fingerprint
from veribattery.sweep.grid import Axis, Point, grid, point_values, yaml_text
from veribattery.sweep.point_result import point_properties
from veribattery.sweep.store import ResultsStore, Row, RowCheck, check_target, open_results
from veribattery.sweep.summary import counted, sweep_warnings
from veribattery.sweep.tasks import PointResult, plan_tasks

__all__ = [
    "FIXED_COLUMNS",
    "PointCallback",
    "SweepProgress",
    "any_requirement_fails",
    "describe_point",
    "records",
    "run_sweep",
    "wide",
]

#: Called with (points done, total points): once before the first, then after each.
SweepProgress = Callable[[int, int], None]

#: Called after each point with its result and its grid point (for per-point log lines).
PointCallback = Callable[[PointResult, Point], None]

#: The columns after the axis keys, in order.
FIXED_COLUMNS = ("property", "value", "states", "transitions", "seconds", "requirement", "holds",
                 "recharge_cap_probability", "error")


def run_sweep(
    config: str | Path,
    axes: Sequence[Axis],
    overrides: Sequence[str] = (),
    progress: SweepProgress | None = None,
    *,
    jobs: int = 1,
    scheduler: str | None = None,
    results: str | Path | None = None,
    force: bool = False,
    on_point: PointCallback | None = None,
    notes: Callable[[str], None] | None = None,
) -> pd.DataFrame:
    """Check the mission *config* at every point of the grid of *axes*.

    The config is read once, and every point's config validated (as
    :func:`~veribattery.config.load_config` would with the point's keys given by
    ``--set``), the RESULTS target checked and the scheduler reached before any point is
    checked or anything written, so bad input fails at once and leaves nothing behind.
    Each point still to check is rendered once, for its reuse key and its check.

    :param config: the config file (or YAML text, as
        :func:`~veribattery.config.load_config` takes).
    :param axes: the swept keys; their values override *overrides*.
    :param overrides: ``KEY=VALUE`` strings applied at every point (``--set``).
    :param progress: called with (points done, total points).
    :param jobs: worker processes (1: in this process); Dask workers for ``"local"``.
    :param scheduler: a Dask scheduler address ``tcp://HOST:PORT``, or ``"local"``.
    :param results: a ``.csv``, ``.jsonl`` or ``.parquet`` file: rows are appended as
        points finish, and a rerun resumes (the file must belong to this same sweep).
    :param force: start *results* afresh even if it holds another sweep's rows (or its
        ``RESULTS.sweep.json`` exists without them).
    :param on_point: called after each point checked.
    :param notes: called with one-line notes (points already done, reuse, executor).
    :raises ConfigError: on invalid configs (naming the point), a bad RESULTS target or
        an unreachable scheduler.
    :raises ArgumentError: when *axes* is not a sequence of :class:`Axis`, or *jobs* < 1.
    """
    _require_axes(axes)
    if jobs < 1:  # a pool of none would fail on the second point, with a ValueError
        raise ArgumentError(f"jobs must be at least 1 (1: in this process), got {jobs}")
    points = grid(axes)
    document = read_config(config, overrides)
    configs = [_at(document, point) for point in points]
    _check_properties(points, configs)
    columns = ["point", *(axis.key for axis in axes), *FIXED_COLUMNS]
    cells = [_cells(point) for point in points]
    if results is not None:
        check_target(Path(results), force=force)
    parses = ParseCache()  # the reuse keys' parses, and the checks' in this process
    with open_executor(jobs, scheduler, parses) as executor:
        store, earlier = None, {}
        if results is not None:
            mark = fingerprint(document.validate(), overrides, axes)
            names = [point_properties(cfg) for cfg in configs]
            store, rows = open_results(Path(results), columns, mark, force=force,
                                       check=_foreign_to(names))
            earlier = _by_point(rows, cells, names)
        sweep = _Sweep(points, configs, cells, store, earlier, parses)
        sweep.run(executor, jobs, progress, on_point, notes or (lambda _: None))
    return sweep.frame(columns)


def _require_axes(axes: object) -> None:
    """Refuse what a notebook might pass for *axes*: ``KEY=SPEC`` text, or one axis.

    :raises ArgumentError: naming the call that makes an :class:`Axis` of it.
    """
    if isinstance(axes, str | Axis):
        raise ArgumentError(f"axes: a list of axes is needed, not {axes!r}: give [axis], "
                            "each from veribattery.sweep.parse_axis('KEY=SPEC')")
    for number, axis in enumerate(axes if isinstance(axes, Sequence) else [axes]):
        if not isinstance(axis, Axis):
            text = axis if isinstance(axis, str) else "KEY=SPEC"
            raise ArgumentError(f"axes[{number}] is {axis!r}, not an Axis: give "
                                f"veribattery.sweep.parse_axis({text!r})")


class _Sweep:
    """One sweep's state: every point's rows so far, and the new results."""

    def __init__(self, points: list[Point], configs: list[MissionConfig], cells: list[Row],
                 store: ResultsStore | None, earlier: dict[int, list[Row]],
                 parses: ParseCache):
        self.points, self.configs, self.cells, self.store = points, configs, cells, store
        self.rows = earlier
        self.results: list[tuple[Point, PointResult]] = []
        #: Where the reuse keys are parsed (the executor's in-process checks share it).
        self.parses = parses

    def run(self, executor: Executor, jobs: int, progress: SweepProgress | None,
            on_point: PointCallback | None, notes: Callable[[str], None]) -> None:
        total = len(self.points)
        cut = [i for i, rows in self.rows.items() if not rows]
        for index in cut:
            del self.rows[index]
        done = {i for i, rows in self.rows.items() if rows[0]["error"] is None}
        if done or cut:
            notes(_resumed(len(done), total, len(self.rows) - len(done), len(cut)))
        pending = [(i, RenderedMission.of_point(c)) for i, c in enumerate(self.configs)
                   if i not in done]
        whole = list(enumerate(self.configs)) if done else None
        tasks, plan = plan_tasks(pending, jobs, whole, self.parses)
        if pending:
            notes(f"{plan.describe()}; running {executor.describe(tasks)}")
        if progress is not None:
            progress(len(done), total)
        try:
            for result in executor.results(tasks):
                self._record(result)
                if progress is not None:
                    progress(len(done) + len(self.results), total)
                if on_point is not None:
                    on_point(result, self.points[result.index])
        except BaseException:
            if self.store is not None:
                self.store.close()
            raise
        if self.store is not None:
            self.store.finish(row for i in sorted(self.rows) for row in self.rows[i])

    def _record(self, result: PointResult) -> None:
        rows = point_rows(result, self.cells[result.index])
        if self.store is not None:
            self.store.append(rows)
        self.rows[result.index] = rows
        self.results.append((self.points[result.index], result))

    def frame(self, columns: list[str]) -> pd.DataFrame:
        rows = [row for i in sorted(self.rows) for row in self.rows[i]]
        frame = pd.DataFrame(rows, columns=columns)
        frame["holds"] = frame["holds"].astype("boolean")
        frame.attrs["warnings"] = sweep_warnings(self.results, frame, self.points)
        frame.attrs["failed"] = int(frame.loc[frame["error"].notna(), "point"].nunique())
        return frame


def point_rows(result: PointResult, cells: Row) -> list[Row]:
    """The tidy rows of one point: one per property, or one carrying the point's error."""
    common: Row = {"states": result.states, "transitions": result.transitions,
                   "seconds": result.seconds,
                   "recharge_cap_probability": result.recharge_cap_probability,
                   "error": result.error}
    if result.error is not None:
        return [{"point": result.index, **cells, "property": None, "value": None,
                 "requirement": None, "holds": None, **common}]
    return [{"point": result.index, **cells, "property": v.name, "value": v.value,
             "requirement": v.requirement, "holds": v.holds, **common} for v in result.values]


def _resumed(done: int, total: int, failed: int, cut: int) -> str:
    """``3 of 5 points already done; 1 failed point is retried; ...``."""
    text = f"{done} of {total} points already done"
    if failed:
        text += f"; {counted(failed, 'failed point')} {_be(failed)} retried"
    if cut:
        text += (f"; {counted(cut)} with rows missing from the results "
                 f"{_be(cut)} checked again")
    return text


def _be(count: int) -> str:
    return "is" if count == 1 else "are"


def _foreign_to(names: Sequence[tuple[str, ...]]) -> RowCheck:
    """Why a row read back is not one of this sweep's, whose point *i* has a row for each
    of ``names[i]`` (or one error row): a point outside the grid, a property not the
    point's."""

    def foreign(row: Row) -> str | None:
        index = row["point"]
        if not isinstance(index, int) or not 0 <= index < len(names):
            return f"point {index} is not one of this sweep's {len(names)}"
        name = row["property"]
        if name is None:
            return None if row["error"] is not None else "neither a property nor an error"
        return None if name in names[index] else f"point {index} has no property {name!r}"

    return foreign


def _by_point(rows: list[Row], cells: list[Row],
              names: Sequence[tuple[str, ...]]) -> dict[int, list[Row]]:
    """Earlier rows by point: a point's rows when each of its properties ``names[i]`` has
    one (the last written), else its last error row; an empty list for a point some
    of whose rows are missing (a results file cut short, or a row deleted): it is
    checked again, as if it had never run.

    Axis cells are taken from the grid rather than the file, so they have their types.
    """
    values: dict[int, dict[object, Row]] = {}
    found: dict[int, list[Row]] = {}
    for row in rows:
        index = int(row["point"])  # type: ignore[call-overload]
        row = {**row, "point": index, **cells[index]}
        if row["property"] is None:
            found[index] = [row]
        else:
            values.setdefault(index, {})[row["property"]] = row
    for index, by_name in values.items():
        if all(name in by_name for name in names[index]):
            found[index] = [by_name[name] for name in names[index]]
        else:
            found.setdefault(index, [])
    return found


def _cells(point: Point) -> Row:
    return {key: yaml_text(v) if isinstance(v, tuple) else v for key, v in point.items()}


def _at(document: ConfigDocument, point: Point) -> MissionConfig:
    """The validated config of *point*; an error names the point."""
    try:
        return document.with_values(point_values(point)).validate()
    except VeribatteryError as exc:
        if not point:
            raise
        raise type(exc)(f"at {describe_point(point)}: {exc.message}", exc.span) from None


def _check_properties(points: list[Point], configs: list[MissionConfig]) -> None:
    """Refuse, before any point is checked, a property that does not parse or names what
    the model lacks (as ``check`` does): it is bad input, not a failure of every point.

    Each distinct set of properties is resolved once, against the first BS1 point's model
    that has it (a synthesis point asks its MDP for Pmax, not the config's properties).
    """
    seen: set[tuple[tuple[str, str], ...]] = set()
    for point, cfg in zip(points, configs, strict=True):
        key = tuple(cfg.properties.items())
        if cfg.strategy.mode != "bs1" or key in seen:
            continue
        seen.add(key)
        try:
            validate_properties(cfg)
        except VeribatteryError as exc:
            if not any(name.startswith("properties") for name in point):
                raise
            raise type(exc)(f"at {describe_point(point)}: {exc.message}", exc.span) from None


def describe_point(point: Point) -> str:
    """``key=value, key=value`` for messages."""
    return ", ".join(f"{key}={yaml_text(value)}" for key, value in point.items()) or "the config"


def any_requirement_fails(frame: pd.DataFrame) -> bool:
    """True when some requirement fails at some point of a :func:`run_sweep` frame."""
    return bool(frame["holds"].eq(False).any())


def wide(frame: pd.DataFrame, keys: Sequence[str]) -> pd.DataFrame:
    """One row per point: the axis keys, one column per property (in config order), sizes.

    A ``requirements`` column (``PASS``/``FAIL``) is added when the config has requirements.
    """
    first = frame.drop_duplicates("point").set_index("point")
    result = first[[*keys, "states", "transitions"]].copy()
    for name in frame["property"].dropna().drop_duplicates():  # a failed point has none
        rows = frame[frame["property"] == name].set_index("point")
        result[name] = rows["value"]
    judged = frame.dropna(subset=["holds"])
    if not judged.empty:
        holds = judged.groupby("point")["holds"].all()
        result["requirements"] = holds.map({True: "PASS", False: "FAIL"})
    return result.reset_index(drop=True)


def records(frame: pd.DataFrame) -> list[dict[str, object]]:
    """The rows as plain Python dicts (missing values as ``None``), ready for JSON."""
    plain = frame.astype(object).where(frame.notna(), None)
    return [dict(row) for row in plain.to_dict("records")]
