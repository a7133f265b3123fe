"""Keys decoded a group of variables at a time give back the rows they encode."""

from __future__ import annotations

import numpy as np
import pytest

from veribattery.explore.build.digits import GROUP_LIMIT, decode, digit_groups
from veribattery.explore.build.store import radix_words

RANGES = {
    "booleans and a counter": [(0, 1)] * 5 + [(0, 20)] + [(0, 5)] * 9,
    "negative lows": [(-3, 4), (-100, -90), (7, 9)],
    "wider than a group": [(0, 1), (0, 3 * GROUP_LIMIT), (-5, 5)],
    "several words": [(0, 1 << 40), (-(1 << 30), 1 << 30), (0, 2), (0, 1 << 40)],
}


@pytest.mark.parametrize("ranges", RANGES.values(), ids=RANGES.keys())
def test_decode_inverts_the_mixed_radix_encoding(ranges: list[tuple[int, int]]) -> None:
    lows = [low for low, _ in ranges]
    highs = [high for _, high in ranges]
    rng = np.random.default_rng(7)
    rows = np.column_stack([rng.integers(low, high + 1, 500) for low, high in ranges])
    rows[0], rows[1] = lows, highs  # both ends of every range
    multipliers = radix_words(lows, highs)
    keys = (rows - np.array(lows)) @ multipliers  # the store's key words
    sizes = [high - low + 1 for low, high in ranges]
    assert np.array_equal(decode(keys, digit_groups(multipliers, lows, sizes), len(ranges)), rows)


def test_small_variables_share_a_group() -> None:
    ranges = RANGES["booleans and a counter"]
    lows, sizes = [lo for lo, _ in ranges], [hi - lo + 1 for lo, hi in ranges]
    groups = digit_groups(radix_words(lows, [hi for _, hi in ranges]), lows, sizes)
    # 2**5 * 21 * 6 = 4032, then 6**4 = 1296 twice (one more 6 would pass 4096)
    assert [(g.first, g.stop) for g in groups] == [(0, 7), (7, 11), (11, 15)]
