# pito — `make demo` starts the app on the simulated cube, `make test` runs every test.
# Both set everything up first (system packages, .venv, pito installed editable).

PYTHON ?= python3
VENV   ?= .venv
BIN     = $(VENV)/bin
XVFB    = xvfb-run -a -s "-screen 0 1600x1000x24"

.PHONY: demo test deps venv lint screenshots bench reproduce clean

demo: deps venv
	$(BIN)/pito-app --demo

test: deps venv
	$(BIN)/lint-imports
	$(XVFB) $(BIN)/python -m pytest -q -n 2 --dist loadgroup --durations=15 $(PYTEST_ARGS)

deps:
	@bash scripts/install-system-deps.sh

venv: $(VENV)/.installed

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -e ".[app,interop,analysis,test]"
	touch $@

lint: venv
	$(BIN)/lint-imports

screenshots: deps venv
	for page in live mount load results; do \
	  $(XVFB) $(BIN)/pito-app --demo --screenshot docs/screenshots/$$page.png --page $$page; done

bench: venv
	$(BIN)/pito bench

reproduce: venv
	$(BIN)/pito reproduce --out out/reproduction

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache
