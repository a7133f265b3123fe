"""The witness strategy of a ``multi(...)`` answer: randomised, with finite memory,
and checked on the chain it induces before anyone sees it.

A multi-objective optimum (or a strategy meeting several bounds at once) may need
both randomisation and memory. The memory here is

* one *visited* bit per reachability objective, set on entering a state of its
  target (the product of :mod:`~veribattery.checker.mdp.multi`), and
* a *mode*, running or stopped, wherever a run has to stay forever in a
  zero-reward end component with some probability and leave it with the rest:
  once stopped, the strategy takes one choice per state that keeps the run in the
  component. A component that is never left, or never stayed in, needs no mode.

In a running memory state the strategy takes each choice (or stops) with
probability proportional to its flow (:mod:`~veribattery.checker.mdp.multi_strategy_flow`).
The chain the strategy induces has one state per memory state reached (*nodes*:
MDP state, visited bits, mode); every objective is solved on it with the DTMC
engine, certified (:mod:`~veribattery.checker.mdp.multi_strategy_check`), and the
strategy is returned only if each bounded objective is met and the optimised one
equals the reported optimum, each within
:data:`~veribattery.checker.mdp.multi.LP_TOLERANCE` (relative, absolute below 1):
the programme behind it is solved in floating point, so a strategy is never more
exact than that. Objectives over ``C<=k`` (whose strategy also needs the step
count) are refused, as is a query no strategy meets.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import partial

import numpy as np
import scipy.sparse as sp

from veribattery._types import BoolArray, CsrMatrix, FloatArray, IntArray
from veribattery.checker.mdp.formula import _mask
from veribattery.checker.mdp.graph import reached_from
from veribattery.checker.mdp.model import MDP
from veribattery.checker.mdp.multi_formula import (
    _constraint,
    _Goal,
    _goals,
    _towards,
)
from veribattery.checker.mdp.multi_strategy_check import (
    ObjectiveValue,
    Reported,
    verified_values,
)
from veribattery.checker.mdp.multi_strategy_flow import (
    Flows,
    WitnessFailed,
    uncollapsed,
    witness_flows,
)
from veribattery.checker.mdp.witness import NoStrategyError, strategy_refusal
from veribattery.lang.nodes import Multi, ProbOp

__all__ = ["MultiStrategy", "multi_strategy"]

#: Expected uses, in all, on states the strategy never reaches, beyond which the
#: programme's solution is refused as unattained (far above HiGHS's crumbs).
UNREACHED = 1e-6

#: A probability below this share of a state's flow is dropped (and the rest
#: renormalised): HiGHS leaves crumbs of the order of its tolerances.
NEGLIGIBLE = 1e-12


@dataclass(frozen=True, slots=True)
class MultiStrategy:
    """A randomised strategy with finite memory, and the chain it induces.

    The chain's states (*nodes*) are the memory states reached from the initial one:
    an MDP state, the visited bits, the mode. Per node the strategy's *moves*: a
    choice, its probability, and whether the memory switches to stopped with it.

    :param mdp: the MDP the strategy acts on.
    :param targets: the number of visited bits (bit *i*: the *i*-th reachability
        objective's target has been entered).
    :param node_state: per node, the MDP state.
    :param node_visited: per node, the visited bits (bit *i* is ``1 << i``).
    :param node_stopped: per node, whether the memory is in the stopped mode.
    :param initial: the initial node.
    :param move_ptr: per node, the offsets of its moves in the ``move_*`` arrays.
    :param move_choice: the MDP choice of each move.
    :param move_probability: the probability of each move (per node summing to 1).
    :param move_stops: whether the move switches the memory to stopped.
    :param chain: the induced DTMC over the nodes (row-stochastic).
    :param values: each objective's value on the chain (:class:`ObjectiveValue`).
    """

    mdp: MDP
    targets: int
    node_state: IntArray
    node_visited: IntArray
    node_stopped: BoolArray
    initial: int
    move_ptr: IntArray
    move_choice: IntArray
    move_probability: FloatArray
    move_stops: BoolArray
    chain: CsrMatrix
    values: tuple[ObjectiveValue, ...] = ()

    @property
    def num_nodes(self) -> int:
        """The number of memory states reached (states of the induced chain)."""
        return int(self.node_state.size)

    @property
    def has_mode(self) -> bool:
        """Whether the memory needs the running/stopped mode at all."""
        return bool(self.node_stopped.any() or self.move_stops.any())

    def moves(self, node: int) -> range:
        """The positions of *node*'s moves in the ``move_*`` arrays."""
        return range(int(self.move_ptr[node]), int(self.move_ptr[node + 1]))

    def expected_rewards(self, per_choice: FloatArray) -> FloatArray:
        """Per node, the expected reward of its step (*per_choice* per MDP choice)."""
        weights = self.move_probability * per_choice[self.move_choice]
        owner = np.repeat(np.arange(self.num_nodes), np.diff(self.move_ptr))
        return np.asarray(np.bincount(owner, weights=weights, minlength=self.num_nodes),
                          dtype=np.float64)


def multi_strategy(mdp: MDP, query: Multi, reported: object,
                   enclosure: tuple[float, float] | None = None) -> MultiStrategy:
    """A strategy that attains *reported*, the checked answer of *query* on *mdp*
    (True for achievability, the optimum of a numerical query), verified on its
    induced chain (see the module's description).

    :param enclosure: the certified interval of the optimum, when the check has one.
    :raises NoStrategyError: a ``C<=k`` objective, an answer no strategy attains (false,
        NaN, infinite, undecided), several initial states, or a strategy that fails
        its check (the message says which objective, by how much).
    """
    if mdp.initial.size != 1:
        raise NoStrategyError("no strategy: multi(...) needs a single initial state",
                              query.span)
    _refuse_steps(query)
    _refuse_answer(query, reported)
    goals, _ = _goals(mdp, query, partial(_mask, mdp, None))
    try:
        flows = _flows(mdp, goals)
    except WitnessFailed as exc:
        raise NoStrategyError(f"no strategy: {exc}", query.span) from None
    strategy = _strategy(mdp, flows)
    if _stray(flows, strategy) > UNREACHED:  # a paying cycle inside a resting class
        flows = uncollapsed(flows, spread=True)
        strategy = _strategy(mdp, flows)
    _refuse_unreached(flows, strategy, query)
    values = verified_values(strategy.chain, strategy.initial, strategy.node_state,
                             strategy.expected_rewards, goals,
                             Reported(reported, enclosure, flows.optimum))
    return replace(strategy, values=values)


def _refuse_steps(query: Multi) -> None:
    refusal = strategy_refusal(query)
    if refusal is not None:
        raise refusal


def _refuse_answer(query: Multi, reported: object) -> None:
    """Only a true achievability query or a finite optimum has a strategy to show."""
    if isinstance(reported, bool | np.bool_):
        if not reported:
            raise NoStrategyError("no strategy: no strategy meets every objective of "
                                  "multi(...) (it is false)", query.span)
        return
    if not isinstance(reported, float | int) or not np.isfinite(reported):
        raise NoStrategyError(f"no strategy: the optimum of multi(...) is {reported} "
                              "(undefined or infinite), which no strategy attains",
                              query.span)


def _stray(flows: Flows, strategy: MultiStrategy) -> float:
    """The flow, in all, on product states that no running memory state reaches."""
    pm = flows.product.mdp
    width = 1 << flows.targets
    running = ~strategy.node_stopped
    codes = strategy.node_state[running] * width + strategy.node_visited[running]
    reached = np.zeros(pm.num_states, dtype=bool)
    reached[np.searchsorted(flows.product.codes, codes)] = True
    return float(flows.out_of[~reached].sum(initial=0.0))


def _refuse_unreached(flows: Flows, strategy: MultiStrategy, query: Multi) -> None:
    """Flow on a state no run of the strategy reaches is a circulation the programme
    counts and its strategy never collects (rewards in a cycle fed by no path, outside
    the resting classes, where spreading cannot feed it): the programme counts a value
    that this strategy does not attain."""
    stray = _stray(flows, strategy)
    if stray > UNREACHED:
        raise NoStrategyError(
            "no strategy exported: the linear programme's solution puts expected uses "
            f"(in all {stray:.3g}) on states its strategy never reaches -- rewards "
            "collected in a cycle that no path feeds -- so its strategy does not attain it "
            "(such an optimum may be approached by strategies and attained by none)",
            query.span)


def _flows(mdp: MDP, goals: list[_Goal]) -> Flows:
    """The witness flows of the query's constraints and its optimised objective."""
    constraints = [_constraint(goal) for goal in goals if goal.op.op != "=?"]
    queried = [goal for goal in goals if goal.op.op == "=?"]
    quantities = [goal.quantity for goal in goals]
    if not queried:
        return witness_flows(mdp, quantities, constraints, None, "max")
    goal = queried[0]
    if goal.op.direction is None:  # the check refused it already
        name = "P" if isinstance(goal.op, ProbOp) else "R"
        raise WitnessFailed(f"the =? objective needs a direction ({name}min=? or {name}max=?)")
    return witness_flows(mdp, quantities, constraints, goal.quantity,
                         _towards(goal.op.direction, goal.sign))


def _strategy(mdp: MDP, flows: Flows) -> MultiStrategy:
    """The strategy of *flows* over the memory states reached from the initial one."""
    pm = flows.product.mdp
    n, m = pm.num_states, pm.num_choices
    moves = _move_matrix(flows)
    blocks = sp.csr_matrix(sp.block_diag([pm.transitions, pm.transitions]))
    chain = sp.csr_matrix(moves @ blocks)
    reached = reached_from(chain, flows.product.initial)
    chain = sp.csr_matrix(chain[reached][:, reached])
    chosen = sp.csr_matrix(moves[reached])
    chosen.sort_indices()
    width = 1 << flows.targets
    codes = flows.product.codes[reached % n]
    original = pm.states[:, 0] if pm.states is not None else np.arange(m)
    columns = chosen.indices.astype(np.int64)
    return MultiStrategy(
        mdp, flows.targets, codes // width, codes % width, reached >= n,
        int(np.searchsorted(reached, flows.product.initial)),
        chosen.indptr.astype(np.int64), original[columns % m].astype(np.int64),
        np.asarray(chosen.data, dtype=np.float64), columns >= m, chain)


def _move_matrix(flows: Flows) -> sp.csr_matrix:
    """Memory states (running: product state *p*; stopped: ``n + p``) by moves (choice
    *a* keeping the mode: *a*; choice *a* switching to stopped: ``m + a``)."""
    pm = flows.product.mdp
    n, m = pm.num_states, pm.num_choices
    total = flows.out_of
    owner = pm.choice_owner
    share = np.divide(flows.uses, total[owner], out=np.zeros(m), where=total[owner] > 0)
    taken = share > NEGLIGIBLE
    rows, cols, probs = [owner[taken]], [np.flatnonzero(taken)], [share[taken]]
    resting = flows.resting >= 0
    stay = np.divide(flows.stays, total, out=np.zeros(n), where=total > 0)
    stopping = resting & (stay > NEGLIGIBLE)
    mixed = _mixed(flows)
    switch = resting & (mixed[np.maximum(flows.resting, 0)] if mixed.size else False)
    rows.append(np.flatnonzero(stopping))
    cols.append(flows.stop_choice[stopping] + np.where(switch[stopping], m, 0))
    probs.append(stay[stopping])
    idle = total <= 0  # reached only through the programme's crumbs: stay put
    rows.append(np.flatnonzero(idle))
    cols.append(np.where(resting, flows.stop_choice, pm.row_groups[:-1])[idle])
    probs.append(np.ones(int(idle.sum())))
    rows.append(n + np.flatnonzero(resting))
    cols.append(m + flows.stop_choice[resting])
    probs.append(np.ones(int(resting.sum())))
    matrix = sp.csr_matrix((np.concatenate(probs), (np.concatenate(rows), np.concatenate(cols))),
                           shape=(2 * n, 2 * m))
    matrix.sum_duplicates()
    sums = np.asarray(matrix.sum(axis=1)).ravel()
    return sp.csr_matrix(sp.diags(np.divide(1.0, sums, out=np.zeros(2 * n), where=sums > 0))
                         @ matrix)


def _mixed(flows: Flows) -> BoolArray:
    """Per resting class, whether runs both stay in it and take choices that leave it
    (or pay): only then does stopping need the mode (elsewhere staying is just taking
    the inside choices)."""
    pm = flows.product.mdp
    count = int(flows.resting.max(initial=-1)) + 1
    members = flows.resting >= 0
    owner_class = flows.resting[pm.choice_owner]
    moving_on = (owner_class >= 0) & ~flows.inside  # leaving, or paying a reward
    left = np.bincount(owner_class[moving_on], weights=flows.uses[moving_on], minlength=count)
    stayed = np.bincount(flows.resting[members], weights=flows.stays[members], minlength=count)
    return np.asarray((left > 0) & (stayed > 0), dtype=bool)
