# ServoBot co-evolution toolkit. `make demo` and `make test` work on a fresh machine.
PY      ?= python3
VENV    := .venv
BIN     := $(VENV)/bin
STAMP   := $(VENV)/.installed
OUT     ?= out
PYDIRS  := $(wildcard host protocol simulator tests bench)

.PHONY: help venv test demo bench bench-diagnose lint clean

help:
	@echo "make demo    run a short paper experiment on the built-in simulated robot"
	@echo "make test    install into .venv and run the test suite"
	@echo "make bench   run the benchmarks, writing bench/results/bench.json"
	@echo "make bench-diagnose  blind benchmark of the gap diagnosis, bench/results/diagnose.json"
	@echo "make lint    ruff"

$(STAMP): pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	$(BIN)/pip install -q -e '.[dev]'
	touch $(STAMP)

venv: $(STAMP)

test: $(STAMP)
	$(BIN)/ruff check $(PYDIRS)
	$(BIN)/python -m pytest

demo: $(STAMP)
	rm -rf $(OUT)/demo-experiment
	$(BIN)/pac-host experiment --seeds 4 --generations 400 --methods full,partial --jobs 2 --out $(OUT)/demo-experiment

bench: $(STAMP)
	$(BIN)/python bench/run.py --out bench/results/bench.json

bench-diagnose: $(STAMP)
	$(BIN)/python bench/run.py --only diagnose --out bench/results/diagnose.json

lint: $(STAMP)
	$(BIN)/ruff check $(PYDIRS)

clean:
	rm -rf $(VENV) $(OUT) bench/results
