"""``synthesize --export-strategy``/``--export-induced``: the table's strategy (safest,
then fastest) as files other tools read.

The strategy is written as :mod:`veribattery.strategies` writes an MDP property's
(PRISM's actions form, or Storm's scheduler JSON by the suffix), and the DTMC it
induces likewise, with the three questions whose answers ``synthesize`` reports for
the strategy: ``P=? [ F "success" ]``, ``R{"mt"}=? [ F "done" ]`` and
``R{"rc"}=? [ F "done" ]`` (the MDP's own properties read the rewards up to
``"done"``), so that Storm, PRISM or ``veribattery prism`` can confirm them.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from veribattery.checker.mdp import MDP, Strategy
from veribattery.lang import FlatModel
from veribattery.strategies import (
    INDUCED_MODEL,
    INDUCED_PROPERTIES,
    induced_model_text,
    reached_under,
    strategy_text,
)
from veribattery.strategies import ChosenStrategy as ExportedStrategy
from veribattery.synthesis.optimal import ChosenStrategy

__all__ = ["INDUCED_QUESTIONS", "StrategyExport", "strategy_export_texts"]

#: The induced DTMC's properties: ``synthesize``'s name of each value and its question.
INDUCED_QUESTIONS = (
    ("p_success", 'P=? [ F "success" ]'),
    ("exp_mission_time", 'R{"mt"}=? [ F "done" ]'),
    ("exp_recharges", 'R{"rc"}=? [ F "done" ]'),
)


#: The strategy, as the induced model's header names it.
ABOUT = "veribattery synthesize's strategy (safest, then fastest)"


@dataclass(frozen=True, slots=True)
class StrategyExport:
    """Which files of the strategy to write (None: not that one).

    :ivar strategy_file: the strategy; ``.json`` Storm's scheduler, else PRISM's form.
    :ivar induced_dir: the folder of ``induced.prism`` and ``induced.props``.
    """

    strategy_file: Path | None = None
    induced_dir: Path | None = None


def strategy_export_texts(model: FlatModel, mdp: MDP, chosen: ChosenStrategy,
                          export: StrategyExport) -> dict[Path, str]:
    """The text of each file *export* asks for, of *chosen* on *mdp* (built from the
    flat *model*)."""
    strategy = Strategy(chosen.choices)
    exported = ExportedStrategy(None, strategy, mdp, model, reached_under(mdp, strategy),
                                about=ABOUT)
    texts: dict[Path, str] = {}
    if export.strategy_file is not None:
        texts[export.strategy_file] = strategy_text(exported, export.strategy_file)
    if export.induced_dir is not None:
        texts[export.induced_dir / INDUCED_MODEL] = induced_model_text(exported)
        texts[export.induced_dir / INDUCED_PROPERTIES] = _induced_properties(chosen)
    return texts


def _induced_properties(chosen: ChosenStrategy) -> str:
    """The strategy's three questions, each with the value ``synthesize`` found."""
    found = {"p_success": chosen.p_success.value,
             "exp_mission_time": chosen.exp_mission_time.value,
             "exp_recharges": chosen.exp_recharges.value}
    lines = ["// The values veribattery synthesize reports for its strategy (safest, then\n"
             "// fastest), which the induced DTMC in induced.prism should give:\n"]
    lines.extend(f"// {name} = {value!r}\n" for name, value in found.items())
    lines.extend(f'"{name}": {question};\n' for name, question in INDUCED_QUESTIONS)
    return "".join(lines)
