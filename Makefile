# The two commands the README leads with. Both work on a fresh machine with only Python.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
CORE := $(VENV)/.core
STAMP := $(VENV)/.installed

.PHONY: demo test install lint clean

# Two steps: the envs with their core dependencies first (all the kernels need), then
# training, sweeps, plans and the test tools. ``make demo`` and ``make test`` compile the
# kernels while the second step installs.
$(CORE): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	# --no-compile: Python compiles a module the first time it is imported, and only those;
	# byte-compiling every file of torch, Ray and the rest up front took about a minute.
	$(BIN)/pip install --quiet --no-compile -e .
	# The second step keeps every version the kernels were compiled against (and keeps
	# the compiling processes' imports in place).
	$(BIN)/pip freeze --exclude-editable > $(VENV)/core-constraints.txt
	touch $(CORE)

$(STAMP): $(CORE)
	# Pinned CPU build first: an unpinned torch pulls a multi-GB CUDA build.
	$(BIN)/pip install --quiet --no-compile -c $(VENV)/core-constraints.txt torch==2.13.0
	# The extras' requirements, not the project again: reinstalling it would take it away
	# for a moment from the processes compiling its kernels.
	$(BIN)/python -c "$$EXTRAS" > $(VENV)/extras.txt
	$(BIN)/pip install --quiet --no-compile -c $(VENV)/core-constraints.txt -r $(VENV)/extras.txt
	# Where PYTHONDONTWRITEBYTECODE is set Python writes no bytecode when it imports a
	# module, so every process (test workers, CLI runs, Ray workers) would compile torch,
	# Ray and the rest from source again: write it once for what the package and the
	# tests import.
	PYTHONDONTWRITEBYTECODE= $(BIN)/python -c "$$BYTECODE"
	touch $(STAMP)

# The requirements of the [dev] extra (every extra), with the extras it names expanded.
define EXTRAS
import re, tomllib
with open("pyproject.toml", "rb") as file:
    project = tomllib.load(file)["project"]
extras, wanted, seen = project["optional-dependencies"], ["dev"], set()
while wanted:
    name = wanted.pop()
    if name in seen:
        continue
    seen.add(name)
    for requirement in extras[name]:
        own = re.fullmatch(re.escape(project["name"]) + r"\[(.+)\]", requirement)
        if own:
            wanted += own.group(1).split(",")
        else:
            print(requirement)
endef
export EXTRAS

# Every module of the package imported (so every dependency it loads), what the sweep
# loads when it runs (Ray Tune), the test tools, and what is imported only once work
# starts: torch's optimisers import torch._dynamo (and sympy) at their first step, the
# aggregate's intervals rliable's bootstrap (statsmodels, arch), the plots matplotlib and
# PIL, Tune's logger tensorboardX, a wheel build setuptools. Left out, every process that
# trains or plots compiled them from source again. Ray's own processes (its dashboard, its
# agents, the autoscaler's monitor and the log monitor, started with every cluster) load
# their modules from three of its folders, the dashboard's by walking them: those folders
# whole.
define BYTECODE
import compileall, importlib, os, pkgutil, warnings
warnings.simplefilter("ignore")
import ikbranch_gym
for module in pkgutil.walk_packages(ikbranch_gym.__path__, "ikbranch_gym."):
    if not module.name.endswith("__main__"):
        importlib.import_module(module.name)
import coal, hypothesis, pytest, ray.tune, scipy.optimize, xdist
import matplotlib.pyplot, PIL.Image, rliable.library, setuptools, tensorboardX, torch._dynamo
for folder in ("_private", "autoscaler", "dashboard"):
    compileall.compile_dir(os.path.join(os.path.dirname(ray.__file__), folder), quiet=1)
endef
export BYTECODE

install: $(STAMP)

# Compiled kernels (numba) land in its on-disk cache once, before parallel processes use
# them; they need only the core install, so they compile while the rest installs.
WARM_UP := $(BIN)/ikbranch warm-up

demo: $(CORE)
	$(WARM_UP) & warm=$$!; $(MAKE) --no-print-directory $(STAMP); installed=$$?; \
	wait $$warm; warmed=$$?; [ $$installed -eq 0 ] && [ $$warmed -eq 0 ]
	MUJOCO_GL=egl $(BIN)/python -m train.demo

# The kernels compile while the rest installs and the linters run at the lowest priority,
# on the cores the compiling processes leave idle; mypy in two processes, so that it takes
# both once the kernels are done. The tests wait for both.
test: $(CORE)
	$(WARM_UP) & warm=$$!; \
	nice -n 19 $(MAKE) --no-print-directory $(STAMP) && nice -n 19 $(BIN)/ruff check . && \
	nice -n 19 $(BIN)/mypy --num-workers 2; lint=$$?; \
	wait $$warm; warmed=$$?; [ $$lint -eq 0 ] && [ $$warmed -eq 0 ]
	MUJOCO_GL=egl $(BIN)/python -m pytest -q -n 2

lint: $(STAMP)
	$(BIN)/ruff check .

clean:
	rm -rf $(VENV) build *.egg-info
