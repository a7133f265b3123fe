"""Floating-point checks: a :class:`Session` checks one model after another and owns what
the checks share; :func:`check_model` checks one model alone."""

from __future__ import annotations

import functools
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

from veribattery._memory import trim_for
from veribattery.checker import Workspace, check
from veribattery.checker.ltl.cosafety import require_cosafe
from veribattery.errors import ArgumentError
from veribattery.explore import DTMC, build_compact_dtmc, build_dtmc
from veribattery.lang import (
    FlatModel,
    Model,
    PropertiesFile,
    Property,
    flatten_model,
    resolve_property,
    with_used_rewards,
)
from veribattery.lang.expressions import walk
from veribattery.lang.nodes import Expr, Filter, Ident, Value
from veribattery.pipeline.inputs import (
    parsed_model,
    parsed_properties,
    reject_unknown_constants,
)
from veribattery.pipeline.run import (
    STAGES,
    CheckOptions,
    ModelCheckRun,
    ProgressCallback,
    Rewards,
    Stopwatch,
    internal_results,
    may_hold,
    require_rewards,
    run_checks,
    stages_of,
    tell_building,
)
from veribattery.pipeline.stopping import stopping_condition

if TYPE_CHECKING:
    from veribattery.explore.reuse.lumping import Lumper
    from veribattery.explore.reuse.structure import Structure

__all__ = ["ReusingBuilder", "Rewards", "Session", "check_model"]


class ReusingBuilder:
    """Builds DTMCs one after another, re-using the last state space where it can.

    When a model shares the structure of the last model built in full (the same
    variables, guards and assignments; see :mod:`veribattery.explore.reuse.structure`), its
    probabilities, rewards and labels are evaluated on the known states instead of
    exploring them again; otherwise it is built in full and becomes the new base.
    """

    def __init__(self) -> None:
        self._base: tuple[DTMC, Structure] | None = None

    def build(self, flat: FlatModel, progress: ProgressCallback | None = None) -> tuple[DTMC, bool]:
        """The DTMC of *flat*, and whether it re-used the base's state space."""
        from veribattery.explore.reuse.structure import build_reusable, reevaluate  # reuse only

        if self._base is not None:
            dtmc = reevaluate(*self._base, flat)
            if dtmc is not None:
                return dtmc, True
        dtmc, structure = build_reusable(flat, progress=progress)
        self._base = (dtmc, structure)
        return dtmc, False


