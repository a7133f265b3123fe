"""StateStore: numbering, deduplication and multi-word keys."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from veribattery.explore.store import StateStore, radix_words


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
