# Two commands do all set-up: `make demo` and `make test` (see README).
VENV ?= .venv
PY := $(VENV)/bin/python

.PHONY: setup demo test lint bench clean

setup:
	@bash scripts/setup.sh

demo: setup
	$(PY) -m ambulo.cli demo

test: setup
	$(PY) -m pytest -q -p no:cacheprovider --durations=30

# ruff, then the import contracts of pyproject.toml [tool.importlinter] (the layers of DESIGN.md,
# no import cycles); --no-cache: the graph of ~250 modules takes under a second to build
lint: setup
	$(PY) -m ruff check src tests examples benchmarks scripts
	$(VENV)/bin/lint-imports --no-cache

bench: setup
	$(PY) benchmarks/engine_cpu.py

clean:
	rm -rf $(VENV) out runs
