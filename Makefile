# tli-verify: two commands on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed-stamp
JOBS   ?= 2
export MPLBACKEND := Agg

.PHONY: demo test test-all lint bench gate clean venv

venv: $(STAMP)

$(STAMP): pyproject.toml
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev]'
	@touch $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/tli demo --out out

lint: $(STAMP)
	$(VENV)/bin/ruff check tli_verify tests benchmarks scripts
	$(VENV)/bin/mypy

test: $(STAMP) lint
	$(PY) -m pytest -m "not slow" -n $(JOBS) -q

test-all: $(STAMP) lint
	$(PY) -m pytest -n $(JOBS) -q

bench: $(STAMP)
	$(PY) -m benchmarks --out benchmarks/results

gate: $(STAMP)
	$(VENV)/bin/tli gate

clean:
	rm -rf out .pytest_cache .mypy_cache .ruff_cache
