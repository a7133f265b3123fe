"""build_dtmc on hand-built flat models: semantics, numbering, errors."""

from __future__ import annotations

import numpy as np
import pytest

from tests.explore.models import boolean, command, flat_model, module, rewards, var
from veribattery.errors import ModelError, Span
from veribattery.explore import build_dtmc
from veribattery.lang.nodes import FlatModel


def walk(n: int = 4) -> FlatModel:
    """A bounded random walk on 0..n-1 with a reflecting top."""
    return flat_model(
        [var("x", 0, n - 1)],
        [
            module(
                "W",
                ["x"],
                [
                    command(f"x < {n - 1}", [("0.5", {"x": "x+1"}), ("0.5", {"x": "max(x-1, 0)"})]),
                    command(f"x = {n - 1}", [("1", {"x": "x-1"})]),
                ],
            )
        ],
        labels={"top": f"x = {n - 1}"},
    )


def test_random_walk_counts_and_numbering() -> None:
    dtmc = build_dtmc(walk(4))
    assert dtmc.num_states == 4
    assert dtmc.num_transitions == 7  # 0:{0,1} 1:{0,2} 2:{1,3} 3:{2}
    assert dtmc.states[:, 0].tolist() == [0, 1, 2, 3]  # BFS discovery order
    assert dtmc.initial.tolist() == [0]
    assert dtmc.labels["top"].tolist() == [False, False, False, True]
    assert dtmc.labels["init"].tolist() == [True, False, False, False]
    assert not dtmc.labels["deadlock"].any()
    assert dtmc.warnings == ()
    np.testing.assert_allclose(dtmc.transitions.sum(axis=1).A1, 1.0)


def test_duplicate_successors_are_summed_and_zero_probabilities_dropped() -> None:
    model = flat_model(
        [var("x", 0, 1)],
        [
            module(
                "M",
                ["x"],
                [command("true", [("0.25", {"x": "0"}), ("0.75", {"x": "0"}), ("0", {"x": "1"})])],
            )
        ],
    )
    dtmc = build_dtmc(model)
    assert dtmc.num_states == 1
    assert dtmc.num_transitions == 1
    assert dtmc.transitions[0, 0] == pytest.approx(1.0)


def test_uniform_choice_between_enabled_commands() -> None:
    model = flat_model(
        [var("x", 0, 2)],
        [
            module(
                "M",
                ["x"],
                [command("x = 0", [("1", {"x": "1"})]), command("x = 0", [("1", {"x": "2"})])],
            )
        ],
    )
    dtmc = build_dtmc(model)
    assert dtmc.transitions.toarray()[0].tolist() == [0.0, 0.5, 0.5]
    assert dtmc.nondeterministic == 1
    assert dtmc.deadlocks == 2
    assert "1 states with several enabled choices" in dtmc.warnings[1]


def test_deadlocks_get_self_loops_and_a_label() -> None:
    model = flat_model(
        [var("x", 0, 3)], [module("M", ["x"], [command("x < 2", [("1", {"x": "x+1"})])])]
    )
    dtmc = build_dtmc(model)
    assert dtmc.num_states == 3
    assert dtmc.deadlocks == 1
    assert dtmc.transitions[2, 2] == 1.0
    assert dtmc.labels["deadlock"].tolist() == [False, False, True]
    assert dtmc.warnings == ("1 deadlock state (self-loop added)",)


def two_synchronising_modules() -> FlatModel:
    return flat_model(
        [var("x", 0, 2, module="A"), var("y", 0, 2, module="B")],
        [
            module(
                "A",
                ["x"],
                [
                    command("x = 0", [("0.5", {"x": "1"}), ("0.5", {"x": "2"})], action="go"),
                    command("x = 0", [("1", {"x": "x"})], action="go"),
                ],
            ),
            module(
                "B",
                ["y"],
                # The right-hand side reads x in the SOURCE state (x=0), not A's new value.
                [command("y = 0", [("0.25", {"y": "x + 1"}), ("0.75", {"y": "2"})], action="go")],
            ),
        ],
    )


