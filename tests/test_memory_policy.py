"""The heap trim between properties: freed arrays leave the process."""

from __future__ import annotations

import platform
import subprocess
import sys
from pathlib import Path

import pytest

from veribattery._memory import trim_heap


def test_trim_runs_under_glibc() -> None:
    assert trim_heap() is (platform.libc_ver()[0] == "glibc")


# Sixty 2 MB arrays freed below a kept one: glibc keeps their pages (the kept array
# pins the heap's top, so the heap cannot shrink from its end) until trim_heap hands
# the free pages in the middle back. Asserted as "not held after the trim" against the
# RSS before the arrays were made, in a fresh process so that the heap is known.
_FRESH_PROCESS = """
import sys
import numpy as np
from veribattery._memory import trim_heap

def rss_kb():
    for line in open("/proc/self/status"):
        if line.startswith("VmRSS:"):
            return int(line.split()[1])

for _ in range(3):  # raise glibc's mapping threshold to 16 MB: the arrays below from the heap
    big = np.ones(16 << 20 >> 3); del big
baseline = rss_kb()
arrays = [np.ones(2 << 20 >> 3) for _ in range(60)]  # 120 MB
keep = np.ones(2 << 20 >> 3)
del arrays
if sys.argv[1] == "trim":
    trim_heap()
print(rss_kb() - baseline)
"""


def _held_kb(mode: str) -> int:
    done = subprocess.run([sys.executable, "-c", _FRESH_PROCESS, mode], capture_output=True,
                          text=True, check=True, cwd=Path(__file__).resolve().parents[1])
    return int(done.stdout)


@pytest.mark.skipif(platform.libc_ver()[0] != "glibc", reason="glibc only (malloc_trim)")
def test_freed_arrays_are_not_held_after_a_trim() -> None:
    assert _held_kb("trim") < 20 << 10  # KB: the kept 2 MB and noise, not the 120 MB


def test_an_mdp_check_trims_after_the_build_and_each_property(
        monkeypatch: pytest.MonkeyPatch) -> None:
    # As the DTMC pipeline: trim_for decides by the size (TRIM_MIN_STATES) whether to trim.
    from veribattery.lang import parse_model, parse_property
    from veribattery.pipeline import mdp as mdp_pipeline

    calls: list[int] = []
    monkeypatch.setattr(mdp_pipeline, "trim_for", calls.append)
    model = parse_model("mdp\nmodule m\n x : [0..2];\n [a] x<2 -> (x'=x+1);\n"
                        " [b] x<2 -> 0.5:(x'=0) + 0.5:(x'=2);\nendmodule\n")
    props = [parse_property("Pmax=? [ F x=2 ]"), parse_property("Pmin=? [ F x=2 ]")]
    run = mdp_pipeline.check_mdp_model(model, props)
    assert [r.value for r in run.results] == [1.0, 1.0]
    assert calls == [3, 3, 3]  # after the build, then after each of the two properties
