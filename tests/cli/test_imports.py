"""Start-up: a command imports only what it needs (a regression guard for lazy imports).

Each case runs in a fresh interpreter (``sys.modules`` of the test process is shared by
every test) and lists the top-level packages it ended up importing.
"""

from __future__ import annotations

import json
import subprocess
import sys
from fractions import Fraction
from pathlib import Path

import pytest

#: Never needed to start the CLI, print help or check a mission.
HEAVY = ("pandas", "matplotlib", "dask", "distributed", "pyarrow", "pybamm", "stormpy")
#: Needed by checking, but not to start the CLI or print its help.
ENGINE = ("numpy", "scipy", "lark", "jinja2", "pydantic", "yaml", "rich")

_LIST_MODULES = """
import json, sys
{body}
print(json.dumps(sorted({{name.partition('.')[0] for name in sys.modules}})))
"""


def _imported(body: str) -> set[str]:
    """The top-level packages imported by running *body* in a fresh interpreter."""
    script = _LIST_MODULES.format(body=body)
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          check=True)
    return set(json.loads(done.stdout.splitlines()[-1]))


def _run_cli(*args: str) -> str:
    return ("from veribattery.cli import main\n"
            f"try:\n    main({list(args)!r})\nexcept SystemExit:\n    pass\n")


def test_importing_the_cli_imports_no_library() -> None:
    imported = _imported("import veribattery.cli")
    assert "click" in imported  # the case is real: the CLI was imported
    assert imported.isdisjoint(HEAVY + ENGINE), sorted(imported & {*HEAVY, *ENGINE})


@pytest.mark.parametrize("args", [("--help",), ("check", "--help"), ("sweep", "--help")])
def test_help_imports_no_library(args: tuple[str, ...]) -> None:
    imported = _imported(_run_cli(*args))
    assert imported.isdisjoint(HEAVY + ENGINE), sorted(imported & {*HEAVY, *ENGINE})


def test_check_imports_no_dataframe_plotting_or_cluster_library(tmp_path: Path) -> None:
    config = tmp_path / "small.yaml"  # a 2x2 farm: checked in well under a second
    config.write_text("farm: {cols: 2, rows: 2, base: [0, 0]}\nbattery: {resolution_ah: 0.5}\n")
    imported = _imported(_run_cli("check", str(config), "--format", "json"))
    assert {"numpy", "scipy", "pydantic"} <= imported  # the case is real: it checked
    assert imported.isdisjoint(HEAVY), sorted(imported & set(HEAVY))


def test_a_sweep_worker_imports_no_dataframe_library() -> None:
    # What a worker process imports to unpickle and run a task.
    imported = _imported("import veribattery.sweep.execute, veribattery.sweep.tasks")
    assert "numpy" in imported  # the case is real: the checker was imported
    assert imported.isdisjoint(HEAVY), sorted(imported & set(HEAVY))


_TINY = """dtmc
module m
 x : [0..2] init 0;
 [] x=0 -> 0.5:(x'=1) + 0.5:(x'=2);
 [] x>0 -> true;
endmodule
"""


def test_checking_a_prism_file_as_json_needs_no_parser_generator_tables_or_configs(
    tmp_path: Path,
) -> None:
    # Small models are most of the public benchmarks: start-up is their cost.
    model = tmp_path / "tiny.prism"
    model.write_text(_TINY)
    body = _run_cli("prism", str(model), "--property", "P=? [ F x=1 ]", "--json")
    imported = _imported(body)
    assert {"numpy", "scipy"} <= imported  # the case is real: it checked
    unneeded = {"lark", "rich", "pydantic", "yaml", "jinja2", "pyamg", "gmpy2", *HEAVY}
    assert imported.isdisjoint(unneeded), sorted(imported & unneeded)


def test_the_cli_defers_numpy_modules_that_scipy_drags_in(tmp_path: Path) -> None:
    model = tmp_path / "tiny.prism"
    model.write_text(_TINY)
    body = _run_cli("prism", str(model), "--property", "P=? [ F x=1 ]", "--json")
    script = body + "import sys\nprint(sorted(m for m in sys.modules if m.startswith(" \
        "('numpy.f2py.', 'numpy.testing.'))))\n"
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          check=True)
    assert '"value": 0.5' in done.stdout  # the case is real: it checked
    assert done.stdout.splitlines()[-1] == "[]"


def _modules_after(body: str) -> tuple[list[str], str]:
    """Every module imported by running *body* in a fresh interpreter, and its output."""
    script = body + "import sys\nprint(sorted(sys.modules))\n"
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          check=True)
    *output, modules = done.stdout.splitlines()
    return eval(modules), "\n".join(output)  # a printed list of str


#: What a small ``P=? [ F ... ]`` check does not use, so does not import: the kernels of
#: rarer kinds of property (steady state, conditional, reward-bounded), answers at a
#: few states, a sweep's re-use and lumping, cyclic systems' segments, the exact last
#: resort (and ``fractions``), the unfused successor expansion.
COLD = (
    "veribattery.checker.kernels.steady", "veribattery.checker.kernels.conditional",
    "veribattery.checker.kernels.reward_bounded", "veribattery.checker.kernels.reward_radius",
    "veribattery.checker.certify.focus", "veribattery.explore.reuse.lumping",
    "veribattery.explore.reuse.structure", "veribattery.checker.linalg.scc",
    "veribattery.checker.linalg.rational", "fractions", "veribattery.explore.build.successors",
)


