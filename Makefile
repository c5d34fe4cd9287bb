# Two commands for a newcomer: `make demo` and `make test`. Both create .venv and install the
# package through constraints.txt on first use (and again when the packaging changes).
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
GELFABRIC ?= ../shared/data/gelfabric

.PHONY: demo test test-slow lint typecheck bench clean

$(STAMP): pyproject.toml constraints.txt
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -c constraints.txt -e '.[dev]'
	@touch $(STAMP)

demo: $(STAMP)
	$(BIN)/lookfeel demo --data $(GELFABRIC)

lint: $(STAMP)
	$(BIN)/ruff check src tests benchmarks
	$(BIN)/ruff format --check src tests benchmarks

typecheck: $(STAMP)
	$(BIN)/mypy

test: lint typecheck
	$(BIN)/python -m pytest -q

test-slow: $(STAMP)
	$(BIN)/python -m pytest -q -m slow

bench: $(STAMP)
	$(BIN)/python -m benchmarks $(if $(wildcard $(GELFABRIC)),--data $(GELFABRIC))

clean:
	rm -rf $(VENV) .pytest_cache .mypy_cache .ruff_cache
