# The README's commands. A fresh machine needs only Python 3.10+, a Rust toolchain and network
# access to PyPI and crates.io: everything else is installed here into .venv.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
OUT    ?= out

.PHONY: demo test test-slow install bench lint clean

$(VENV)/.deps: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q "maturin>=1.5,<2" "numpy>=1.23" "matplotlib>=3.6" "pytest>=7" \
		"netCDF4>=1.6" "xarray>=2023.1" "dask[distributed]>=2023.1" "vtk>=9.2"
	touch $@

# Builds the Rust extension in release mode into .venv (re-run after changing Rust code).
install: $(VENV)/.deps
	$(VENV)/bin/maturin develop --release -q

# The main job: the paper's fluidised column collapse on the coarse default grid (ny = 32), with
# the non-fluidised run beside it on front.png; plots and tables in $(OUT)/column*/ (~1 min).
demo: install
	$(VENV)/bin/granrs run column --no-fluidised --out $(OUT)/column-dry
	$(VENV)/bin/granrs run column --out $(OUT)/column --compare-with $(OUT)/column-dry

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

# The Rust tree's layout, clippy's lints as errors, and the core's floors (rust/granrs-core/src/lib.rs).
lint:
	cargo fmt --all -- --check
	cargo clippy --workspace --release --all-targets -- -D warnings
	python3 scripts/check_layers.py

clean:
	rm -rf $(VENV) target $(OUT)
