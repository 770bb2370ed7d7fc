# The two commands of the README:
#   make demo   set everything up, then run the main job on the shipped default
#   make test   set everything up, then run the tests (what .ci/run calls)
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: setup demo test lint clean

setup: $(STAMP)

$(STAMP): pyproject.toml constraints.txt
	@bash .ci/system-deps
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	# The CPU wheel first: a looser spec would pull a multi-GB CUDA build.
	$(BIN)/pip install --quiet torch==2.13.0
	# Every version held (constraints.txt): the benchmark problems depend on them.
	$(BIN)/pip install --quiet -c constraints.txt -e '.[dev]'
	# Compile the planning kernels once; later processes load them from numba's cache.
	$(BIN)/python -m planning.compiled.warmup
	@touch $(STAMP)

demo: setup
	$(BIN)/gaide demo

test: setup
	$(BIN)/python -m pytest -q

lint: setup
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy

clean:
	rm -rf $(VENV) build *.egg-info