def test_synchronisation_is_a_product_of_commands_and_updates() -> None:
    dtmc = build_dtmc(two_synchronising_modules())
    # Joint choices at (0,0): A's first command x B's, A's second x B's: two choices.
    expected = {
        (1, 1): 0.5 * 0.5 * 0.25,
        (2, 1): 0.5 * 0.5 * 0.25,
        (1, 2): 0.5 * 0.5 * 0.75,
        (2, 2): 0.5 * 0.5 * 0.75,
        (0, 1): 0.5 * 0.25,
        (0, 2): 0.5 * 0.75,
    }
    row = dtmc.transitions[0].toarray()[0]
    got = {tuple(dtmc.states[j].tolist()): row[j] for j in np.flatnonzero(row)}
    assert got == pytest.approx(expected)
    assert dtmc.nondeterministic == 1
    # Every successor has y != 0: B blocks "go", so all of them deadlock.
    assert dtmc.deadlocks == 6


def test_action_blocked_when_one_module_has_no_enabled_command() -> None:
    model = flat_model(
        [var("x", 0, 1, module="A"), var("y", 0, 1, module="B")],
        [
            module("A", ["x"], [command("true", [("1", {"x": "1"})], action="s")]),
            module("B", ["y"], [command("false", [("1", {"y": "1"})], action="s")]),
        ],
    )
    dtmc = build_dtmc(model)
    assert dtmc.num_states == 1 and dtmc.deadlocks == 1


def test_init_block_enumerates_the_domain() -> None:
    model = flat_model(
        [boolean(f"b{i}", module=f"P{i}") for i in range(3)],
        [module("P0", ["b0"], [command("true", [("1", {})])])],
        init="b0 | b1 & b2",
    )
    dtmc = build_dtmc(model)
    assert dtmc.num_states == 5
    assert dtmc.initial.tolist() == [0, 1, 2, 3, 4]
    assert dtmc.states.tolist() == [[0, 1, 1], [1, 0, 0], [1, 0, 1], [1, 1, 0], [1, 1, 1]]


def test_progress_is_called_per_layer() -> None:
    calls: list[tuple[int, int]] = []
    build_dtmc(walk(4), progress=lambda found, frontier: calls.append((found, frontier)))
    assert calls == [(2, 1), (3, 1), (4, 1), (4, 1)]


def test_state_and_transition_rewards() -> None:
    model = flat_model(
        [var("x", 0, 2)],
        [
            module(
                "M",
                ["x"],
                [
                    command("x < 2", [("1", {"x": "x+1"})]),
                    command("x = 0", [("1", {"x": "2"})], action="jump"),
                ],
            )
        ],
        reward_structs=[
            rewards("r", ("x > 0", "x * 1.5"), ("jump", "true", "4"), (None, "true", "1"))
        ],
    )
    dtmc = build_dtmc(model)
    r = dtmc.reward("r")
    assert r.state.tolist() == [0.0, 1.5, 3.0]
    # x=0: two choices, [] (reward 1) and [jump] (reward 4): (1 + 4) / 2.
    assert r.transition.tolist() == [2.5, 1.0, 0.0]


def _counter_with_reward(guard: str, value: str) -> FlatModel:
    """x counts 0, 1, 2 and stays; one reward item ``guard : value``."""
    return flat_model(
        [var("x", 0, 2)],
        [module("M", ["x"], [command("x < 2", [("1", {"x": "x+1"})])])],
        reward_structs=[rewards("r", (guard, value))],
    )


@pytest.mark.parametrize("value", ["1/x", "pow(0.0, x - 1)", "log(x, 1)"])
def test_a_reward_that_is_not_finite_is_an_error_naming_structure_and_state(value: str) -> None:
    """As PRISM: "Reward structure is not finite at state ..." (1/0 is inf, log base 1 NaN)."""
    with pytest.raises(ModelError, match=r'reward structure "r" is not finite at state \(x=0\)'):
        build_dtmc(_counter_with_reward("true", value))


def test_a_reward_is_evaluated_only_where_its_guard_holds() -> None:
    """``x>0 : floor(6/x)`` has no value at x=0 (floor of inf), where PRISM does not
    evaluate it; 1/x is infinite there, but not a reward there either."""
    r = build_dtmc(_counter_with_reward("x > 0", "floor(6/x)")).reward("r")
    assert r.state.tolist() == [0.0, 6.0, 3.0]
    r = build_dtmc(_counter_with_reward("x > 0", "1/x")).reward("r")
    assert r.state.tolist() == [0.0, 1.0, 0.5]