class Session:
    """Floating-point checks of one model after another, with fixed options.

    A sweep's task, a PHM recheck or a single check: the session owns what its checks
    share -- the last state space (*reuse*), the partitions of bisimulation quotients
    (*lump*) and the checker's workspace -- so that two sessions never influence each
    other's results.

    :param options: what each result keeps, and how a property without a value is
        reported.
    :param reuse: build through a :class:`ReusingBuilder`: a model that shares the
        structure of the last one built in full re-uses its state space.
    :param lump: check on the DTMC's bisimulation quotient when it has one worth
        checking on (:mod:`veribattery.explore.reuse.lumping`): the answers equal the
        DTMC's, their last bits aside. Only with ``keep="answers"``: a quotient has
        no values for the model's own states.
    :param rewards: ``"named"``: build only the reward structures the properties name
        (all of them when one is referred to by index or by default), for a caller that
        keeps values, not models (a sweep point).
    :param workspace: the checker's caches, shared by this session's checks (default:
        a new one, so the session's caches live and go with it).
    :raises ArgumentError: for *lump* without ``keep="answers"``, an unknown *rewards*,
        or *options* that are no :class:`CheckOptions`.
    """

    def __init__(self, options: CheckOptions | None = None, *, reuse: bool = True,
                 lump: bool = False, rewards: Rewards = "all",
                 workspace: Workspace | None = None) -> None:
        self.options = CheckOptions.given(options)
        if lump and self.options.keep != "answers":
            raise ArgumentError('lumping keeps answers only: give CheckOptions(keep="answers")')
        require_rewards(rewards)
        self.rewards = rewards
        self.builder = ReusingBuilder() if reuse else None
        self.lumper: Lumper | None = None
        if lump:  # sweeps only: a single check never imports lumping
            from veribattery.explore.reuse.lumping import Lumper

            self.lumper = Lumper()
        self.workspace = workspace if workspace is not None else Workspace()

    def __repr__(self) -> str:
        # What was chosen, not <object at 0x...>: a notebook with two sessions tells
        # them apart by their options.
        return (f"Session(options={self.options!r}, reuse={self.builder is not None}, "
                f"lump={self.lumper is not None}, rewards={self.rewards!r})")

    def check(
        self,
        model: Model,
        properties: Sequence[Property],
        *,
        props_file: PropertiesFile | None = None,
        constants: Mapping[str, Value | str] | None = None,
        progress: ProgressCallback | None = None,
        stopwatch: Stopwatch | None = None,
        internal: Sequence[Property] = (),
        stop_early: bool = False,
    ) -> ModelCheckRun:
        """Flatten *model*, build its DTMC and check each property at the initial states.

        :param props_file: the properties file the properties come from (its constants
            and labels), if any.
        :param constants: values of the model's and properties' undefined constants; a
            name that neither declares is an error.
        :param progress: told after each BFS layer of the build; a
            :class:`~veribattery.pipeline.CheckProgress` also hears the stages and how
            far each long solve is.
        :param internal: properties the caller reads (:attr:`ModelCheckRun.internal`)
            but does not report: checked after *properties* and together with them
            (shared linear systems, the quotient), answers only, never NaN. One that is
            ``P=? [ F a ]`` with an operator-free ``a`` that no state satisfies is 0
            without a check, and shapes neither the shared systems nor the quotient.
        :param stop_early: answers only, in a session that does not re-use state spaces:
            leave unexpanded the states where every property's value is known
            (:func:`~veribattery.pipeline.stopping.stopping_condition`), as Storm does.
        """
        model, properties = parsed_model(model), parsed_properties(properties)
        reject_unknown_constants(model, props_file, constants or {})
        watch = stopwatch or Stopwatch(*STAGES)
        stages = stages_of(progress)
        with watch.stage("parse"):
            flat = flatten_model(model, constants)
            resolved = [resolve_property(p, flat, props_file, constants) for p in properties]
            aside = [resolve_property(p, flat, props_file, constants) for p in internal]
            for prop in resolved:
                require_cosafe(prop.formula)  # refused before the build, not after it
            if self.rewards == "named":
                flat = with_used_rewards(flat, resolved + aside)
            stop = self._stop(flat, resolved + aside) if stop_early else None
        with watch.stage("build"):
            tell_building(stages)
            dtmc, reused = self._build(flat, progress, stop)
        live = [may_hold(dtmc, p) for p in aside]
        formulas = [p.formula for p in resolved] + [
            p.formula for p, may in zip(aside, live, strict=True) if may]
        quotient = None
        if self.lumper is not None:
            with watch.stage("lump"):
                quotient = _quotient(self.lumper, dtmc, formulas)
        checked = quotient if quotient is not None else dtmc
        checks = [functools.partial(check, checked, p, keep=self.options.keep,
                                    workspace=self.workspace)
                  for p in resolved]
        listener = stages.solving if stages is not None else None
        with watch.stage("check"), self.workspace.monitor.listening(listener):
            trim_for(dtmc.num_states)  # the builder's last temporaries, under the DTMC's
            if stages is not None:
                stages.starting("preparing the linear systems")
            self.workspace.prepare(checked, formulas)  # systems shared between the properties
            trim_for(dtmc.num_states)  # the pre-pass's freed temporaries
            results, undefined = run_checks(checks, resolved, checked, self.options, stages)
            aside_results = internal_results(checked, aside, live, self.workspace)
        return ModelCheckRun(dtmc, results, watch.seconds, dtmc.warnings + undefined, reused,
                             quotient, aside_results, self.workspace)

    def _stop(self, flat: FlatModel, properties: Sequence[Property]) -> Expr | None:
        """Where the build may stop for *properties*: only when answers alone are kept
        and no state space is re-used (a base must be whole)."""
        if self.builder is not None or self.options.keep != "answers":
            return None
        return stopping_condition(properties, flat)

    def _build(self, flat: FlatModel, progress: ProgressCallback | None,
               stop: Expr | None = None) -> tuple[DTMC, bool]:
        """*flat*'s DTMC, and whether it re-used an earlier state space."""
        if self.builder is not None:
            return self.builder.build(flat, progress)
        if self.options.keep == "answers":
            # Answers only, and the DTMC not kept as a re-using builder's base: nothing
            # does arithmetic on whole state rows, so the table can be narrow (65 -> 17
            # MB on the 11x11 mission), and is narrow from the start (528 -> 66 MB on
            # crowds 5/20, whose int64 table was the peak of the build).
            return build_compact_dtmc(flat, progress=progress, stop=stop), False
        return build_dtmc(flat, progress=progress), False


def check_model(
    model: Model,
    properties: Sequence[Property],
    *,
    props_file: PropertiesFile | None = None,
    constants: Mapping[str, Value | str] | None = None,
    progress: ProgressCallback | None = None,
    stopwatch: Stopwatch | None = None,
    options: CheckOptions | None = None,
    internal: Sequence[Property] = (),
    rewards: Rewards = "all",
    stop_early: bool = False,
) -> ModelCheckRun:
    """Flatten *model*, build its DTMC and check each property at the initial states, in
    floating point with certified bounds: :meth:`Session.check` in a session of its own.

    :param options: what each result keeps, and how a property without a value is
        reported (default: :class:`CheckOptions` ``()``).
    :param rewards: the reward structures built: ``"all"``, or ``"named"``, those the
        properties use (the DTMC's other structures are then missing or empty).
    """
    return Session(options, reuse=False, rewards=rewards).check(
        model, properties, props_file=props_file, constants=constants, progress=progress,
        stopwatch=stopwatch, internal=internal, stop_early=stop_early)


def _quotient(lumper: Lumper, dtmc: DTMC, formulas: Sequence[Expr]) -> DTMC | None:
    """*dtmc*'s quotient for *formulas*: it keeps apart what their atoms read (labels and
    rewards always; the variables they name). None if a formula filters over states (a
    count or sum over them would change) or names something else."""
    variables: set[str] = set()
    for formula in formulas:
        for node in walk(formula):
            if isinstance(node, Filter):
                return None
            if isinstance(node, Ident):
                if node.name not in dtmc.variable_names:
                    return None
                variables.add(node.name)
    return lumper.quotient(dtmc, sorted(variables))
