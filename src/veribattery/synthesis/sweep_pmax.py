"""``Pmax [ F "success" ]`` over many configs (a sweep's points), one MDP per distinct model.

The mission MDP leaves every decision of BS1 open, so it does not depend on
``strategy.safe_t`` (it is only named in the header comment): points that differ only
there share one MDP. Points are grouped by their rendered MDP text less its whole-line
comments — equal text, equal model, equal value — and each distinct model is built and
solved once, in a process pool when asked for more than one job.
"""

from __future__ import annotations

import multiprocessing
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor

from veribattery.checker.mdp import reach_probability
from veribattery.config import MissionConfig
from veribattery.explore.build.mdp import build_mdp
from veribattery.lang import flatten_model, parse_model
from veribattery.mission import MODEL_FILE
from veribattery.pipeline.mdp import as_checker_mdp
from veribattery.render import render_synthesis_model
from veribattery.synthesis.model import Certified

__all__ = ["pmax_of_configs", "pmax_of_model"]

#: Told ``(models solved, models in all)`` after each distinct model.
ModelsProgress = Callable[[int, int], None]


def pmax_of_model(text: str) -> Certified:
    """Certified ``Pmax [ F "success" ]`` at the initial state of the mission MDP *text*
    (as :func:`~veribattery.render.render_synthesis_model` writes it)."""
    model = parse_model(text, name=MODEL_FILE)
    mdp = as_checker_mdp(build_mdp(flatten_model(model)))
    return Certified.at_initial(mdp, reach_probability(mdp, mdp.labels["success"],
                                                        objective="max"))


def pmax_of_configs(cfgs: Sequence[MissionConfig], *, jobs: int = 1,
                    progress: ModelsProgress | None = None) -> list[Certified]:
    """Certified ``Pmax [ F "success" ]`` of each config in *cfgs*, in their order.

    :param jobs: worker processes (1: in this process).
    :param progress: told ``(models solved, models in all)`` after each distinct MDP.
    :raises VeribatteryError: when a config cannot be rendered, built or checked.
    """
    models: dict[str, str] = {}  # key -> the first text with it, in the configs' order
    keys = []
    for text in map(render_synthesis_model, cfgs):
        keys.append(_model_key(text))
        models.setdefault(keys[-1], text)
    values = _solve_all(list(models.values()), jobs, progress)
    solved = dict(zip(models, values, strict=True))
    return [solved[key] for key in keys]


def _model_key(text: str) -> str:
    """*text* without its whole-line comments: what the model checker reads of it."""
    return "\n".join(line for line in text.splitlines() if not line.lstrip().startswith("//"))


def _solve_all(texts: list[str], jobs: int,
               progress: ModelsProgress | None) -> list[Certified]:
    if jobs <= 1 or len(texts) <= 1:
        return [_told(pmax_of_model(text), i, len(texts), progress)
                for i, text in enumerate(texts, 1)]
    # spawn, as the sweep's pool: no forked copy of the parent's caches and threads
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(min(jobs, len(texts)), mp_context=context) as pool:
        return [_told(value, i, len(texts), progress)
                for i, value in enumerate(pool.map(pmax_of_model, texts), 1)]


def _told(value: Certified, done: int, total: int,
          progress: ModelsProgress | None) -> Certified:
    if progress is not None:
        progress(done, total)
    return value
