"""The facade: text → parse → semantics → build → check, timed stage by stage.

One typed entry point per way of checking a model, each with the options it can use::

    run = check_model(model, props)                      # floating point, certified bounds
    run = check_model_exact(model, props)                # exact rational arithmetic
    session = Session(CheckOptions(keep="answers"), reuse=True, lump=True, rewards="named")
    runs = [session.check(m, props) for m in models]     # many similar models (a sweep)

:class:`CheckOptions` says what each result keeps (``keep="states"`` or ``"answers"``)
and whether a property without a value is NaN; a :class:`Session` owns what successive
float checks share (the state space re-used, the quotients' partitions, the checker's
workspace), and lumping is refused unless only answers are kept. The ``prism`` command
and the Python API check a user's file through :func:`check_prism_file`; the mission
commands and sweeps check the model they rendered through the same functions, so a
generated mission model is checked by exactly the code that checks a user's own file.

Modules: :mod:`~veribattery.pipeline.run` (runs, options, the loop over properties),
:mod:`~veribattery.pipeline.session` (float checks), :mod:`~veribattery.pipeline.exact`
(exact checks), :mod:`~veribattery.pipeline.mdp` (MDPs),
:mod:`~veribattery.pipeline.mdp_exact` (MDPs in rationals),
:mod:`~veribattery.pipeline.undecided` (bounds the float interval cannot decide, settled
exactly), :mod:`~veribattery.pipeline.prism_file` (a user's file to results).

The modules are imported when a name is first read from this package: an MDP's check
does not import the DTMC session, and the ``prism`` command imports
:mod:`~veribattery.pipeline.prism_file` only.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from veribattery._lazy import lazy_exports

if TYPE_CHECKING:
    from veribattery.pipeline.exact import check_model_exact
    from veribattery.pipeline.prism_file import check_prism_file, select
    from veribattery.pipeline.run import (
        CheckOptions,
        CheckProgress,
        Keep,
        ModelCheckRun,
        ProgressCallback,
        Stopwatch,
    )
    from veribattery.pipeline.session import ReusingBuilder, Rewards, Session, check_model

_EXPORTS = {
    "veribattery.pipeline.exact": ("check_model_exact",),
    "veribattery.pipeline.prism_file": ("check_prism_file", "select"),
    "veribattery.pipeline.run": (
        "CheckOptions", "CheckProgress", "Keep", "ModelCheckRun", "ProgressCallback",
        "Stopwatch"),
    "veribattery.pipeline.session": ("ReusingBuilder", "Rewards", "Session", "check_model"),
}
__getattr__ = lazy_exports(__name__, _EXPORTS)


__all__ = [
    "CheckOptions",
    "CheckProgress",
    "Keep",
    "ModelCheckRun",
    "ProgressCallback",
    "ReusingBuilder",
    "Rewards",
    "Session",
    "Stopwatch",
    "check_model",
    "check_model_exact",
    "check_prism_file",
    "select",
]
