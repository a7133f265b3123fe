"""Physics when there is no data: PyBaMM discharge and ageing runs, written as PHM CSVs.

Needs the ``pybamm`` extra. Telemetry is switched off before PyBaMM is imported
(``PYBAMM_DISABLE_TELEMETRY``, and ``pybamm.telemetry.disable()``), and only built-in
parameter sets are used, so nothing is downloaded or sent at run time.

A pack is ``S`` cells in series and ``P`` in parallel: each cell delivers ``P_pack/(S·P)``
watts; the pack voltage is ``S`` times the cell's and its current ``P`` times the cell's.
"""

from __future__ import annotations

import math
import os
import shlex
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from veribattery._files import write_texts
from veribattery._types import FloatArray
from veribattery.phm.data import PhmDataError

__all__ = ["CYCLES_FILE", "DISCHARGE_FILE", "SEI_MODELS", "Pack", "Simulation", "simulate",
           "write_csvs"]

DISCHARGE_FILE = "discharge.csv"
CYCLES_FILE = "cycles.csv"
#: SEI growth submodels offered for the ageing experiment (PyBaMM option values); the
#: first, kinetics-limited growth, fades Chen2020 cells by ~0.015 %/cycle, close to the
#: ~20 % over 1000+ cycles reported for such cells.
SEI_MODELS = ("reaction limited", "solvent-diffusion limited", "ec reaction limited",
              "interstitial-diffusion limited")


@dataclass(frozen=True, slots=True)
class Pack:
    """A battery pack of identical cells, discharged at constant power."""

    parameter_set: str
    power_w: float
    series: int = 1
    parallel: int = 1
    sei: str = SEI_MODELS[0]

    @property
    def cell_power_w(self) -> float:
        """Power each cell delivers."""
        return self.power_w / (self.series * self.parallel)


@dataclass(frozen=True, slots=True)
class Simulation:
    """What a run produced: the discharge curve and, optionally, capacity per cycle."""

    pack: Pack
    time_s: FloatArray
    voltage_v: FloatArray
    current_a: FloatArray
    cycles: FloatArray | None
    capacity_ah: FloatArray | None


def _pybamm() -> ModuleType:
    """PyBaMM with telemetry off, or a one-line error naming the extra."""
    os.environ.setdefault("PYBAMM_DISABLE_TELEMETRY", "true")
    os.environ.setdefault("PYBAMM_OPTOUT_TELEMETRY", "true")
    try:
        import pybamm  # type: ignore[import-untyped, import-not-found, unused-ignore]
    except ImportError:
        raise PhmDataError("phm simulate needs PyBaMM: pip install 'veribattery[pybamm]'") from None
    telemetry = getattr(pybamm, "telemetry", None)
    if telemetry is not None and hasattr(telemetry, "disable"):
        telemetry.disable()
    pybamm.set_logging_level("CRITICAL")  # failures are reported as one line of ours
    module: ModuleType = pybamm
    return module


def _parameters(pybamm: ModuleType, name: str) -> Any:
    known = sorted(pybamm.parameter_sets.keys())
    if name not in known:
        raise PhmDataError(f"--parameter-set: unknown PyBaMM parameter set {name!r} "
                           f"(built in: {', '.join(known)})")
    return pybamm.ParameterValues(name)


def _discharge(pybamm: ModuleType, pack: Pack, period_s: float) -> tuple[FloatArray, ...]:
    params = _parameters(pybamm, pack.parameter_set)
    cutoff = params["Lower voltage cut-off [V]"]
    experiment = pybamm.Experiment(
        [f"Discharge at {_plain(pack.cell_power_w)} W until {cutoff} V"],
        period=f"{_plain(period_s)} seconds")
    solution = pybamm.Simulation(pybamm.lithium_ion.SPMe(), parameter_values=params,
                                 experiment=experiment).solve(initial_soc=1)
    time = np.asarray(solution["Time [s]"].entries, dtype=np.float64)
    voltage = np.asarray(solution["Voltage [V]"].entries, dtype=np.float64)
    current = np.asarray(solution["Current [A]"].entries, dtype=np.float64)
    if voltage[-1] > 1.01 * float(cutoff):  # PyBaMM stops a step after 24 h, emptied or not
        raise PhmDataError(f"--power-w {pack.power_w:g}: after {time[-1] - time[0]:g} s the "
                           f"cells are still at {voltage[-1]:.3g} V, above their {cutoff} V "
                           "cut-off: not a whole discharge; raise the power")
    return time - time[0], voltage * pack.series, current * pack.parallel


