# Two commands do everything on a fresh clone (see README):
#   make demo   - set up .venv with the base package only (no torch), then run the planner comparison
#   make test   - add torch, stable-baselines3, Ray and the test tools, then type-check the League code (mypy,
#                 [tool.mypy] in pyproject.toml) and run the test suite
# torch==2.13.0 is installed *before* stable-baselines3, from wherever pip finds it: a local CPU wheel
# where the machine has one, else plain PyPI, which on Linux serves the multi-GB CUDA build.  For the
# CPU build from PyTorch's own index: make test TORCH_INDEX=https://download.pytorch.org/whl/cpu

PYTHON      ?= python3
VENV        ?= .venv
PY          := $(VENV)/bin/python
TORCH       ?= torch==2.13.0
TORCH_INDEX ?=
BASE_STAMP  := $(VENV)/.base-stamp
FULL_STAMP  := $(VENV)/.full-stamp

.PHONY: demo test reproduce clean

$(PY):
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip

# the package and its base dependencies: all the planners, the chip and the envs
$(BASE_STAMP): pyproject.toml | $(PY)
	$(PY) -m pip install --quiet -e .
	touch $(BASE_STAMP)

# everything: learned agents (torch CPU build first), Ray, the test tools
$(FULL_STAMP): pyproject.toml $(BASE_STAMP)
	$(PY) -m pip install --quiet $(TORCH) $(if $(TORCH_INDEX),--index-url $(TORCH_INDEX))
	$(PY) -m pip install --quiet -e ".[all]"
	touch $(FULL_STAMP)

demo: $(BASE_STAMP)
	$(VENV)/bin/mrmt compare --worlds 20 --robots 3 --targets 10 --controllers fast,strong,ising,ising-paper --out results/demo

# the kernels are compiled once, on two processes, before the suite (its two workers would otherwise each
# compile the same kernels side by side on first use); a warm install skips it in about a second
test: $(FULL_STAMP)
	$(VENV)/bin/mrmt warmup --no-progress --lorr pibt,pibt-flow,epibt,epibt-chain
	$(PY) -m mypy
	$(PY) -m pytest -q -n 2 --durations=15

reproduce: $(BASE_STAMP)
	$(VENV)/bin/mrmt reproduce --out results/paper

clean:
	rm -rf $(VENV) results .pytest_cache