@pytest.mark.parametrize(
    ("updates", "message"),
    [
        (
            [("1", {"x": "x+2"})],
            r"module M, command: update sets x to 3, outside its range 0\.\.2, "
            r"in state \(x=1, y=0\)",
        ),
        (
            [("0.5", {"x": "0"}), ("0.4", {"x": "1"})],
            r"probabilities sum to 0\.9, not 1, in state \(x=1, y=0\)",
        ),
        (
            [("1.5", {"x": "0"}), ("-0.5", {"x": "1"})],
            r"negative probability -0\.5 in state \(x=1, y=0\)",
        ),
        ([("1", {"x": "x/2"})], "non-integer value to 'x'"),
    ],
)
def test_errors_name_module_state_and_span(
    updates: list[tuple[str, dict[str, str]]], message: str
) -> None:
    model = flat_model(
        [var("x", 0, 2), var("y", 0, 1)],
        [
            module(
                "M",
                ["x", "y"],
                [command("x = 0", [("1", {"x": "1"})]), command("x = 1", updates, line=7)],
            )
        ],
    )
    with pytest.raises(ModelError, match=message) as info:
        build_dtmc(model)
    assert info.value.span == Span(7, 3, "test.pm")


def test_synchronised_sum_error_names_both_modules() -> None:
    model = flat_model(
        [var("x", 0, 1, module="A"), var("y", 0, 1, module="B")],
        [
            module(
                "A",
                ["x"],
                [command("true", [("0.5", {"x": "1"}), ("0.5", {})], action="s", line=4)],
            ),
            module("B", ["y"], [command("true", [("0.5", {"y": "1"})], action="s", line=9)]),
        ],
    )
    with pytest.raises(ModelError, match=r"modules A, B, command \[s\]: probabilities sum to 0\.5"):
        build_dtmc(model)


def test_huge_ranges_use_multi_word_keys() -> None:
    # 2^40 * 2^40 overflows one 63-bit word.
    big = 1 << 40
    model = flat_model(
        [var("x", 0, big), var("y", -(1 << 50), 0, init=0)],
        [
            module(
                "M",
                ["x", "y"],
                [
                    command(
                        "x < 3",
                        [("0.5", {"x": "x+1"}), ("0.5", {"x": "x+1", "y": "y - 1099511627776"})],
                    )
                ],
            )
        ],
    )
    dtmc = build_dtmc(model)
    assert dtmc.num_states == 1 + 2 + 3 + 4
    assert dtmc.deadlocks == 4


# --- one command per part: the fast path must equal the general product -----------


def _three_part_sync() -> FlatModel:
    """Three modules on one action, one command each, 2 x 1 x 3 updates (some varying)."""
    return flat_model(
        [var("x", 0, 3), var("y", 0, 3), var("z", 0, 3)],
        [
            module("A", ["x"], [command("x < 3", [("0.5", {"x": "x+1"}), ("0.5", {"x": "0"})],
                                        action="t")]),
            module("B", ["y"], [command("y <= x", [("1", {"y": "min(y+1, 3)"})], action="t")]),
            module("C", ["z"], [command("true", [("0.2", {"z": "0"}), ("x/10", {"z": "1"}),
                                                 ("0.8 - x/10", {"z": "min(z+1, 3)"})],
                                        action="t")]),
        ],
    )


def test_one_command_per_part_matches_the_general_product() -> None:
    from veribattery.explore.build import successors
    from veribattery.explore.compile.program import compile_program

    program = compile_program(_three_part_sync())
    (group,) = program.groups
    states = np.array([[x, y, z] for x in range(4) for y in range(4) for z in range(4)])
    fast = successors.expand_group(program, group, states)
    general = successors._expand_product(program, group, states)
    assert fast is not None and general is not None
    assert fast.source.tolist() == general.source.tolist()
    assert fast.targets.tolist() == general.targets.tolist()
    assert fast.probability.tolist() == general.probability.tolist()  # bit for bit
    assert fast.choices.tolist() == general.choices.tolist()


def test_one_command_per_part_reports_bad_sums() -> None:
    model = flat_model(
        [var("x", 0, 1), var("y", 0, 1)],
        [
            module("A", ["x"], [command("true", [("0.5", {"x": "1"})], action="t")]),
            module("B", ["y"], [command("true", [("1", {"y": "1"})], action="t")]),
        ],
    )
    with pytest.raises(ModelError, match=r"sum to 0\.5"):
        build_dtmc(model)


# --- range checks are made once per layer; errors stay those of the command order ---


