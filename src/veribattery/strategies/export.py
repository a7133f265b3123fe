"""Writing a run's strategy files: the strategy and the induced DTMC, all or nothing."""

from __future__ import annotations

from pathlib import Path

from veribattery._files import write_texts
from veribattery.pipeline.mdp import MdpCheckRun
from veribattery.strategies.chosen import ChosenStrategy, choose_strategy
from veribattery.strategies.formats import strategy_text
from veribattery.strategies.induced import (
    INDUCED_MODEL,
    INDUCED_PROPERTIES,
    induced_model_text,
    induced_properties_text,
)
from veribattery.strategies.induced_multi import (
    induced_multi_model_text,
    induced_multi_properties_text,
)
from veribattery.strategies.randomised import ChosenMulti, multi_strategy_text

__all__ = ["export_strategy", "strategy_files"]


def strategy_files(chosen: ChosenStrategy | ChosenMulti, strategy_file: Path | None,
                   induced_dir: Path | None) -> dict[Path, str]:
    """The text of each file asked for: the strategy (format by suffix, see
    :mod:`~veribattery.strategies.formats`, or :mod:`~veribattery.strategies.randomised`
    for a ``multi(...)`` property's) and the induced model and properties."""
    texts: dict[Path, str] = {}
    if strategy_file is not None:
        texts[strategy_file] = (multi_strategy_text(chosen, strategy_file)
                                if isinstance(chosen, ChosenMulti)
                                else strategy_text(chosen, strategy_file))
    if induced_dir is not None:
        texts[induced_dir / INDUCED_MODEL], texts[induced_dir / INDUCED_PROPERTIES] = (
            _induced_texts(chosen))
    return texts


def _induced_texts(chosen: ChosenStrategy | ChosenMulti) -> tuple[str, str]:
    """The induced DTMC's model and properties texts."""
    if isinstance(chosen, ChosenMulti):
        return induced_multi_model_text(chosen), induced_multi_properties_text(chosen)
    return induced_model_text(chosen), induced_properties_text(chosen)


def export_strategy(run: MdpCheckRun, *, selector: str | None = None,
                    strategy_file: Path | None = None,
                    induced_dir: Path | None = None) -> tuple[Path, ...]:
    """Write the strategy of the property *selector* names (see
    :func:`~veribattery.strategies.choose_strategy`) and/or its induced DTMC.

    Every text is made before any file is written, and the files are replaced all
    at once (:func:`veribattery._files.write_texts`): an error leaves none. Existing
    files are overwritten; refusing them is the caller's choice.

    :return: the paths written.
    :raises NoStrategyError: the property has no strategy to export.
    """
    texts = strategy_files(choose_strategy(run, selector), strategy_file, induced_dir)
    if induced_dir is not None:
        induced_dir.mkdir(parents=True, exist_ok=True)
    write_texts(texts)
    return tuple(texts)
