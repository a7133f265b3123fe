"""StateStore: numbering, deduplication and multi-word keys."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from veribattery.explore.build.store import StateStore, radix_words


def test_first_occurrence_numbering() -> None:
    store = StateStore([0, 0], [9, 9])
    assert store.add(np.array([[1, 1], [0, 0], [1, 1]])).tolist() == [0, 1, 0]
    assert store.add(np.array([[5, 5], [0, 0], [2, 2], [5, 5]])).tolist() == [2, 1, 3, 2]
    assert store.states.tolist() == [[1, 1], [0, 0], [5, 5], [2, 2]]


def test_radix_words_split_when_a_word_overflows() -> None:
    assert radix_words([0, 0], [9, 9]).tolist() == [[1], [10]]
    big = (1 << 40) - 1
    assert radix_words([0, 0, 0], [big, big, 1]).shape == (3, 2)


@settings(max_examples=50, deadline=None)
@given(
    st.lists(
        st.lists(st.tuples(st.integers(-3, 3), st.integers(0, 1 << 45)), min_size=0, max_size=60),
        min_size=1,
        max_size=8,
    )
)
def test_matches_a_dictionary(batches: list[list[tuple[int, int]]]) -> None:
    # Ranges whose product overflows one word, so rows compare over two words.
    store = StateStore([-3, 0], [3, 1 << 45])
    reference: dict[tuple[int, int], int] = {}
    for batch in batches:
        rows = np.array(batch, dtype=np.int64).reshape(-1, 2)
        expected = [reference.setdefault(row, len(reference)) for row in batch]
        assert store.add(rows).tolist() == expected
    assert [tuple(r) for r in store.states.tolist()] == list(reference)


@settings(max_examples=20, deadline=None)
@given(st.lists(st.integers(0, 5000), min_size=1, max_size=3000))
def test_growth_and_rehash(values: list[int]) -> None:
    store = StateStore([0], [5000])
    index = store.add(np.array(values, dtype=np.int64)[:, None])
    first = {v: i for i, v in reversed(list(enumerate(dict.fromkeys(values))))}
    assert index.tolist() == [first[v] for v in values]
    assert store.add(np.array(values, dtype=np.int64)[:, None]).tolist() == index.tolist()


@settings(max_examples=50, deadline=None)
@given(
    st.lists(
        st.lists(st.tuples(st.integers(-3, 3), st.integers(0, 1 << 45), st.integers(-7, 0)),
                 min_size=0, max_size=40),
        min_size=1,
        max_size=6,
    ),
    st.lists(st.tuples(st.integers(0, 300), st.integers(0, 60)), max_size=10),
)
def test_rows_served_or_decoded_equal_the_rows_added(
    batches: list[list[tuple[int, int, int]]], ranges: list[tuple[int, int]]
) -> None:
    # Two key words (the middle range alone needs 46 bits), negative lows; ranges
    # asked in search order (recent rows served as added) and out of order (decoded).
    store = StateStore([-3, 0, -7], [3, 1 << 45, 0])
    reference: dict[tuple[int, int, int], None] = {}
    low = 0
    for batch in batches:
        store.add(np.array(batch, dtype=np.int64).reshape(-1, 3))
        reference.update(dict.fromkeys(batch))
        high = min(low + 7, store.count)
        assert [tuple(r) for r in store.rows(low, high).tolist()] == list(reference)[low:high]
        low = high
    everything = list(reference)
    for start, width in ranges:
        start = min(start, store.count)
        stop = min(start + width, store.count)
        assert [tuple(r) for r in store.rows(start, stop).tolist()] == everything[start:stop]
    assert [tuple(r) for r in store.states.tolist()] == everything


class _Crowded(StateStore):
    """Every key hashed into one of three slots: long probe chains in every batch."""

    def _slots(self, keys: np.ndarray) -> np.ndarray:
        first_word = keys if keys.ndim == 1 else keys[:, 0]
        return np.asarray(first_word % 3, dtype=np.int64)


@settings(max_examples=30, deadline=None)
@given(st.lists(st.lists(st.integers(0, 400), max_size=80), min_size=1, max_size=6))
def test_long_probe_chains_match_a_dictionary(batches: list[list[int]]) -> None:
    store = _Crowded([0], [400])
    reference: dict[int, int] = {}
    for batch in batches:
        expected = [reference.setdefault(v, len(reference)) for v in batch]
        assert store.add(np.array(batch, dtype=np.int64).reshape(-1, 1)).tolist() == expected
    assert store.states[:, 0].tolist() == list(reference)


def _replay_against_a_dictionary(store: StateStore, batches: list[np.ndarray]) -> None:
    """Add *batches* to *store* and to a dict (the reference): same numbers, same states."""
    reference: dict[tuple[int, ...], int] = {}
    for rows in batches:
        expected = [reference.setdefault(tuple(row), len(reference)) for row in rows.tolist()]
        assert store.add(rows).tolist() == expected
        assert store.count == len(reference)
    assert [tuple(r) for r in store.states.tolist()] == list(reference)


@pytest.mark.parametrize(
    ("lows", "highs"),
    [
        ([0, -5, 0], [9, 5, 300]),  # one word
        ([-3, 0, -7], [3, 1 << 45, 0]),  # two words
        ([0, 0, 0], [(1 << 40) - 1, (1 << 40) - 1, (1 << 40) - 1]),  # three words
    ],
    ids=["one-word", "two-words", "three-words"],
)
def test_random_streams_with_growth_and_duplicates_match_a_dictionary(
    lows: list[int], highs: list[int]
) -> None:
    # BFS-like batches: from a few rows to thousands, drawn from a pool of ~6,000
    # states so that keys repeat within a batch and across batches, and the table
    # grows (rehashes) several times on the way.
    rng = np.random.default_rng(20261123)
    pool = np.stack([rng.integers(lo, hi, size=6000, endpoint=True)
                     for lo, hi in zip(lows, highs, strict=True)], axis=1)
    batches = [pool[rng.integers(0, pool.shape[0], size=int(size))]
               for size in rng.geometric(1 / 400, size=60)]
    _replay_against_a_dictionary(StateStore(lows, highs), batches)


def test_a_batch_of_one_repeated_row_is_one_state() -> None:
    store = StateStore([0], [9])
    assert store.add(np.full((500, 1), 7)).tolist() == [0] * 500
    assert store.add(np.array([[3], [7], [3]])).tolist() == [1, 0, 1]
    assert store.states.tolist() == [[7], [3]]


class _Racing(StateStore):
    """Keys hash to 4 slots in 16 of a small table: distinct new keys of one batch
    often stop at the same empty slot, and chains run past the probing window."""

    def _slots(self, keys: np.ndarray) -> np.ndarray:
        first_word = keys if keys.ndim == 1 else keys[:, 0]
        return np.asarray(first_word % 4 * 4, dtype=np.int64)


def test_racing_new_keys_and_long_chains_match_a_dictionary(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # Both ways of numbering a batch must run: claiming the empty slots, and sorting
    # when distinct keys claim one slot.
    sorted_batches: list[int] = []
    original = StateStore._number_sorted

    def counted(self: StateStore, *args: np.ndarray) -> None:
        sorted_batches.append(args[-1].size)
        original(self, *args)

    monkeypatch.setattr(StateStore, "_number_sorted", counted)
    rng = np.random.default_rng(7)
    batches = [rng.integers(0, 600, size=(int(n), 1)) for n in rng.integers(1, 120, size=30)]
    batches.insert(1, np.array([[4], [4], [8], [8]]))  # 4 and 8 share a slot: a race
    _replay_against_a_dictionary(_Racing([0], [600]), batches)
    assert sorted_batches and len(sorted_batches) < len(batches)
