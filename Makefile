# The two commands the README leads with. Both work on a fresh machine with only Python.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test install lint clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	# --no-compile: Python compiles a module the first time it is imported, and only those;
	# byte-compiling every file of torch, Ray and the rest up front took about a minute.
	# Pinned CPU build first: an unpinned torch pulls a multi-GB CUDA build.
	$(BIN)/pip install --quiet --no-compile torch==2.13.0
	$(BIN)/pip install --quiet --no-compile -e '.[dev]'
	# Where PYTHONDONTWRITEBYTECODE is set Python writes no bytecode when it imports a
	# module, so every process (test workers, CLI runs, Ray workers) would compile torch,
	# Ray and the rest from source again: write it once for what the package and the
	# tests import.
	PYTHONDONTWRITEBYTECODE= $(BIN)/python -c "$$BYTECODE"
	touch $(STAMP)

# Every module of the package imported (so every dependency it loads), what the sweep
# loads when it runs (Ray Tune), and the test tools.
define BYTECODE
import importlib, pkgutil, warnings
warnings.simplefilter("ignore")
import ikbranch_gym
for module in pkgutil.walk_packages(ikbranch_gym.__path__, "ikbranch_gym."):
    if not module.name.endswith("__main__"):
        importlib.import_module(module.name)
import coal, hypothesis, pytest, ray.tune, scipy.optimize, xdist
endef
export BYTECODE

install: $(STAMP)

# Compiled kernels (numba) land in its on-disk cache once, before parallel processes use them.
WARM_UP := $(BIN)/ikbranch warm-up

demo: $(STAMP)
	$(WARM_UP)
	MUJOCO_GL=egl $(BIN)/python -m train.demo

# The kernels compile on one core while the linters run on the other.
test: $(STAMP)
	$(WARM_UP) & warm=$$!; $(BIN)/ruff check . && $(BIN)/mypy; lint=$$?; \
	wait $$warm; warmed=$$?; [ $$lint -eq 0 ] && [ $$warmed -eq 0 ]
	MUJOCO_GL=egl $(BIN)/python -m pytest -q -n 2

lint: $(STAMP)
	$(BIN)/ruff check .

clean:
	rm -rf $(VENV) build *.egg-info
