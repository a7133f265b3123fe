"""The command line's allocator setting: a freed large array leaves the process at once."""

from __future__ import annotations

import os
import platform

import numpy as np
import pytest

from veribattery._memory import map_large_blocks


def _rss() -> int:
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def test_setting_applies_under_glibc() -> None:
    assert map_large_blocks() is (platform.libc_ver()[0] == "glibc")


@pytest.mark.skipif(platform.libc_ver()[0] != "glibc" or not os.path.exists("/proc/self/statm"),
                    reason="glibc on Linux only")
def test_a_freed_array_of_a_few_mb_is_returned() -> None:
    assert map_large_blocks()
    # Without the setting, freeing a 16 MB mapped block raises glibc's threshold to
    # 16 MB; a 3 MB array then comes from the heap and stays there when freed
    # (small blocks allocated after it pin the heap's top).
    big = np.ones(2 << 20)
    del big
    before = _rss()
    block = np.ones(3 << 17)  # 3 MB
    pins = [np.ones(100) for _ in range(10)]
    assert _rss() - before >= 2 << 20
    del block
    assert _rss() - before < 1 << 20
    assert len(pins) == 10
