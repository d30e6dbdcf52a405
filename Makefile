# VEGA TVC flight software: workspace set-up, tests and software-in-the-loop runs.
#
#   make setup   .venv from requirements.txt, colcon build of ros2_ws, offline/ and cli/, `vega`
#   make lint    ruff (lint, docstrings) and the package layering contracts (pyproject.toml)
#   make check   `make lint`, then the fast tier of the suite: tests not marked slow (≤ 60 s)
#   make test    `make lint`, then the whole pytest suite (sets up first; what .ci/run runs)
#   make sil     fly the default SIL scenario into bags/ (sets up first; SIL_ARGS=...)
#   make mc      the default Monte Carlo campaign: 852 flight-day samples of `nominal` on a Dask
#                LocalCluster into bags/mc-<UTC time>/ (sets up first; MC_ARGS=..., e.g. --runs 100)
#   make mutation  mutmut over the core modules, one at a time (MODULE=name: one; docs/TESTING.md)
#   make soak    the whole suite ROUNDS times (10) with COPIES copies (2) at once (tools/soak.py)
#   make verify-design  the sign-off checks of TABLE (default: the shipped table), ≈ 30 min
#   make clean   remove the workspace build products and caches; `make distclean` also .venv
#
# Every step is incremental: a second `make setup` with nothing changed does nothing.
# Environment rules (docs/ENVIRONMENT_SETUP.md): every process started from here discovers
# on localhost only; `vega`, `vega-env` and the test suite pick a ROS_DOMAIN_ID per run
# (vega_bringup/rosenv.py) unless the caller exported one (1..101).

SHELL := /bin/bash
.SHELLFLAGS := -eu -o pipefail -c
.DEFAULT_GOAL := setup
.DELETE_ON_ERROR:

ROOT := $(patsubst %/,%,$(dir $(abspath $(lastword $(MAKEFILE_LIST)))))
PYTHON ?= python3
VENV := $(ROOT)/.venv
WS := $(ROOT)/ros2_ws
PYTEST_ARGS ?=
SIL_ARGS ?=

export ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST
unexport ROS_LOCALHOST_ONLY ROS_STATIC_PEERS

REQUIREMENTS_STAMP := $(VENV)/.stamp-requirements
OFFLINE_STAMP := $(VENV)/.stamp-offline
WS_STAMP := $(WS)/install/.stamp-build
KERNELS_STAMP := $(WS)/install/.stamp-kernels
BUILD_LOG := $(WS)/log/make-colcon-build.log
WRAPPERS := $(VENV)/bin/vega $(VENV)/bin/vega-env

