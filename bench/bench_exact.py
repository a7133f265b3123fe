"""``--exact`` against Storm's exact (rational) engine, whole processes, in one run.

For the paper's baseline mission (case1) ``veribattery prism --exact`` checks
the emitted ``model.prism`` with the paper's three properties, as Storm does with
``stormpy.Rational`` (the same file), and ``veribattery check --exact`` runs on
the config (five properties, the two conditional ones NaN; its first three
values are compared); for the Haddad-Monmege chain
(N = 20, 100, 300; p = 0.7, exact answer 7/10) both check the same file. Each
measurement is its own process (interpreter start-up included) run through a
small wrapper that reports wall-clock seconds and the child's peak RSS. The
two tools' answers must be the same rationals.

    python bench/bench_exact.py            # case1 and the Haddad-Monmege family
    python bench/bench_exact.py --quick    # Haddad-Monmege only
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from fractions import Fraction
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
EXE = str(Path(sys.executable).parent / "veribattery")

#: Runs argv[1:], then prints its wall and CPU (user + system) seconds and peak RSS as JSON
#: (and the child's stdout on stderr). CPU time is the fairer figure on a shared machine.
WRAPPER = """
import json, resource, subprocess, sys, time
start = time.perf_counter()
proc = subprocess.run(sys.argv[1:], capture_output=True, text=True)
wall = time.perf_counter() - start
if proc.returncode != 0:
    sys.exit(proc.stderr[-2000:])
usage = resource.getrusage(resource.RUSAGE_CHILDREN)
sys.stderr.write(proc.stdout)
print(json.dumps({"wall_s": wall, "cpu_s": usage.ru_utime + usage.ru_stime,
                  "peak_mb": usage.ru_maxrss / 1024}))
"""

STORM_EXACT = """
import sys, stormpy
program = stormpy.parse_prism_program(sys.argv[1])
props = stormpy.parse_properties(open(sys.argv[2]).read(), program)
if len(sys.argv) > 3:
    program, props = stormpy.instantiate_constants(program, sys.argv[3], props)
model = stormpy.build_model[stormpy.Rational](program, options=stormpy.BuilderOptions(props))
init = model.initial_states[0]
for prop in props:
    print(str(stormpy.model_checking(model, prop).get_value_vector()[init]))
"""

HADDAD_MONMEGE = (Path(__file__).parents[1] / "tests" / "data" / "haddad_monmege.prism").read_text()


def measured(argv: list[str]) -> tuple[dict[str, float], str]:
    """Wall seconds and peak MB of one whole process, and what it printed."""
    proc = subprocess.run([sys.executable, "-c", WRAPPER, *argv],
                          capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise SystemExit(f"{argv[:3]} failed:\n{proc.stderr[-2000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1]), proc.stderr


def storm_values(printed: str) -> list[Fraction]:
    return [Fraction(line.strip()) for line in printed.strip().splitlines()]


#: The paper's three properties (the emitted file's first three; the other two are
#: conditional expectations, which ``--exact`` does not compute).
PAPER_PROPERTIES = 3


def bench_case1(workdir: Path) -> list[list[str]]:
    """``prism --exact`` and ``check --exact`` on case1 against Storm on the paper properties."""
    config = str(REPO / "configs/paper/case1.yaml")
    emitted = workdir / "case1"
    subprocess.run([EXE, "emit", config, "-o", str(emitted)], check=True, capture_output=True)
    lines = (emitted / "properties.props").read_text().splitlines()
    named = [line for line in lines if line.startswith('"')][:PAPER_PROPERTIES]
    paper = emitted / "paper.props"
    paper.write_text("\n".join(named) + "\n")
    storm, printed = measured([sys.executable, "-c", STORM_EXACT,
                               str(emitted / "model.prism"), str(paper)])
    expected = storm_values(printed)
    ours, out = measured([EXE, "prism", str(emitted / "model.prism"), "--props", str(paper),
                          "--exact", "--json"])
    document = json.loads(out)
    mine = [Fraction(r["exact"]) for r in document["results"]]
    states = f"{document['model']['states']:,}"
    rows = [_row("case1 prism (3 props)", states, ours, storm, mine == expected)]
    ours, out = measured([EXE, "check", config, "--exact", "--format", "json"])
    mine = [Fraction(v) for v in json.loads(out)["exact"].values()][:PAPER_PROPERTIES]
    rows.append(_row("case1 check (5 props)", states, ours, storm, mine == expected))
    return rows


def bench_haddad_monmege(n: int, workdir: Path) -> list[str]:
    model, props = workdir / "hm.prism", workdir / "hm.props"
    model.write_text(HADDAD_MONMEGE)
    props.write_text("P=? [ F x=0 ]\n")
    consts = f"N={n},p=0.7"
    ours, out = measured([EXE, "prism", str(model), "--props", str(props), "--const", consts,
                          "--exact", "--json"])
    storm, printed = measured([sys.executable, "-c", STORM_EXACT, str(model), str(props), consts])
    document = json.loads(out)
    mine = [Fraction(r["exact"]) for r in document["results"]]
    same = mine == storm_values(printed) == [Fraction(7, 10)]
    return _row(f"Haddad-Monmege N={n}", f"{document['model']['states']:,}", ours, storm, same)


def _row(name: str, states: str, ours: dict[str, float], storm: dict[str, float],
         same: bool) -> list[str]:
    return [name, states, f"{ours['wall_s']:.2f}", f"{storm['wall_s']:.2f}",
            f"{ours['wall_s'] / storm['wall_s']:.2f}", f"{ours['cpu_s']:.2f}",
            f"{storm['cpu_s']:.2f}", f"{ours['cpu_s'] / storm['cpu_s']:.2f}",
            f"{ours['peak_mb']:.0f}", f"{storm['peak_mb']:.0f}", "yes" if same else "NO"]


HEADER = ["model", "states", "vb --exact wall s", "storm exact wall s", "wall ratio",
          "vb cpu s", "storm cpu s", "cpu ratio", "vb peak MB", "storm peak MB",
          "same rationals"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="Haddad-Monmege only")
    args = parser.parse_args()
    rows = []
    print(" | ".join(HEADER), flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        for n in (20, 100, 300):
            rows.append(bench_haddad_monmege(n, Path(tmp)))
            print(" | ".join(rows[-1]), flush=True)
        if not args.quick:
            for row in bench_case1(Path(tmp)):
                rows.append(row)
                print(" | ".join(row), flush=True)


if __name__ == "__main__":
    main()
