# ServoBot co-evolution toolkit. `make demo` and `make test` work on a fresh machine.
PY      ?= python3
VENV    := .venv
BIN     := $(VENV)/bin
STAMP   := $(VENV)/.installed
OUT     ?= out
PYDIRS  := $(wildcard host protocol simulator tests bench)

.PHONY: help venv test demo demo-evolve bench lint sim clean

help:
	@echo "make demo    run a short paper experiment on the built-in simulated robot"
	@echo "make test    install into .venv and run the test suite"
	@echo "make demo-evolve  PAL over the serial link against the built-in emulator (about a minute)"
	@echo "make bench   run the benchmarks, writing bench/results/bench.json"
	@echo "make lint    ruff"
	@echo "make sim     run the Stamp emulator on a pseudo-terminal (REALTIME=0 for full speed)"

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

demo-evolve: $(STAMP)
	rm -rf $(OUT)/demo-evolve
	$(BIN)/pac-host evolve --out $(OUT)/demo-evolve --generations 480 --budget 200 --seed 1

bench: $(STAMP)
	$(BIN)/python bench/run.py --out bench/results/bench.json

sim: $(STAMP)
	$(BIN)/pac-sim --realtime $(or $(REALTIME),1)

lint: $(STAMP)
	$(BIN)/ruff check $(PYDIRS)

clean:
	rm -rf $(VENV) $(OUT) bench/results