# Workspace inputs that need a colcon build. The Python package directories of the
# ament_python packages are left out: --symlink-install links them, so edits (and new modules
# or data files) take effect without a rebuild.
PY_PACKAGES := $(notdir $(patsubst %/setup.py,%,$(wildcard $(WS)/src/*/setup.py)))
WS_SOURCES := $(filter-out $(foreach p,$(PY_PACKAGES),$(WS)/src/$(p)/$(p) $(WS)/src/$(p)/$(p)/%), \
  $(shell find $(WS)/src -name __pycache__ -prune -o -name '*.pyc' -o -print 2>/dev/null))

COLCON_FLAGS := --symlink-install \
  --cmake-args -DBUILD_TESTING=OFF -DPython3_EXECUTABLE=$(VENV)/bin/python

.PHONY: setup lint test sil clean distclean help

help:
	@sed -n '2,14s/^# \{0,1\}//p' $(firstword $(MAKEFILE_LIST))

setup: $(REQUIREMENTS_STAMP) $(WS_STAMP) $(OFFLINE_STAMP) $(WRAPPERS) $(KERNELS_STAMP)

$(VENV)/bin/python:
	$(PYTHON) -m venv $(VENV)

$(REQUIREMENTS_STAMP): $(ROOT)/requirements.txt | $(VENV)/bin/python
	$(VENV)/bin/python -m pip install --disable-pip-version-check --quiet -r $(ROOT)/requirements.txt
	touch $@

$(WS_STAMP): $(REQUIREMENTS_STAMP) $(WS_SOURCES)
	@echo "colcon build $(WS) (log: $(BUILD_LOG))"
	@mkdir -p $(dir $(BUILD_LOG))
	@source $(ROOT)/tools/env.bash --no-workspace && cd $(WS) && colcon build $(COLCON_FLAGS) \
	  > $(BUILD_LOG) 2>&1 || { cat $(BUILD_LOG); echo "colcon build failed (log above)"; exit 1; }
	@# The venv is an ament prefix but not a colcon one: colcon's warning about that is expected.
	@grep -E '^(Finished|Failed)|WARNING' $(BUILD_LOG) \
	  | grep -v "doesn't contain any 'local_setup" || true
	@touch $@

# The plant's numba kernels compiled ahead of time (vega_model/kernels.py: the plant node then
# starts without numba; the file name carries the sources' digest, so an edited kernel falls
# back to numba's JIT until this runs again)
KERNEL_SOURCES := $(addprefix $(WS)/src/vega_model/vega_model/,kernels.py nonlinear_kernel.py \
  wind_kernel.py)
$(KERNELS_STAMP): $(WS_STAMP) $(KERNEL_SOURCES) | $(WRAPPERS)
	@$(VENV)/bin/vega-env python -m vega_model.kernels
	@touch $@

# The offline side (offline/: vega_loops ... vega_design) and the command line (cli/: vega_cli),
# editable: edits take effect without a reinstall; a new package needs its pyproject entry.
$(OFFLINE_STAMP): $(ROOT)/offline/pyproject.toml $(ROOT)/cli/pyproject.toml $(REQUIREMENTS_STAMP)
	$(VENV)/bin/python -m pip install --disable-pip-version-check --quiet \
	  --no-deps --no-build-isolation --editable $(ROOT)/offline --editable $(ROOT)/cli
	touch $@

# Small wrappers that set up the whole environment (tools/env.bash) from any directory, without
# an activated venv: `vega ...` runs the command line, `vega-env CMD ...` runs any command.
$(VENV)/bin/vega: $(ROOT)/Makefile | $(VENV)/bin/python
	@echo "write $@"
	@printf '%s\n' '#!/usr/bin/env bash' \
	  '# vega: the VEGA TVC command line (written by `make setup`, see Makefile).' \
	  'source "$(ROOT)/tools/env.bash"' \
	  'exec "$$VIRTUAL_ENV/bin/python" -m vega_cli.cli "$$@"' > $@
	@chmod +x $@

$(VENV)/bin/vega-env: $(ROOT)/Makefile | $(VENV)/bin/python
	@echo "write $@"
	@printf '%s\n' '#!/usr/bin/env bash' \
	  '# vega-env CMD [ARGS...]: run CMD in the VEGA TVC project environment.' \
	  '# (written by `make setup`, see Makefile)' \
	  'source "$(ROOT)/tools/env.bash"' \
	  'exec "$$VIRTUAL_ENV/bin/python" -m vega_bringup.rosenv "$$@"' > $@
	@chmod +x $@

# ruff (lint, docstrings) and the layering contracts of pyproject.toml (import-linter).
lint: setup
	cd $(ROOT) && $(VENV)/bin/ruff check ros2_ws/src offline cli tests bench tools
	cd $(ROOT) && $(VENV)/bin/vega-env lint-imports --no-logo --no-cache $(ROOT)/pyproject.toml

# The whole suite, in this process (TEST_WORKERS=0, the default), or on TEST_WORKERS
# pytest-xdist workers, a test module per worker at a time (--dist loadfile). Two workers are
# not the default yet: in a soak of two 2-worker copies one SIL security test failed in both
# copies (docs/TESTING.md, "The soak check").
TEST_WORKERS ?= 0
test: setup lint
	cd $(ROOT) && $(VENV)/bin/vega-env python -m pytest tests -n $(TEST_WORKERS) --dist loadfile $(PYTEST_ARGS)

# The fast tier for everyday work: every test not marked slow (docs/TESTING.md, "Test tiers").
.PHONY: check
check: setup lint
	cd $(ROOT) && $(VENV)/bin/vega-env python -m pytest tests -m "not slow" -q $(PYTEST_ARGS)

# SIL_ARGS: more `vega sil run` arguments, e.g. make sil SIL_ARGS="--scenario thesis --seed 2"
sil: setup
	$(VENV)/bin/vega sil run --out $(ROOT)/bags $(SIL_ARGS)

# 852 runs: 99.73 % at 90 % confidence with no failure (docs/MONTE_CARLO.md); MC_ARGS are
# appended (a later --runs wins)
.PHONY: mc
mc: setup
	$(VENV)/bin/vega mc run --scenario nominal --runs 852 \
	  --out $(ROOT)/bags/mc-$$(date -u +%Y%m%dT%H%M%SZ) $(MC_ARGS)

# MODULE: one module of tools/mutation/targets.toml (default: all, one after the other, one
# worker, then the five seeded bugs of issue 15); table: bench/results/mutation.md, survivors:
# bench/results/mutation/<module>.json; docs/TESTING.md
MODULE ?=
.PHONY: mutation
mutation: setup
	cd $(ROOT) && OPENBLAS_NUM_THREADS=1 $(VENV)/bin/vega-env python tools/mutation/run.py \
	  $(if $(MODULE),--module $(MODULE))
	$(if $(MODULE),,cd $(ROOT) && $(VENV)/bin/vega-env python tools/mutation/seeded_bugs.py)

# Flake check of issue 15: ROUNDS rounds, each COPIES copies of the whole suite at once; one line
# per round, log build/soak.jsonl; exit 1 when a round failed (docs/TESTING.md)
ROUNDS ?= 10
COPIES ?= 2
.PHONY: soak
soak: setup
	cd $(ROOT) && $(VENV)/bin/vega-env python tools/soak.py --rounds $(ROUNDS) --copies $(COPIES)

# Sign-off checks of a controller table (`vega verify`, docs/FLIGHT_DESIGN.md §6.5): the SIL
# verdict scenarios, `vega margins --dispersed`, `vega robust --no-mu`, an 852-flight
# thesis-box campaign and an 852-sample flight-day campaign;
# exit 0 when every gated check passes; the record bags/verify-<UTC>/verify.json is what
# `vega ship` installs a table with. TABLE (default: the shipped table), VERIFY_ARGS appended,
# e.g. VERIFY_ARGS="--mc-reference 757" (the flown table's own sign-off passes, the least
# `vega ship` accepts); the time: docs/PERFORMANCE.md
TABLE ?= $(WS)/src/vega_gnc/config/tvc_controller.npz
.PHONY: verify-design
verify-design: setup
	cd $(ROOT) && OPENBLAS_NUM_THREADS=1 $(VENV)/bin/vega verify \
	  $(TABLE) --out $(ROOT)/bags/verify-$$(date -u +%Y%m%dT%H%M%SZ) $(VERIFY_ARGS)

clean:
	rm -rf $(WS)/build $(WS)/install $(WS)/log $(ROOT)/.pytest_cache $(ROOT)/.ruff_cache
	rm -rf $(ROOT)/offline/*.egg-info $(ROOT)/offline/build $(ROOT)/cli/*.egg-info $(ROOT)/cli/build \
	  $(OFFLINE_STAMP)
	find $(ROOT) -name .venv -prune -o -name __pycache__ -type d -prune -exec rm -rf {} +

distclean: clean
	rm -rf $(VENV)
