"""Files veribattery writes get the mode ``open()`` would give them: 0666 less the umask.

(They were made with ``mkstemp`` and renamed, which left them 0600 whatever the umask.)
"""

from __future__ import annotations

import os
import stat
from collections.abc import Iterator
from pathlib import Path

import pytest
from click.testing import CliRunner

from tests.cli.inputs import CASE1, SMALL
from veribattery.cli import cli

#: (id, arguments, files written).
WRITERS = [
    ("emit", ["emit", CASE1, *SMALL, "-o", "out"], ["out/model.prism", "out/config.resolved.yaml"]),
    ("sweep", ["sweep", CASE1, *SMALL, "--vary", "battery.capacity_ah=10,11", "-j", "1",
               "-o", "r.csv", "--plot", "r.png"], ["r.csv", "r.csv.sweep.json", "r.png"]),
    ("sweep-parquet", ["sweep", CASE1, *SMALL, "--vary", "battery.capacity_ah=10", "-j", "1",
                       "-o", "r.parquet"], ["r.parquet"]),
    ("explain", ["explain", CASE1, *SMALL, "-o", "paths.csv"], ["paths.csv"]),
    ("simulate", ["simulate", CASE1, *SMALL, "--runs", "5", "-o", "paths.csv"], ["paths.csv"]),
    ("distribution", ["distribution", CASE1, *SMALL, "-o", "cdf.csv", "--plot", "cdf.svg"],
     ["cdf.csv", "cdf.svg"]),
]


@pytest.fixture()
def umask_022(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    monkeypatch.chdir(tmp_path)
    old = os.umask(0o022)
    try:
        yield tmp_path
    finally:
        os.umask(old)


@pytest.mark.parametrize(("args", "written"), [w[1:] for w in WRITERS], ids=[w[0] for w in WRITERS])
def test_written_files_follow_the_umask(umask_022: Path, args: list[str],
                                        written: list[str]) -> None:
    result = CliRunner().invoke(cli, args)
    assert result.exit_code == 0, result.output
    for name in written:
        assert stat.S_IMODE((umask_022 / name).stat().st_mode) == 0o644, name
    assert not [p.name for p in umask_022.rglob(".*")]  # no temporary left behind


def test_a_replaced_file_keeps_its_mode(umask_022: Path) -> None:
    target = umask_022 / "paths.csv"
    target.write_text("old\n")
    target.chmod(0o640)
    result = CliRunner().invoke(cli, ["explain", CASE1, *SMALL, "-o", "paths.csv", "--force"])
    assert result.exit_code == 0, result.output
    assert stat.S_IMODE(target.stat().st_mode) == 0o640
    assert target.read_text().startswith("path,probability")
