"""The command line's allocator setting: large arrays get mappings of their own.

Measured with glibc's ``mallinfo2`` (bytes in mapped blocks), not RSS: the
kernel's RSS counters of a multi-threaded process lag behind its page faults.
"""

from __future__ import annotations

import ctypes
import platform
import subprocess
import sys
from pathlib import Path

import pytest

from veribattery._memory import map_large_blocks

_FIELDS = ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks",
           "uordblks", "fordblks", "keepcost")


class _MallInfo2(ctypes.Structure):
    _fields_ = [(name, ctypes.c_size_t) for name in _FIELDS]


def _mapped_bytes() -> int:
    """Bytes glibc holds in blocks mapped on their own (freed at once when freed)."""
    libc = ctypes.CDLL("libc.so.6")
    libc.mallinfo2.restype = _MallInfo2
    return int(libc.mallinfo2().hblkhd)


def _has_mallinfo2() -> bool:
    try:
        return hasattr(ctypes.CDLL("libc.so.6"), "mallinfo2")
    except OSError:
        return False


def test_setting_applies_under_glibc() -> None:
    assert map_large_blocks() is (platform.libc_ver()[0] == "glibc")


_FRESH_PROCESS = """
from tests.test_memory_policy import _mapped_bytes
from veribattery._memory import map_large_blocks
assert map_large_blocks()
big = np.ones(2 << 20)
del big
before = _mapped_bytes()
block = np.ones(3 << 17)  # 3 MB
grown = _mapped_bytes() - before
del block
print(grown, _mapped_bytes() - before)
"""


@pytest.mark.skipif(not _has_mallinfo2(), reason="glibc >= 2.33 only (mallinfo2)")
def test_an_array_of_a_few_mb_is_mapped_and_unmapped() -> None:
    # Without the setting, freeing a 16 MB mapped block raises glibc's threshold to
    # 16 MB, and a 3 MB array then comes from the heap, which keeps it when freed.
    # A fresh process: in a long-lived one (a test worker) the heap may already hold a
    # free chunk large enough, which malloc serves before it considers a mapping.
    done = subprocess.run([sys.executable, "-c", _FRESH_PROCESS], capture_output=True,
                          text=True, check=True, cwd=Path(__file__).resolve().parents[1])
    grown, left = map(int, done.stdout.split())
    assert grown >= 3 << 20
    assert left == 0