def test_a_small_check_imports_no_module_it_does_not_use(tmp_path: Path) -> None:
    # Table output into a pipe: rich (colours, widths) has nothing to add there either.
    model = tmp_path / "tiny.prism"
    model.write_text(_TINY)
    modules, output = _modules_after(_run_cli("prism", str(model), "--property", "P=? [ F x=1 ]"))
    assert "P=? [ F x=1 ]  0.5" in output and "Time: parse " in output  # it checked
    assert "veribattery.checker.kernels" in modules  # the case is real: the checker ran
    unused = [m for m in modules if m in COLD or m.partition(".")[0] == "rich"]
    assert unused == []


def test_a_check_without_a_linear_solve_imports_no_solver_package(tmp_path: Path) -> None:
    # csgraph (SCCs, BFS) reads LinearOperator from scipy.sparse.linalg: that package
    # (every sparse solver, ARPACK, LOBPCG) and scipy.linalg are set up, never run.
    model = tmp_path / "tiny.prism"
    model.write_text(_TINY)
    modules, output = _modules_after(
        _run_cli("prism", str(model), "--property", "P=? [ F x=1 ]", "--json"))
    assert '"value": 0.5' in output  # the case is real: it checked
    assert "scipy.sparse.csgraph" in modules and "scipy.sparse.linalg" in modules
    solvers = [m for m in modules if m.startswith(("scipy.sparse.linalg._isolve",
                                                   "scipy.sparse.linalg._eigen",
                                                   "scipy.linalg."))]
    assert solvers == []


def test_a_check_with_sparse_lu_runs_no_krylov_solver_package(tmp_path: Path) -> None:
    # Gambler's ruin from 10 of 20, up-probability 0.6: a cyclic system (SuperLU, and
    # the steady-state solver reads spsolve). Exact: (1 - r^10) / (1 - r^20), r = 2/3.
    # The direct solvers are served without running scipy.sparse.linalg's __init__
    # (every Krylov and eigen solver, all of scipy.linalg).
    model = tmp_path / "ruin.prism"
    model.write_text("dtmc\nmodule m\n x : [0..20] init 10;\n"
                     " [] x>0 & x<20 -> 0.4:(x'=x-1) + 0.6:(x'=x+1);\n"
                     " [] x=0 | x=20 -> true;\nendmodule\n")
    modules, output = _modules_after(_run_cli(
        "prism", str(model), "--property", "P=? [ F x=20 ]", "--property", "S=? [ x=20 ]",
        "--json"))
    r = Fraction(2, 3)
    exact = float((1 - r**10) / (1 - r**20))
    values = [result["value"] for result in json.loads(output)["results"]]
    assert values == [pytest.approx(exact, rel=1e-12)] * 2
    assert "scipy.sparse.linalg._dsolve._superlu" in modules  # SuperLU solved it
    krylov = [m for m in modules if m.startswith(("scipy.sparse.linalg._isolve",
                                                  "scipy.sparse.linalg._eigen",
                                                  "scipy.linalg."))]
    assert krylov == []
    # The cold modules load when met: steady state for S, segments for a cyclic system.
    assert {"veribattery.checker.kernels.steady", "veribattery.checker.linalg.scc"} <= set(modules)


#: What an MDP's float check does not use: the DTMC checker (formula recursion, kernels,
#: DTMC solvers, their workspace, the DTMC session), the exact engine (gmpy2, a last
#: resort), rich for output into a pipe, and scipy's Krylov and dense solvers.
MDP_COLD = (
    "veribattery.checker.api", "veribattery.checker.formula.pctl",
    "veribattery.checker.kernels", "veribattery.checker.linalg.factorization",
    "veribattery.checker.linalg.triangular", "veribattery.checker.workspace",
    "veribattery.pipeline.session", "veribattery.checker.exact", "gmpy2",
    "scipy.sparse.linalg._isolve", "scipy.linalg._basic", "rich",
)

_COIN_MDP = """mdp
module m
 x : [0..3] init 0;
 [safe]  x=0 -> 0.5:(x'=1) + 0.5:(x'=0);
 [risky] x=0 -> 0.7:(x'=1) + 0.3:(x'=2);
 [] x>0 -> (x'=3);
 [] x=3 -> true;
endmodule
"""


def test_an_mdp_float_check_imports_no_dtmc_checker_or_exact_engine(tmp_path: Path) -> None:
    # From x=0, "safe" retries until x=1 (probability 1); "risky" reaches x=1 with 0.7.
    # So Pmax [ F x=1 ] = 1 and Pmin = 0.7 (risky once, then x=2 forever misses x=1).
    model = tmp_path / "coin.prism"
    model.write_text(_COIN_MDP)
    modules, output = _modules_after(_run_cli(
        "prism", str(model), "--property", "Pmax=? [ F x=1 ]", "--property",
        "Pmin=? [ F x=1 ]", "--json"))
    values = [result["value"] for result in json.loads(output)["results"]]
    assert values == [pytest.approx(1.0, abs=1e-12), pytest.approx(0.7, abs=1e-12)]
    assert "veribattery.checker.mdp.optimum" in modules  # the case is real: the MDP engine ran
    unused = [m for m in modules if m.startswith(MDP_COLD)]
    assert unused == []