def test_out_of_range_on_a_zero_probability_branch_is_reported() -> None:
    model = flat_model(
        [var("x", 0, 2)],
        [module("M", ["x"], [command("true", [("1", {"x": "0"}), ("0", {"x": "x+3"})], line=5)])],
    )
    with pytest.raises(ModelError, match=r"update sets x to 3, outside its range 0\.\.2") as info:
        build_dtmc(model)
    assert info.value.span == Span(5, 3, "test.pm")


def test_first_error_in_command_order_is_reported() -> None:
    # Module A's command leaves x's range; module B's later command has a bad sum.
    model = flat_model(
        [var("x", 0, 1, module="A"), var("y", 0, 1, module="B")],
        [
            module("A", ["x"], [command("true", [("1", {"x": "x+2"})], line=3)]),
            module("B", ["y"], [command("true", [("0.5", {"y": "1"})], line=8)]),
        ],
    )
    with pytest.raises(ModelError, match=r"module A, command: update sets x to 2") as info:
        build_dtmc(model)
    assert info.value.span == Span(3, 3, "test.pm")


@pytest.mark.parametrize("synchronised", [False, True])
def test_range_error_located_in_a_later_layer(synchronised: bool) -> None:
    # x climbs one per step: the error appears only in the layer where x = 3.
    action = "a" if synchronised else None
    cmds = [command("true", [("0.5", {"x": "x+1"}), ("0.5", {})], action=action, line=4)]
    modules = [module("M", ["x"], cmds)]
    if synchronised:
        modules.append(module("N", [], [command("true", [("1", {})], action="a", line=9)]))
    model = flat_model([var("x", -2, 3, init=-2)], modules)
    message = r"sets x to 4, outside its range -2\.\.3, in state \(x=3\)"
    with pytest.raises(ModelError, match=message):
        build_dtmc(model)


