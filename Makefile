# reflect: batch renderer for mirror reflections.
# `make demo` installs into .venv and renders the bundled teapot-box scene (EXR + PNG preview).
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
SCENE ?= scenes/teapot-box.toml

.PHONY: demo install test lint render bench figures smoke fuzz clean

demo: install
	$(BIN)/reflect render $(SCENE) --frames 0 --preview

$(BIN)/reflect: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[dev,plots,dask]'
	touch $(BIN)/reflect

install: $(BIN)/reflect

test: install
	$(BIN)/pytest -q

lint: install
	$(BIN)/ruff check reflectcli tests benchmarks scripts

render: install
	$(BIN)/reflect render $(SCENE) --preview

bench: install
	$(BIN)/reflect bench configs/bench/paper-dprm.toml
	$(BIN)/reflect bench configs/bench/paper-curved.toml
	$(BIN)/reflect bench configs/bench/scaling.toml

figures: install
	$(BIN)/reflect bench configs/bench/paper-dprm.toml --resume
	$(BIN)/reflect bench configs/bench/paper-curved.toml --resume
	$(BIN)/reflect bench configs/bench/scaling.toml --resume

smoke: install
	$(BIN)/reflect bench configs/bench/smoke.toml

# long fuzz run: 10,000 mutated scenes through validate and render (FUZZ_COUNT to change)
FUZZ_COUNT ?= 10000
fuzz: install
	$(BIN)/python scripts/fuzz.py --count $(FUZZ_COUNT) --timeout 60 --report out/fuzz.jsonl

clean:
	rm -rf out .reflect-cache .pytest_cache
