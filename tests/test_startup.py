"""The CLI's start-up deferrals: what they defer, and that a deferred module is the real one.

Each case runs in a fresh interpreter: the deferrals apply only to modules imported
after they are installed, and the test process has imported scipy long before.
"""

from __future__ import annotations

import os
import subprocess
import sys

from veribattery._collector import YOUNG_COLLECTION_EVERY
from veribattery._startup import DEFERRED_MODULES, LAZY_PACKAGES

_PRELUDE = """
import sys
from veribattery._startup import defer_unused_numpy_modules
defer_unused_numpy_modules()
"""


def _run(body: str) -> list[str]:
    done = subprocess.run([sys.executable, "-c", _PRELUDE + body], capture_output=True,
                          text=True, check=True)
    return done.stdout.split()


def test_csgraph_works_without_running_the_solver_packages() -> None:
    out = _run("""
import numpy as np, scipy.sparse as sp
from scipy.sparse import csgraph
graph = sp.csr_matrix(np.array([[0, 1, 0], [0, 0, 1], [1, 0, 0]]))
count, _ = csgraph.connected_components(graph, directed=True, connection="strong")
from scipy.sparse.linalg import LinearOperator  # served
double = LinearOperator((2, 2), matvec=lambda v: 2 * v)
print(count, "scipy.sparse.linalg._isolve" in sys.modules, "scipy.linalg._basic" in sys.modules,
      double.matvec(np.ones(2)).tolist() == [2.0, 2.0])
""")
    assert out == ["1", "False", "False", "True"]


def test_served_names_are_the_objects_the_package_exports() -> None:
    assert LAZY_PACKAGES, "no package is served lazily any more: this test checks nothing"
    for package, served in LAZY_PACKAGES.items():
        for name, home in served.items():
            out = _run(f"""
import importlib
served = getattr(importlib.import_module({home!r}), {name!r})
package = importlib.import_module({package!r})
early = getattr(package, {name!r})  # served, the package not run
ran = "__all__" in vars(package)
package.__all__  # now it runs
hook = vars(package).get("__getattr__")
print(ran, early is served, getattr(package, {name!r}) is served,
      hook is None or hook.__module__ != "veribattery._startup",
      type(package.__loader__).__name__ != "_PackageLoader")
""")
            assert out == ["False", "True", "True", "True", "True"], (package, name)


def test_a_lazy_package_runs_once_when_read_from_many_threads() -> None:
    out = _run("""
import threading
import scipy.sparse.linalg as spla
found = []
def read():
    found.append(spla.gmres)  # not served: the first reader runs the package
threads = [threading.Thread(target=read) for _ in range(8)]
for thread in threads:
    thread.start()
for thread in threads:
    thread.join()
import numpy as np, scipy.sparse as sp
x = spla.splu(sp.csc_matrix(np.array([[2.0, 1.0], [1.0, 3.0]]))).solve(np.array([3.0, 4.0]))
print(len(found), len({id(f) for f in found}), np.allclose(x, [1.0, 1.0]))
from scipy.sparse.linalg import *  # noqa
print(callable(gmres), "scipy.sparse.linalg._isolve" in sys.modules)
""")
    assert out == ["8", "1", "True", "True", "True"]


def test_deferred_numpy_modules_load_on_first_use() -> None:
    out = _run(f"""
import scipy.sparse  # imports every name of numpy's __all__
names = {sorted(DEFERRED_MODULES)!r}
print(len([name for name in names if type(sys.modules.get(name)).__name__ == "_LazyModule"]))
import numpy as np
print(np.ma.masked_array([1, 2], mask=[0, 1]).sum(), np.polynomial.Polynomial([1, 2])(3.0))
print(np.fft.fft(np.ones(4))[0].real, "Create a new string" in __import__("pydoc").getdoc(str))
# numpy's compiled functions have no docstrings until their module is read.
print(np.empty.__doc__ is None, np.float64.__doc__ is None)
for docs in ("numpy._core._add_newdocs", "numpy._core._add_newdocs_scalars"):
    sys.modules[docs].__name__  # read: it runs
print(np.empty.__doc__.startswith("empty(shape"), "Double-precision" in np.float64.__doc__)
""")
    assert out == [str(len(DEFERRED_MODULES)), "1", "7.0", "4.0", "True", "True", "True",
                   "True", "True"]


def test_start_process_turns_pydantic_plugins_off_unless_the_user_chose() -> None:
    script = """
import os
from veribattery._startup import start_process
start_process()
print(os.environ["PYDANTIC_DISABLE_PLUGINS"])
"""
    for preset, expected in ((None, "__all__"), ("", ""), ("logfire", "logfire")):
        env = {k: v for k, v in os.environ.items() if k != "PYDANTIC_DISABLE_PLUGINS"}
        if preset is not None:
            env["PYDANTIC_DISABLE_PLUGINS"] = preset
        done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                              check=True, env=env)
        assert done.stdout.strip() == expected


def test_start_process_collects_the_youngest_generation_less_often() -> None:
    script = """
import gc
gc.set_threshold(700, 11, 12)
from veribattery._collector import YOUNG_COLLECTION_EVERY
from veribattery._startup import start_process
start_process()
print(gc.get_threshold() == (YOUNG_COLLECTION_EVERY, 11, 12), YOUNG_COLLECTION_EVERY > 700)
"""
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          check=True)
    assert done.stdout.split() == ["True", "True"]


def test_a_library_build_spaces_collections_and_restores_the_callers() -> None:
    # A notebook keeps its own thresholds; only while a stage runs are they spaced out.
    import gc

    import veribattery as vb
    from veribattery._collector import spaced_collections

    seen: list[tuple[int, ...]] = []
    before = gc.get_threshold()
    try:
        gc.set_threshold(700, 11, 12)
        flat = vb.flatten_model(vb.parse_model("dtmc\nmodule m x : [0..3]; "
                                               "[] x<3 -> (x'=x+1); endmodule\n"))
        dtmc = vb.build_dtmc(flat, progress=lambda *_: seen.append(gc.get_threshold()))
        assert dtmc.num_states == 4
        assert seen and all(t == (YOUNG_COLLECTION_EVERY, 11, 12) for t in seen)
        assert gc.get_threshold() == (700, 11, 12)
        gc.set_threshold(0, 11, 12)  # collection off: left off
        with spaced_collections():
            assert gc.get_threshold() == (0, 11, 12)
        gc.set_threshold(10**6, 11, 12)  # already larger: kept
        with spaced_collections():
            assert gc.get_threshold() == (10**6, 11, 12)
    finally:
        gc.set_threshold(*before)
