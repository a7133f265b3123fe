# Two commands do everything on a fresh machine: `make run` and `make test`.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: run test setup lint typecheck bench clean bytecode chromium reports docs compare \
	compare-speed

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

$(STAMP): pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e ".[dev,storm,dask,pybamm]"
	touch $(STAMP)

setup: $(STAMP) bytecode

# Compile src/ to .pyc as a wheel install would: with PYTHONDONTWRITEBYTECODE set (as
# here), an editable install otherwise recompiles every module in every process
# (~0.4 s of CPU per command). Only stale files are recompiled.
bytecode: $(STAMP)
	$(BIN)/python -m compileall -q src >/dev/null

run: $(STAMP) bytecode
	$(BIN)/veribattery check configs/paper/case1.yaml

test: $(STAMP) lint chromium
	$(BIN)/python -m pytest -n 2 -q

# Debian's Chromium, for the report's browser test (tests/report/test_browser.py); the
# test skips, visibly, where it cannot be installed.
chromium:
	@command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1 || \
	  { SUDO=$$([ "$$(id -u)" = 0 ] || echo sudo); \
	    $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq chromium; } || \
	  echo "warning: Chromium not installed; the browser tests will be skipped" >&2

# The example reports in docs/reports/ (case 1 and the 12.8 Ah dip with its sweep).
reports: $(STAMP) bytecode
	$(BIN)/python docs/reports/make_reports.py

lint: $(STAMP)
	$(BIN)/ruff check src tests bench
	$(BIN)/mypy

bench: $(STAMP) bytecode
	$(BIN)/python bench/bench_models.py

# The working tree against a base revision, e.g. `make compare BASE=8887d91`: every value
# (check JSON on configs/, the three peer suites' outputs, emit's files) byte for byte,
# exit 1 on a difference; compare-speed times both side by side (QUICK=1 for a short run).
# ARGS passes more options (e.g. ARGS="--only check,prism" or ARGS="-n 3").
BASE ?= 8887d91
compare: $(STAMP)
	$(BIN)/python bench/compare_values.py $(BASE) $(ARGS)

compare-speed: $(STAMP)
	$(BIN)/python bench/compare_speed.py $(BASE) $(if $(QUICK),--quick) $(ARGS)

# The documentation site, offline, warnings as errors: the CLI, config and API references
# are generated from the code while it builds (docs/_ext/).
docs: $(STAMP)
	$(BIN)/python -m sphinx -W --keep-going -q -b html docs docs/_build/html

clean:
	rm -rf $(VENV) build dist .pytest_cache .mypy_cache
