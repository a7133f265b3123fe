"""Regenerate the example reports in docs/reports (``make reports``).

- ``case1.html``: the paper's baseline (configs/paper/case1.yaml), with the requirement
  ``p_success >= 0.99`` (it holds);
- ``case1-12.8Ah.html``: the same mission with a new 12.8 Ah battery, the dip of the
  paper's Fig. 6 (the requirement fails), with a sweep of capacity 11-14 Ah
  (``dip-sweep.csv``, run here) drawn and its turning points marked;
- ``case1-12.8Ah.png``: the top of that report in a browser, for the README (needs
  Chromium; skipped with a note without it).

Every file is made by the ``veribattery`` command line, so each report records the
command that makes it again. Run from anywhere: ``python docs/reports/make_reports.py``.
"""

from __future__ import annotations

import shlex
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
CONFIG = "configs/paper/case1.yaml"
REQUIREMENT = 'requirements=["p_success >= 0.99"]'
DIP = "battery.capacity_ah=12.8"
SWEEP = "docs/reports/dip-sweep.csv"
#: The CLI, with ``report`` added in case this checkout does not list it yet.
_CLI = """import sys
from veribattery.cli import cli, main
from veribattery.cli.report import report_command
if "report" not in cli.list_commands(None):
    cli.add_command(report_command, "report")
main(sys.argv[1:])
"""


def veribattery(*args: str, ok: tuple[int, ...] = (0,), quiet: bool = False) -> None:
    """Run ``veribattery ARGS`` from the repository's root; exit codes in *ok* are fine.

    :param quiet: drop what it prints on stdout (a sweep's table).
    """
    print("$ veribattery " + shlex.join(args), flush=True)
    done = subprocess.run([sys.executable, "-c", _CLI, *args], cwd=REPO, check=False,
                          stdout=subprocess.DEVNULL if quiet else None)
    if done.returncode not in ok:
        sys.exit(f"veribattery {args[0]} failed with exit status {done.returncode}")


def screenshot(page: Path, target: Path, width: int = 1200, height: int = 1400) -> None:
    """The top of *page* in headless Chromium (offline), as PNG."""
    chromium = next((p for n in ("chromium", "chromium-browser", "google-chrome")
                     if (p := shutil.which(n))), None)
    if chromium is None:
        print(f"Chromium not found: {target.name} not made", file=sys.stderr)
        return
    with tempfile.TemporaryDirectory() as profile:
        subprocess.run(
            [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
             "--disable-background-networking", "--disable-component-update", "--disable-sync",
             "--no-first-run", f"--user-data-dir={profile}", f"--window-size={width},{height}",
             f"--screenshot={target}", page.as_uri()],
            check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=120)
    print(f"wrote {target.relative_to(REPO)}")


def main() -> None:
    veribattery("report", CONFIG, "--set", REQUIREMENT, "-o", "docs/reports/case1.html",
                "--force")
    veribattery("sweep", CONFIG, "--set", REQUIREMENT, "--vary", "battery.capacity_ah=11:14:0.1",
                "-j", "2", "-o", SWEEP, "--force", ok=(0, 1), quiet=True)
    veribattery("report", CONFIG, "--set", DIP, "--set", REQUIREMENT, "--sweep", SWEEP,
                "-o", "docs/reports/case1-12.8Ah.html", "--force", ok=(0, 1))
    screenshot(HERE / "case1-12.8Ah.html", HERE / "case1-12.8Ah.png")
    for name in ("case1.html", "case1-12.8Ah.html", "case1-12.8Ah.png"):
        path = HERE / name
        if path.exists():
            print(f"{name}: {path.stat().st_size:,} bytes")


if __name__ == "__main__":
    main()
