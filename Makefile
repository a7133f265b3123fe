# Two commands do everything on a fresh machine: `make run` and `make test`.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: run test setup lint typecheck bench clean bytecode

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

test: $(STAMP) lint
	$(BIN)/python -m pytest -n 2 -q

lint: $(STAMP)
	$(BIN)/ruff check src tests bench
	$(BIN)/mypy

bench: $(STAMP) bytecode
	$(BIN)/python bench/bench_models.py

clean:
	rm -rf $(VENV) build dist .pytest_cache .mypy_cache
