# Two commands do all set-up: `make demo` and `make test` (see README).
VENV ?= .venv
PY := $(VENV)/bin/python

.PHONY: setup demo test test-slow bench clean

setup:
	@bash scripts/setup.sh

demo: setup
	$(PY) -m ambulo.cli demo

test: setup
	$(PY) -m pytest -q -p no:cacheprovider

test-slow: setup
	$(PY) -m pytest -q -m slow

bench: setup
	$(PY) benchmarks/engine_cpu.py

clean:
	rm -rf $(VENV) out runs
