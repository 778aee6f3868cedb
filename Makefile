# The two commands of the README: `make run` and `make test`. Both create the
# virtual environment and install xcheck with its dependencies on first use, its
# modules byte-compiled as pip compiles an installed package's (an editable install's
# are not, and where $PYTHONDONTWRITEBYTECODE is set every process compiled them again);
# `make docs` builds the documentation site into docs/_build/html.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: run test lint docs bench clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev,docs,all]'
	$(BIN)/python -m compileall -q src
	touch $(STAMP)

# the command that reproduces the committed reports/fourbar.md (MJX runs only when named),
# so that it rewrites that report as it is
run: $(STAMP)
	$(BIN)/xcheck run fourbar --engines all

test: lint docs
	$(BIN)/python -m pytest -q -n auto

# the documentation site: warnings are errors (a page that names a missing page,
# a docstring that does not parse); the engines' tables come from the registry
docs: $(STAMP)
	$(BIN)/sphinx-build -W --keep-going -q -b html docs docs/_build/html

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy

# every benchmark of docs/benchmarks.md, each printed with its command (CLI: wall and CPU
# medians of N runs); what the runs write goes to BENCH_OUT, never into reports/
BENCH_OUT ?= $${TMPDIR:-/tmp}/xcheck-bench
bench: $(STAMP)
	OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 $(BIN)/python benchmarks/bench_solver.py
	OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 $(BIN)/python benchmarks/bench_chain_size.py --no-reference 1 5 20 50
	mkdir -p $(BENCH_OUT) && rm -rf $(BENCH_OUT)/fuzz
	$(BIN)/python benchmarks/bench_cli.py 5 $(BIN)/xcheck list
	$(BIN)/python benchmarks/bench_cli.py 5 $(BIN)/xcheck solve fourbar
	$(BIN)/python benchmarks/bench_main_job.py --out $(BENCH_OUT)/main-job
	$(BIN)/python benchmarks/bench_report_figures.py fourbar
	$(BIN)/python benchmarks/bench_numba_compile.py
	$(BIN)/python benchmarks/bench_cli.py 1 $(BIN)/xcheck simulate iftomm-a02 --engines native --json --no-report
	OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 $(BIN)/python benchmarks/bench_free_step.py
	OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 $(BIN)/python benchmarks/bench_free_reference.py
	$(BIN)/python benchmarks/bench_cli.py 1 $(BIN)/xcheck fuzz --count 20 --seed 1 --out $(BENCH_OUT)/fuzz

clean:
	rm -rf $(VENV) build src/*.egg-info .pytest_cache tests/.jax-cache docs/_build
