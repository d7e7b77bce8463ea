# Two commands do everything on a fresh clone (see README):
#   make demo   - set up .venv, then run the planner comparison (the main job)
#   make test   - set up .venv, then run the test suite
# The CPU build of torch is installed *before* stable-baselines3 so pip does not
# pull a multi-GB CUDA build.

PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed-stamp

.PHONY: demo test reproduce bench clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet torch==2.13.0
	$(PY) -m pip install --quiet -e ".[all]"
	touch $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/mrmt compare --worlds 20 --robots 3 --targets 10 --controllers fast,strong,ising --out results/demo

test: $(STAMP)
	$(PY) -m pytest -q -n 2 --durations=15

reproduce: $(STAMP)
	$(VENV)/bin/mrmt reproduce --out results/paper

clean:
	rm -rf $(VENV) results .pytest_cache
