# Set-up and the two commands of the README. Everything runs inside .venv.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
CORES ?= 2
export NUMBA_CACHE_DIR := $(CURDIR)/.numba_cache
export NUMBA_NUM_THREADS := 1

.PHONY: venv reproduce quick test lint clean-results

$(BIN)/gearsim: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[dev]'
	touch $(BIN)/gearsim

venv: $(BIN)/gearsim

reproduce: venv  ## full reproduction of the study (config/config.yaml)
	. $(BIN)/activate && snakemake --cores $(CORES)

quick: venv  ## small grids for a fast look (config/quick.yaml)
	. $(BIN)/activate && snakemake --cores $(CORES) --configfile config/quick.yaml

test: venv  ## the test suite (what CI runs)
	. $(BIN)/activate && pytest -q

lint: venv
	. $(BIN)/activate && ruff check src tests benchmarks && snakemake --lint

clean-results:
	rm -rf results .snakemake
