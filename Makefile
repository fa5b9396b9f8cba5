# make demo: create .venv, install, run the main job.  make test: the test suite.  make notebooks: JupyterLab.
# Both first run setup/install_prereqs (system packages: Chromium for the browser test).
PYTHON ?= python3.11
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
export PYTHON

.PHONY: demo test bench notebooks install prereqs clean

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

# JupyterLab on localhost only, in notebooks/ (Ctrl-C stops it); as root it needs --allow-root
notebooks: $(STAMP)
	$(BIN)/python -m pip install --quiet -e ".[notebooks]"
	$(BIN)/jupyter lab --ip=127.0.0.1 --notebook-dir=notebooks $$([ "$$(id -u)" = 0 ] && echo --allow-root) $(ARGS)

clean:
	rm -rf $(VENV) out
