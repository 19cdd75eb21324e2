# ServoBot co-evolution toolkit. `make demo` and `make test` work on a fresh machine.
PY      ?= python3
VENV    := .venv
BIN     := $(VENV)/bin
STAMP   := $(VENV)/.installed
OUT     ?= out
TEST_JOBS ?= 2
PYDIRS  := $(wildcard host protocol simulator tests bench)

.PHONY: help venv test test-all demo demo-evolve experiment bench bench-diagnose lint sim sim-firmware clean firmware

help:
	@echo "make demo    about 2 minutes on two cores: PAL over the serial link against the built-in emulated"
	@echo "             robot, then a small experiment (the learnt model against the oracle); plots in out/"
	@echo "make experiment  the paper's question, 30 seeds of full, partial and the oracle (--profile paper;"
	@echo "             a few minutes; RESUME=1 continues it) in out/experiment"
	@echo "make test    install into .venv and run the test suite (make test-all: and the slow end-to-end runs)"
	@echo "make demo-evolve  PAL over the serial link against the built-in emulator, longer (a few minutes)"
	@echo "make bench   run the benchmarks, writing bench/results/bench.json"
	@echo "make bench-diagnose  blind benchmark of the gap diagnosis, bench/results/diagnose.json"
	@echo "make lint    ruff"
	@echo "make sim     run the Stamp emulator on a pseudo-terminal (REALTIME=0 for full speed)"
	@echo "make sim-firmware  the same, running firmware/servobot.bs2 itself in the PBASIC interpreter"
	@echo "make firmware  tokenize firmware/servobot.bs2 (Node.js), writing build/servobot.json and .bin"

$(STAMP): pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	$(BIN)/pip install -q -e '.[dev]'
	touch $(STAMP)

venv: $(STAMP)

# The firmware: Parallax's tokenizer (npm pbasic-tokenizer, pinned by firmware/package-lock.json).
FW_DEPS := firmware/node_modules/.package-lock.json
FW_IMAGE := build/servobot.json

$(FW_DEPS): firmware/package.json firmware/package-lock.json
	cd firmware && npm ci --no-audit --no-fund --loglevel=error

$(FW_IMAGE): firmware/servobot.bs2 firmware/tools/tokenize.js $(FW_DEPS)
	node firmware/tools/tokenize.js firmware/servobot.bs2 --out build

firmware: $(FW_IMAGE)

# the tests run in TEST_JOBS processes (pytest-xdist); each has its own pseudo-terminals,
# ephemeral tracker ports and tmp dirs, so none shares a resource with another; worksteal
# keeps one process from idling while the other runs the slow tests at the end. Each process
# keeps its linear algebra on one thread (SINGLE_BLAS): the fits' matrices are 32 x 32, and two
# processes with a BLAS thread per core each took the suite from 6 min 7 s to 7 min 51 s
SINGLE_BLAS := OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 MKL_NUM_THREADS=1
test: $(STAMP) firmware
	$(BIN)/ruff check $(PYDIRS)
	$(SINGLE_BLAS) $(BIN)/python -m pytest -n $(TEST_JOBS) --dist worksteal -m "not slow"

# and the long end-to-end runs (marked slow: evolve over the firmware, the camera rig over a
# whole default run, link recovery at real speed), a few minutes more
test-all: $(STAMP) firmware
	$(BIN)/ruff check $(PYDIRS)
	$(SINGLE_BLAS) $(BIN)/python -m pytest -n $(TEST_JOBS) --dist worksteal

# The main job on the built-in simulated robot, in about 2 minutes on two cores: PAL over the
# serial protocol against the emulated Stamp on a pseudo-terminal (bench/bench_demo.py checks
# this evolve line's result), then a small experiment: the default method's learnt model
# against the oracle control (under the default profile full and partial recombination are
# the same run). Progress goes to stderr, a line per step through a pipe.
demo: $(STAMP)
	rm -rf $(OUT)/demo-experiment $(OUT)/demo-evolve
	$(BIN)/pac-host evolve --out $(OUT)/demo-evolve --generations 160 --budget 200 --search-evaluations 200000 --seed 1
	$(BIN)/pac-host experiment --seeds 2 --generations 80 --methods partial,oracle --search-evaluations 50000 --optimum-runs 2 --jobs 2 --out $(OUT)/demo-experiment
	@echo "demo done: plots in $(OUT)/demo-evolve/*.png and $(OUT)/demo-experiment/*.png"

# The paper's question on 30 seeds (docs/how-to/experiment.md): a few minutes on two cores.
experiment: $(STAMP)
	$(BIN)/pac-host experiment --profile paper --seeds 30 --generations 1000 --methods full,partial,oracle --jobs 2 --out $(OUT)/experiment $(if $(RESUME),--resume)

demo-evolve: $(STAMP)
	rm -rf $(OUT)/demo-evolve
	$(BIN)/pac-host evolve --out $(OUT)/demo-evolve --generations 480 --budget 200 --seed 1

bench: $(STAMP)
	$(BIN)/python bench/run.py --out bench/results/bench.json

bench-diagnose: $(STAMP)
	$(BIN)/python bench/run.py --only diagnose --out bench/results/diagnose.json

sim: $(STAMP)
	$(BIN)/pac-sim --realtime $(or $(REALTIME),1)

sim-firmware: $(STAMP) firmware
	$(BIN)/pac-sim --realtime $(or $(REALTIME),1) --firmware firmware/servobot.bs2 --image $(FW_IMAGE)

lint: $(STAMP)
	$(BIN)/ruff check $(PYDIRS)

clean:
	rm -rf $(VENV) $(OUT) bench/results build firmware/node_modules
