# make demo: create .venv, install, run the main job.  make test: the test suite.  make notebooks: JupyterLab.
# make mutate: mutation testing of promp/ and library/ (minutes; not part of make test, see CONTRIBUTING.md).
# Both first run setup/install_prereqs (system packages: Chromium for the browser test).
PYTHON ?= python3.11
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
DEV_STAMP := $(VENV)/.installed-dev
export PYTHON
# The library's products are small (21-161 weights): OpenBLAS threads cost more to start than they
# save, several times over on 2 cores. Override with OPENBLAS_NUM_THREADS=n make ...
OPENBLAS_NUM_THREADS ?= 1
export OPENBLAS_NUM_THREADS

.PHONY: demo test bench notebooks install prereqs clean mutate

prereqs:
	@setup/install_prereqs

$(STAMP): pyproject.toml
	@command -v $(PYTHON) >/dev/null || { echo "need $(PYTHON) (set PYTHON=...)"; exit 1; }
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[test]"
	touch $(STAMP)

install: prereqs $(STAMP)

demo: install
	$(BIN)/drake-skills demo

test: install
	$(BIN)/python -m pytest -q

bench: $(STAMP)
	$(BIN)/drake-skills bench

$(DEV_STAMP): $(STAMP)
	$(BIN)/python -m pip install --quiet -e ".[dev]"
	touch $(DEV_STAMP)

# A fresh run every time (mutmut keeps a verdict until the mutated function changes, not when the
# tests do). MUTANTS='drake_skills.library.storage.*' limits it to one module. One BLAS thread:
# mutmut forks its workers, and a forked OpenBLAS thread pool can hang (seen as false timeouts).
MUTANTS ?=
mutate: $(DEV_STAMP)
	rm -rf mutants
	OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 $(BIN)/mutmut run $(MUTANTS) >mutants.log 2>&1 \
		|| { tail -c 3000 mutants.log; echo "mutmut failed: see mutants.log"; exit 1; }
	@mv mutants.log mutants/run.log
	$(BIN)/python .ci/mutation_report.py --mutmut $(BIN)/mutmut

# JupyterLab on localhost only, in notebooks/ (Ctrl-C stops it); as root it needs --allow-root
notebooks: $(STAMP)
	$(BIN)/python -m pip install --quiet -e ".[notebooks]"
	$(BIN)/jupyter lab --ip=127.0.0.1 --notebook-dir=notebooks $$([ "$$(id -u)" = 0 ] && echo --allow-root) $(ARGS)

clean:
	rm -rf $(VENV) out mutants mutants.log
