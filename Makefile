# Two entry points for a fresh machine (see README): `make run` and `make test`.
# Both create .venv on first use. torch is installed first and pinned (2.13.0, the CPU build),
# so stable-baselines3 finds it satisfied and pulls no CUDA packages.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: run test setup

setup: $(STAMP)

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet torch==2.13.0
	$(BIN)/python -m pip install --quiet -e ".[agents,dev]"
	touch $(STAMP)

# The main job: PPO on the default scene (the intermediate-axis spin; see the README for its time),
# then the learned agent against the analytic controller and zero action.
run: $(STAMP)
	$(BIN)/rbenvs-train --algo ppo --scene default --seed 0

# The tests on every core, at most 8 (one worker per core; each compiles the kernels it uses).
test: $(STAMP)
	$(BIN)/python -m pytest -q -n auto --maxprocesses 8
	$(BIN)/rbenvs verify --quick --no-progress
