# Fresh machine: `make demo` (set up, then simulate a match) or `make test` (set up, then test).
PYTHON ?= python3
VENV ?= .venv
TORCH_SPEC ?= torch==2.13.0
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test lint setup clean

setup: $(STAMP)

# torch goes in first and alone: a CPU wheel pinned by TORCH_SPEC, so nothing that depends on
# torch pulls a multi-gigabyte CUDA build from the registry. Then the numba kernels are
# compiled and cached by one rally (`sportsngen.sim.warm`), so no run pays for it.
$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q "$(TORCH_SPEC)"
	$(BIN)/python -m pip install -q -e ".[dev]"
	$(BIN)/python -m sportsngen.sim.warm
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/python simulate.py

# Bytecode is written even where the environment says not to (PYTHONDONTWRITEBYTECODE): the
# suite starts a dozen Python processes (xdist workers, DDP ranks, spawned pools, CLIs) that
# would each compile the library and re-run pytest's assertion rewriting from source.
test: $(STAMP)
	PYTHONDONTWRITEBYTECODE= $(BIN)/python -m pytest

lint: $(STAMP)
	$(BIN)/ruff check .

clean:
	rm -rf $(VENV) outputs multirun .pytest_cache
