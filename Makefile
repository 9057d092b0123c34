# reflect: batch renderer for mirror reflections.
# `make demo` installs into .venv and renders the bundled teapot-box scene (EXR + PNG preview).
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
SCENE ?= scenes/teapot-box.toml

.PHONY: demo install test lint coverage render bench figures smoke fuzz clean

demo: install
	$(BIN)/reflect render $(SCENE) --frames 0 --preview

$(BIN)/reflect: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[dev,plots,dask,metrics]'
	touch $(BIN)/reflect

install: $(BIN)/reflect

# one pytest worker per core (pytest-xdist): a fresh clone's suite is mostly numba compiling
# kernels (about 12 of its 16 minutes on 2 cores, one compile at a time in one process)
test: install
	$(BIN)/pytest -q -n auto

lint: install
	$(BIN)/ruff check reflectcli tests benchmarks scripts

# Kernel line coverage with numba's JIT off (the kernels run as Python, so coverage sees
# them). Only the kernel tests run: the whole suite renders full scenes and is far too slow
# without the JIT. Prints the kernel lines no test reaches.
KERNEL_TESTS ?= tests/twins tests/raster tests/maps tests/trace tests/test_twins.py tests/test_camera.py
KERNEL_SOURCES := reflectcli/raster/*,reflectcli/trace/*,reflectcli/maps/*,reflectcli/virtual/*,reflectcli/shading.py,reflectcli/camera.py
coverage: install
	NUMBA_DISABLE_JIT=1 $(BIN)/pytest -q -p no:cacheprovider --cov=reflectcli --cov-report= \
		$(KERNEL_TESTS); status=$$?; \
		$(BIN)/coverage report -m --include='$(KERNEL_SOURCES)'; exit $$status

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
