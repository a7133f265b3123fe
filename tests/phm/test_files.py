"""Files the phm layer writes: modes from the umask, atomic, never a temporary left behind."""

from __future__ import annotations

import os
from collections.abc import Iterator
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

from tests.phm.helpers import EXAMPLES
from veribattery.config import load_config
from veribattery.phm.data import PhmDataError, read_cycles
from veribattery.phm.merge import hard_links, write_atomic
from veribattery.phm.plot import plot_fade
from veribattery.phm.refit import fade_parameters
from veribattery.phm.simulate import Pack, Simulation, write_csvs

ARGV = ["veribattery", "phm", "simulate", "--power-w", "60"]


@pytest.fixture
def umask_022() -> Iterator[None]:
    old = os.umask(0o022)
    try:
        yield
    finally:
        os.umask(old)


def _simulation(aged: bool = True) -> Simulation:
    time = np.array([0.0, 60.0, 120.0])
    cycles = np.array([1.0, 2.0, 3.0]) if aged else None
    capacity = np.array([5.0, 4.99, 4.98]) if aged else None
    return Simulation(Pack("Chen2020", 60.0), time, np.array([4.1, 3.9, 3.0]),
                      np.array([14.6, 15.4, 20.0]), cycles, capacity)


def _mode(path: Path) -> int:
    return path.stat().st_mode & 0o777


def test_simulate_csvs_get_modes_from_the_umask(tmp_path: Path, umask_022: None) -> None:
    written = write_csvs(_simulation(), tmp_path / "out", ARGV)
    assert [p.name for p in written] == ["discharge.csv", "cycles.csv"]
    assert [_mode(p) for p in written] == [0o644, 0o644]
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["cycles.csv", "discharge.csv"]
    assert written[0].read_text().splitlines()[1] == "# " + " ".join(ARGV)


def test_simulate_csvs_clash_writes_nothing(tmp_path: Path) -> None:
    (tmp_path / "cycles.csv").write_text("mine\n")
    with pytest.raises(PhmDataError, match="already exist"):
        write_csvs(_simulation(), tmp_path, ARGV)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cycles.csv"]
    assert (tmp_path / "cycles.csv").read_text() == "mine\n"


def test_simulate_csvs_force_keeps_an_existing_files_mode(tmp_path: Path) -> None:
    (tmp_path / "discharge.csv").write_text("mine\n")
    os.chmod(tmp_path / "discharge.csv", 0o600)
    write_csvs(_simulation(aged=False), tmp_path, ARGV, force=True)
    assert (tmp_path / "discharge.csv").read_text().startswith("# constant-power discharge")
    assert _mode(tmp_path / "discharge.csv") == 0o600
    assert [p.name for p in tmp_path.iterdir()] == ["discharge.csv"]


def test_write_atomic_new_file_mode_from_umask(tmp_path: Path, umask_022: None) -> None:
    write_atomic(tmp_path / "m.yaml", "battery: {}\n")
    assert _mode(tmp_path / "m.yaml") == 0o644


def test_write_atomic_through_a_symbolic_link_replaces_its_target(tmp_path: Path) -> None:
    """The rename replaced the link by a regular file and left the config it pointed to
    as it was; now the target is replaced, in its own folder, and the link stays."""
    (tmp_path / "real").mkdir()
    real = tmp_path / "real" / "m.yaml"
    real.write_text("old\n")
    os.chmod(real, 0o640)
    link = tmp_path / "link.yaml"
    link.symlink_to(Path("real") / "m.yaml")
    write_atomic(link, "new\n")
    assert link.is_symlink() and os.readlink(link) == str(Path("real") / "m.yaml")
    assert real.read_text() == "new\n" and _mode(real) == 0o640
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.yaml", "real"]
    assert [p.name for p in real.parent.iterdir()] == ["m.yaml"]


def test_write_atomic_keeps_crlf_line_endings(tmp_path: Path) -> None:
    path = tmp_path / "m.yaml"
    path.write_bytes(b"battery:\r\n  capacity_ah: 11\r\n")
    write_atomic(path, "battery:\n  capacity_ah: 9.5\n  fade_per_recharge: 0.000145\n")
    assert path.read_bytes() == (b"battery:\r\n  capacity_ah: 9.5\r\n"
                                 b"  fade_per_recharge: 0.000145\r\n")
    lf = tmp_path / "lf.yaml"
    lf.write_bytes(b"a: 1\n")
    write_atomic(lf, "a: 2\n")
    assert lf.read_bytes() == b"a: 2\n"


def test_write_atomic_refuses_a_file_with_other_hard_links(tmp_path: Path) -> None:
    """A rename gives the name a new file: the other names kept the old config, split."""
    path, other = tmp_path / "m.yaml", tmp_path / "other.yaml"
    path.write_text("old\n")
    os.link(path, other)
    assert hard_links(path) == 2 and hard_links(tmp_path / "none.yaml") == 0
    with pytest.raises(OSError, match="the file has 2 hard links"):
        write_atomic(path, "new\n")
    assert path.read_text() == other.read_text() == "old\n"
    assert os.path.samefile(path, other)


@pytest.mark.parametrize("suffix", [".png", ".svg", ".PDF"])
def test_figures_are_written_whole_with_umask_modes(tmp_path: Path, umask_022: None,
                                                    suffix: str) -> None:
    log = read_cycles(EXAMPLES / "cycles.csv")
    params = fade_parameters(log, load_config(""))
    path = plot_fade(log, params, 10, float(Fraction(1, 10)), tmp_path / f"fade{suffix}")
    assert _mode(path) == 0o644
    assert [p.name for p in tmp_path.iterdir()] == [f"fade{suffix}"]
    assert path.stat().st_size > 0