def _ageing(pybamm: ModuleType, pack: Pack, cycles: int) -> tuple[FloatArray, FloatArray]:
    """Capacity of each of *cycles* constant-power discharges, each after a CC-CV charge.

    One extra cycle runs first and is dropped: it starts from the parameter set's own
    full state rather than from the protocol's charge, so its capacity is not comparable.
    """
    params = _parameters(pybamm, pack.parameter_set)
    low, high = params["Lower voltage cut-off [V]"], params["Upper voltage cut-off [V]"]
    cycle = (f"Discharge at {_plain(pack.cell_power_w)} W until {low} V",
             f"Charge at 1C until {high} V", f"Hold at {high} V until C/20")
    model = pybamm.lithium_ion.SPM({"SEI": pack.sei})
    solution = pybamm.Simulation(model, parameter_values=params,
                                 experiment=pybamm.Experiment([cycle] * (cycles + 1),
                                                              period="5 minutes")
                                 ).solve(initial_soc=1)
    capacity = [_discharged(c.steps[0]) for c in solution.cycles[1:] if c is not None]
    return np.arange(1, len(capacity) + 1, dtype=np.float64), np.asarray(capacity) * pack.parallel


def _plain(value: float) -> str:
    """*value* for PyBaMM's experiment strings, which cannot read an exponent: ``1e+06 W``
    was read as ``1e`` watts and raised a ValueError."""
    return str(np.format_float_positional(value, precision=6, unique=False, fractional=False,
                                          trim="-"))


def _discharged(step: Any) -> float:
    drawn = np.asarray(step["Discharge capacity [A.h]"].entries, dtype=np.float64)
    return float(drawn[-1] - drawn[0])


@contextmanager
def _quiet_stderr() -> Iterator[None]:
    """Silence file descriptor 2 while SUNDIALS (C code) prints its own solver errors."""
    try:
        saved = os.dup(2)
    except OSError:  # no real stderr (embedded use): nothing to silence
        yield
        return
    with open(os.devnull, "w") as null:
        os.dup2(null.fileno(), 2)
        try:
            yield
        finally:
            os.dup2(saved, 2)
            os.close(saved)


def simulate(pack: Pack, cycles: int | None = None, period_s: float = 30.0) -> Simulation:
    """Discharge *pack* at constant power from full; with *cycles*, also age it.

    :raises PhmDataError: without PyBaMM, for an unknown parameter set, or when the
        solver fails (e.g. the power is more than the cells can give).
    """
    if not (math.isfinite(pack.power_w) and pack.power_w > 0):
        raise PhmDataError(f"--power-w: must be a number of watts > 0, got {pack.power_w:g}")
    if not (math.isfinite(period_s) and period_s >= 1):
        raise PhmDataError(f"--period-s: must be a number of seconds >= 1, got {period_s:g}")
    pybamm = _pybamm()
    try:
        with _quiet_stderr():
            time, voltage, current = _discharge(pybamm, pack, period_s)
            aged = _ageing(pybamm, pack, cycles) if cycles else (None, None)
    except pybamm.SolverError as exc:
        raise PhmDataError(f"PyBaMM could not solve the experiment at {pack.cell_power_w:g} W "
                           f"per cell ({str(exc).splitlines()[0]}); is --power-w more than the "
                           "cells can give? add cells in parallel or lower it") from None
    if len(time) < 3:
        raise PhmDataError(f"--power-w {pack.power_w:g}: the pack reaches its cut-off at "
                           "once; lower the power or add cells in parallel")
    return Simulation(pack, time, voltage, current, *aged)


def _header(argv: Sequence[str], what: str) -> str:
    return f"# {what}, made by PyBaMM with:\n# {shlex.join(argv)}\n"


def _rows(columns: Sequence[FloatArray]) -> str:
    return "".join(",".join(f"{v:.6g}" for v in row) + "\n" for row in zip(*columns, strict=True))


def write_csvs(sim: Simulation, directory: Path, argv: Sequence[str],
               force: bool = False) -> tuple[Path, ...]:
    """Write ``discharge.csv`` (and ``cycles.csv``) with the command line *argv* as a comment.

    The files are written all or nothing, with the modes ``open()`` would give them.

    :raises PhmDataError: when a file exists and not *force* (nothing is written then).
    """
    texts = {DISCHARGE_FILE: _header(argv, "constant-power discharge") +
             "time_s,voltage_v,current_a\n" + _rows([sim.time_s, sim.voltage_v, sim.current_a])}
    if sim.cycles is not None and sim.capacity_ah is not None:
        texts[CYCLES_FILE] = (_header(argv, f"ageing ({sim.pack.sei} SEI growth)") +
                              "cycle,capacity_ah\n" + _rows([sim.cycles, sim.capacity_ah]))
    targets = {directory / name: text for name, text in texts.items()}
    clashes = [str(p) for p in targets if p.exists()]
    if clashes and not force:
        raise PhmDataError(f"{', '.join(clashes)} already exist(s); use --force to overwrite")
    directory.mkdir(parents=True, exist_ok=True)
    write_texts(targets)
    return tuple(targets)