def test_labels_and_rewards_evaluated_in_chunks_equal_the_formulas(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from veribattery.explore.build import builder

    # A 7x5 grid walk; chunks of 4 states split it mid-layer and mid-row.
    monkeypatch.setattr(builder, "_EVAL_CHUNK", 4)
    model = flat_model(
        [var("x", 0, 6), var("y", -2, 2, init=-2)],
        [
            module(
                "M",
                ["x", "y"],
                [command("true", [("0.5", {"x": "min(x+1, 6)"}), ("0.5", {"y": "min(y+1, 2)"})])],
            )
        ],
        labels={"odd": "mod(x, 2) = 1", "safe": "y > 0 & x/y >= 2"},
        reward_structs=[rewards("r", ("y != 0", "x / (y + 3)"), ("x >= 3", "x * x"))],
    )
    dtmc = build_dtmc(model)
    assert dtmc.num_states == 35
    x, y = dtmc.column("x"), dtmc.column("y")
    assert dtmc.labels["odd"].tolist() == [v % 2 == 1 for v in x]
    pairs = list(zip(x.tolist(), y.tolist(), strict=True))
    assert dtmc.labels["safe"].tolist() == [b > 0 and a / b >= 2 for a, b in pairs]
    expected = [(a / (b + 3) if b != 0 else 0.0) + (a * a if a >= 3 else 0.0) for a, b in pairs]
    assert dtmc.reward("r").state.tolist() == expected


# --- packed keys: the multi-word fallback gives the same DTMC as one word ---------


def _clamped_walk(wide: int) -> FlatModel:
    """A walk on x in -3..3 and y in -5..-1 with a boolean flag; *wide* widens the
    declared ranges (the values reached stay the same) past what one key word packs.
    """
    return flat_model(
        [boolean("f"), var("x", -3 - wide, 3 + wide, init=0), var("y", -5 - wide, -1, init=-1)],
        [
            module(
                "M",
                ["f", "x", "y"],
                [
                    command("!f", [("0.25", {"x": "max(x-1, -3)"}), ("0.25", {"x": "min(x+1, 3)"}),
                                   ("0.5", {"f": "true", "y": "max(y-1, -5)"})]),
                    command("f", [("0.5", {"f": "false"}), ("0.5", {"y": "min(y+1, -1)"})]),
                ],
            )
        ],
        labels={"low": "y = -5 & f"},
    )


def test_multi_word_keys_give_the_same_dtmc_as_one_word() -> None:
    from veribattery.explore.build.store import radix_words

    narrow, wide = _clamped_walk(0), _clamped_walk(1 << 40)
    assert radix_words([0, -3, -5], [1, 3, -1]).shape[1] == 1
    wide_ranges = [(v.low, v.high) for v in wide.variables]
    assert radix_words(*zip(*wide_ranges, strict=True)).shape[1] == 2  # 1 + 41 + 41 bits > 63
    a, b = build_dtmc(narrow), build_dtmc(wide)
    assert a.num_states == b.num_states == 2 * 7 * 5
    assert a.states.tolist() == b.states.tolist()  # same numbering
    assert (a.transitions != b.transitions).nnz == 0
    assert a.labels["low"].tolist() == b.labels["low"].tolist()
    assert set(a.column("f").tolist()) == {0, 1}
    assert a.column("x").min() == -3 and a.column("y").min() == -5


def _layered_walk() -> FlatModel:
    """Many BFS layers (x climbs 0..39), an action on half the choices, a rewarded
    action, zero-probability branches (p = 0 where y = 0) and deadlocks at the top."""
    return flat_model(
        [var("x", 0, 39), var("y", 0, 2)],
        [
            module(
                "M",
                ["x", "y"],
                [
                    command("x < 39", [("y / 4", {"x": "x+1", "y": "0"}),
                                       ("1 - y / 4", {"y": "min(y+1, 2)"})]),
                    command("x < 39 & y = 2", [("1", {"x": "x+1", "y": "1"})], action="hop"),
                ],
            )
        ],
        reward_structs=[rewards("r", ("hop", "true", "2"), (None, "x > 3", "1"))],
    )


@pytest.mark.parametrize("merge", [1, 3, 1 << 15])
def test_merged_layers_equal_the_layers_one_by_one(
    monkeypatch: pytest.MonkeyPatch, merge: int
) -> None:
    from dataclasses import fields

    from veribattery.explore.build import builder
    from veribattery.explore.build import layers as layers_module
    from veribattery.explore.compile.program import compile_program

    model = _layered_walk()

    def layers_with(threshold: int) -> tuple[np.ndarray, list[builder.Layer]]:
        monkeypatch.setattr(layers_module, "_MERGE_BRANCHES", threshold)
        states, _, layers = builder.explore(model, compile_program(model))
        return states, layers

    states, apart = layers_with(1)  # every chunk a layer of its own, as before merging
    merged_states, merged = layers_with(merge)
    np.testing.assert_array_equal(merged_states, states)
    assert len(apart) > 40 and (merge == 1) == (len(merged) == len(apart))
    for field in fields(builder.Layer):
        name = field.name
        if name in ("action_choices", "dropped", "branches"):
            continue
        joined = [np.concatenate([getattr(layer, name) for layer in group])
                  for group in (apart, merged)]
        assert joined[0].dtype == joined[1].dtype, name
        np.testing.assert_array_equal(joined[1], joined[0], err_msg=name)
    # dropped positions, counted over all branches of the search
    for group in (apart, merged):
        assert sum(layer.branches for layer in group) == sum(layer.branches for layer in apart)
    assert _global_dropped(merged).tolist() == _global_dropped(apart).tolist()
    assert _global_dropped(apart).size > 0
    for action in ("hop",):
        assert np.concatenate([_counts(layer, action) for layer in merged]).tolist() == (
            np.concatenate([_counts(layer, action) for layer in apart]).tolist())
    # and the DTMC assembled from either is the same, bit for bit
    a = builder.assemble(model, states, np.array([0]), apart)
    b = builder.assemble(model, states, np.array([0]), merged)
    assert (a.transitions != b.transitions).nnz == 0
    assert a.transitions.data.tobytes() == b.transitions.data.tobytes()
    assert a.reward("r").transition.tolist() == b.reward("r").transition.tolist()
    assert a.reward("r").transition.max() > 0  # (x, 2) with x > 3: (2 + 1) / 2
    assert a.deadlocks == b.deadlocks == 2  # (39, 0) and (39, 1)


def _global_dropped(layers: list) -> np.ndarray:  # type: ignore[type-arg]
    offsets = np.cumsum([0] + [layer.branches for layer in layers[:-1]])
    return np.concatenate([layer.dropped + o for layer, o in zip(layers, offsets, strict=True)])


def _counts(layer, action: str) -> np.ndarray:  # type: ignore[no-untyped-def]
    found = layer.action_choices.get(action)
    return np.zeros(layer.choices.size, dtype=np.int64) if found is None else found
