# Two entry points for a fresh machine (see README): `make run` and `make test`; `make test-ray`
# is CI's second job (.ci/run).
# Both create .venv on first use. torch is installed first and pinned (2.13.0, the CPU build),
# so stable-baselines3 finds it satisfied and pulls no CUDA packages.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

# The Ray tests' own venv: RLlib pins gymnasium 1.2.2, so the `ray` extra cannot share .venv
# (whose gymnasium is the newest) without changing what every other test runs on.
RAY_VENV  := .venv-ray
RAY_BIN   := $(RAY_VENV)/bin
RAY_STAMP := $(RAY_VENV)/.installed

.PHONY: run test setup test-ray

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

# The formatter's check and the linter (ruff, configured in pyproject.toml), then the tests on
# every core, at most 8 (one worker per core; the kernels they compile kept in .rbenvs-cache:
# tests/conftest.py). The suite runs every row of `rbenvs verify --quick`, a test per system and
# integrator (tests/test_verify.py), on the same workers.
test: $(STAMP)
	$(BIN)/ruff format --check --quiet rbenvs agents tests
	$(BIN)/ruff check --quiet rbenvs agents tests
	$(BIN)/python -m pytest -q -n auto --maxprocesses 8

$(RAY_STAMP): pyproject.toml
	$(PYTHON) -m venv $(RAY_VENV)
	$(RAY_BIN)/python -m pip install --quiet --upgrade pip
	$(RAY_BIN)/python -m pip install --quiet torch==2.13.0
	$(RAY_BIN)/python -m pip install --quiet -e ".[ray]" "pytest>=8"
	touch $(RAY_STAMP)

# The tests marked `ray` (tests/test_ray.py: the grid on Ray tasks, a Tune sweep, RLlib PPO), each
# on an embedded local cluster of 2 CPUs, one test at a time; the main run skips them.
test-ray: $(RAY_STAMP)
	$(RAY_BIN)/python -m pytest -q -m ray tests/test_ray.py
