# Set-up and the two commands of the README. Everything runs inside .venv.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
CORES ?= 2
export NUMBA_CACHE_DIR := $(CURDIR)/.numba_cache
export NUMBA_NUM_THREADS := 1

.PHONY: venv reproduce quick test test-fast lint clean-results

# A run killed hard (SIGKILL, power loss) leaves Snakemake's directory lock behind. Clear it when
# no snakemake process works in this directory, then resume: finished tiles are kept, a tile that
# was cut off is recomputed (tiles are written to a temporary name and renamed when complete).
define unlock_stale
	@for pid in $$(pgrep -f '[s]nakemake' || true); do \
	  case "$$(readlink /proc/$$pid/cwd 2>/dev/null)" in "$(CURDIR)"|"$(CURDIR)"/studies/*) exit 0;; esac; \
	done; . $(BIN)/activate && snakemake --unlock --cores 1 $(1) >/dev/null 2>&1 || true
endef

# The tested versions of requirements.lock (constraints), within pyproject.toml's ranges;
# VENV_EXTRAS: the optional extras installed with it, in the same pip run (CI: dev,gpu).
VENV_EXTRAS ?= dev
$(BIN)/gearsim: pyproject.toml requirements.lock
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -c requirements.lock -e '.[$(VENV_EXTRAS)]'
	touch $(BIN)/gearsim

venv: $(BIN)/gearsim

reproduce: venv  ## full reproduction of the study (config/config.yaml)
	$(unlock_stale)
	. $(BIN)/activate && snakemake --cores $(CORES) --rerun-incomplete

quick: venv  ## small grids for a fast look (config/quick.yaml), in studies/quick/
	$(call unlock_stale,--configfile config/quick.yaml)
	. $(BIN)/activate && snakemake --cores $(CORES) --rerun-incomplete --configfile config/quick.yaml

# The suite on TEST_WORKERS pytest-xdist workers, one test file per unit (tests/conftest.py: files
# sharing a session-scoped study are one unit). The kernels are compiled into NUMBA_CACHE_DIR once
# first, as the workflow's `compile` rule does, so the workers load them instead of compiling the
# same kernels side by side. Three workers on two cores: the SLURM test's unit spends most of its
# ~6 minutes waiting on the scheduler, and a third worker keeps both cores busy meanwhile.
TEST_WORKERS ?= 3
# Beside it, the CUDA lane kernel under Numba's CUDA simulator: its own pytest process, since
# NUMBA_ENABLE_CUDASIM must be set before Numba is imported (skipped without numba-cuda, the
# gpu extra that .ci/run installs). It runs while the suite waits on its SLURM test's scheduler
# (the suite keeps about 1.3 of 2 cores busy), its output shown after the suite's; the target
# fails when either fails.
SIM_TESTS := tests/unit/test_cuda_lanes.py tests/unit/test_cuda_chains.py
test: venv  ## the test suite (what CI runs)
	. $(BIN)/activate && gearsim compile
	. $(BIN)/activate && sim_log=$$(mktemp) && \
	  { NUMBA_ENABLE_CUDASIM=1 nice -n 5 pytest -q -p no:cacheprovider $(SIM_TESTS) >"$$sim_log" 2>&1 & } && \
	  sim=$$! && suite=0 && { pytest -q -n $(TEST_WORKERS) --dist loadfile --durations=30 || suite=$$?; } && \
	  simrc=0 && { wait $$sim || simrc=$$?; } && echo "--- CUDA lane kernel under the simulator:" && \
	  cat "$$sim_log" && rm -f "$$sim_log" && test $$suite -eq 0 && test $$simrc -eq 0

# The unit tier only (tests/unit): seconds per file, under a minute on 2 cores with a warm cache.
test-fast: venv
	. $(BIN)/activate && gearsim compile && pytest -q -n $(TEST_WORKERS) --dist loadfile tests/unit

# The layer contracts (import-linter, pyproject.toml), ruff, and Snakemake's own lint.
lint: venv
	. $(BIN)/activate && lint-imports && ruff check src tests benchmarks && snakemake --lint

# Every run's outputs: the paper's study (results/), the fast look's and every study's folder
# (studies/), Snakemake's records and the jobs' configuration files (.snakemake/).
clean-results:
	rm -rf results studies .snakemake
