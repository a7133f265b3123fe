"""Monte-Carlo estimates beside the exact values: ``simulate`` on the checked DTMC.

The runs are :func:`~veribattery.analyses.simulate.simulate`'s, with ``simulate``'s
seed and step limit, on the very DTMC the verdict was checked on; the exact value
beside each estimate is the verdict's.
"""

from __future__ import annotations

import math

from veribattery.analyses.simulate import Estimate, simulate
from veribattery.explore.dtmc import DTMC
from veribattery.pipeline import ModelCheckRun
from veribattery.report.data import EstimateRow, MonteCarlo
from veribattery.report.verdict import label

__all__ = ["monte_carlo"]


def monte_carlo(run: ModelCheckRun, dtmc: DTMC, *, runs: int, seed: int,
                max_steps: int) -> MonteCarlo:
    """Estimate *run*'s properties from *runs* simulated runs of *dtmc* (its DTMC)."""
    exact = {r.property.name or r.property.text: r.value for r in run.results
             if isinstance(r.value, float)}
    simulation = simulate(dtmc, [r.property for r in run.results], runs=runs, seed=seed,
                          max_steps=max_steps, exact=exact)
    return MonteCarlo(simulation.runs, simulation.seed, simulation.max_steps, simulation.steps,
                      tuple(_row(e) for e in simulation.estimates),
                      tuple(_skipped(s) for s in simulation.skipped),
                      tuple(w for w in simulation.warnings() if w not in simulation.skipped))


def _skipped(text: str) -> str:
    """``name: not simulated (why)`` as ``name (why)``: the page lists them after
    "Not simulated:" already."""
    name, found, reason = text.partition(": not simulated ")
    return f"{name} {reason}" if found else text


def _row(estimate: Estimate) -> EstimateRow:
    exact = None if estimate.exact is None or math.isnan(estimate.exact) else estimate.exact
    return EstimateRow(estimate.name, label(estimate.name), exact, estimate.estimate,
                       estimate.ci95, estimate.runs, estimate.undecided, not estimate.disagrees)
