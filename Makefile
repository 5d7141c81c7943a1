# The README's commands. A fresh machine needs only Python 3.10+, a Rust toolchain and network
# access to PyPI and crates.io: everything else is installed here into .venv.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
OUT    ?= out

.PHONY: demo test test-slow install bench lint format clean docs docs-deps

$(VENV)/.deps: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q "maturin>=1.5,<2" "numpy>=1.23" "matplotlib>=3.6" "pytest>=7" "hypothesis>=6" \
		"netCDF4>=1.6" "xarray>=2023.1" "dask[distributed]>=2023.1" "vtk>=9.2" "ruff>=0.6" "mypy>=1.10" "clarabel>=0.9"
	touch $@

# Builds the Rust extension in release mode into .venv (re-run after changing Rust code).
install: $(VENV)/.deps
	$(VENV)/bin/maturin develop --release -q

# The main job: the paper's fluidised column collapse on the coarse default grid (ny = 32), with
# the non-fluidised run beside it on front.png; plots and tables in $(OUT)/column*/ (~1 min).
demo: install
	$(VENV)/bin/granrs run column --no-fluidised --overwrite --out $(OUT)/column-dry
	$(VENV)/bin/granrs run column --overwrite --out $(OUT)/column --compare-with $(OUT)/column-dry

# The whole fast test suite: Rust tests (release) then pytest.
test: install
	cargo test --release --workspace --exclude granrs-py
	$(PY) -m pytest -q

# Long validations (minutes to an hour on 2 cores).
test-slow: install
	cargo test --release --workspace --exclude granrs-py -- --ignored
	$(PY) -m pytest -q -m slow

bench: install
	cargo bench -p granrs-core

# The Rust tree's layout, clippy's lints as errors, the core's floors (rust/granrs-core/src/lib.rs) and
# the Python package's floors (docs/architecture.md);
# the Python code's lints and layout (ruff), the package's types (mypy) and the extension's stubs
# against the compiled module (mypy.stubtest; settings in pyproject.toml).
PY_SOURCES := python tests examples studies scripts benchmarks

lint: install
	cargo fmt --all -- --check
	cargo clippy --workspace --release --all-targets -- -D warnings
	python3 scripts/check_layers.py
	python3 scripts/check_python_layers.py
	$(VENV)/bin/ruff check $(PY_SOURCES)
	$(VENV)/bin/ruff format --check $(PY_SOURCES)
	$(VENV)/bin/mypy
	$(PY) -m mypy.stubtest granrs._granrs

# Rewrites the Python code to what make lint checks: ruff's fixable lints (import order, unused
# imports, ...), then its layout.
format: $(VENV)/.deps
	$(VENV)/bin/ruff check --fix $(PY_SOURCES)
	$(VENV)/bin/ruff format $(PY_SOURCES)

clean:
	rm -rf $(VENV) target $(OUT) docs/_build docs/auto_examples docs/reference/generated

# The documentation's own requirements, into .venv (lower bounds: the versions it is built with).
$(VENV)/.docs-deps: $(VENV)/.deps
	$(PY) -m pip install -q "sphinx>=7.2" "myst-parser>=2.0" "furo>=2024.1.29" "numpydoc>=1.6" \
		"sphinx-gallery>=0.15"
	touch $@

docs-deps: $(VENV)/.docs-deps

# The documentation site into docs/_build/html; warnings are errors; the gallery runs (~2 min).
docs: install docs-deps
	$(VENV)/bin/sphinx-build -W --keep-going -b html docs docs/_build/html
