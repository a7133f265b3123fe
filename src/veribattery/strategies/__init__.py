"""Optimal strategies of MDP properties, for people and other tools.

The strategy of one checked property (:func:`choose_strategy`), written in PRISM's
``-exportstrat`` actions form or Storm's scheduler JSON (:func:`strategy_text`), and
the DTMC it induces as a PRISM model with its property (:func:`induced_model_text`,
:func:`induced_properties_text`), so that PRISM, Storm or ``veribattery prism`` can
confirm the optimum on it. :func:`export_strategy` writes them, all or nothing.

Memoryless deterministic strategies of unbounded ``Pmin``/``Pmax``/``Rmin``/``Rmax``
properties, and the randomised strategies with finite memory that attain a
``multi(...)`` answer (:mod:`~veribattery.strategies.randomised`,
:mod:`~veribattery.strategies.induced_multi`) are exported; step-bounded ones (their
strategy depends on the step, also ``C<=k`` in ``multi(...)``) are not.
"""

from veribattery.strategies.chosen import (
    DTMC_HAS_NO_STRATEGY,
    ChosenStrategy,
    choose_strategy,
    reached_under,
    refuse_hopeless_export,
)
from veribattery.strategies.export import export_strategy, strategy_files
from veribattery.strategies.formats import (
    prism_strategy_text,
    storm_scheduler_json,
    strategy_text,
)
from veribattery.strategies.induced import (
    INDUCED_MODEL,
    INDUCED_PROPERTIES,
    dtmc_property_text,
    induced_model_text,
    induced_properties_text,
)
from veribattery.strategies.induced_multi import (
    induced_multi_model_text,
    induced_multi_properties_text,
)
from veribattery.strategies.randomised import ChosenMulti, multi_strategy_text

__all__ = [
    "DTMC_HAS_NO_STRATEGY",
    "INDUCED_MODEL",
    "INDUCED_PROPERTIES",
    "ChosenMulti",
    "ChosenStrategy",
    "choose_strategy",
    "dtmc_property_text",
    "export_strategy",
    "induced_model_text",
    "induced_multi_model_text",
    "induced_multi_properties_text",
    "induced_properties_text",
    "multi_strategy_text",
    "prism_strategy_text",
    "reached_under",
    "refuse_hopeless_export",
    "storm_scheduler_json",
    "strategy_files",
    "strategy_text",
]
