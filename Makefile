# tactile_viz: every target does its own set-up on a fresh Debian 12 machine.
#
#   make run     start the desktop app, tactile-viz app (needs a display; headless:
#                xvfb-run -a make run); its options in ARGS: make run ARGS="--object vase_2"
#   make test    ruff check, then the whole pytest suite (GUI tests on a virtual X server)
#   make lint    ruff check alone (pyproject.toml's [tool.ruff])
#   make setup   system packages + .venv + pip install -e '.[gui,test,bench]'

SHELL := /bin/bash
.SHELLFLAGS := -eu -o pipefail -c
.DEFAULT_GOAL := test

VENV   := .venv
PY     := $(VENV)/bin/python
# pip runs again only when pyproject.toml is newer than this stamp.
STAMP  := $(VENV)/.tactile_viz-installed
EXTRAS := gui,test,bench

# python3.11 if there is one, else python3 if it is 3.11 or newer.
PYTHON ?= $(shell for p in python3.11 python3; do \
	  command -v $$p >/dev/null 2>&1 && $$p -c 'import sys; sys.exit(sys.version_info < (3, 11))' 2>/dev/null \
	  && { echo $$p; break; }; done)

.PHONY: setup system-deps venv run lint test screenshots

setup: system-deps $(STAMP)

system-deps:
	@bash scripts/install-system-deps.sh

$(PY):
	@if [ -z "$(PYTHON)" ]; then \
	  echo "error: Python 3.11+ not found (tried python3.11, python3); on Debian 12: apt-get install python3 python3-venv" >&2; \
	  exit 1; fi
	$(PYTHON) -m venv $(VENV)

# Then the numba kernels are compiled into their cache (7-20 s), which a first trial
# would otherwise do (13-16 s of a fresh clone's first two-step trial).
$(STAMP): pyproject.toml | $(PY)
	$(PY) -m pip install --no-input --disable-pip-version-check -q -e '.[$(EXTRAS)]'
	OPENBLAS_NUM_THREADS=1 $(PY) -m tactile_viz.engine.warmup
	@touch $@

venv: $(STAMP)

# The installed command (pyproject.toml's [project.scripts]); app.py in the clone is the same.
ARGS ?=
run: setup
	$(VENV)/bin/tactile-viz app $(ARGS)

# The linter (ruff, in the `test` extra; its rules in pyproject.toml): a finding fails
# `make lint` and so `make test`, before any test runs. `ruff check --fix` fixes the import
# order and other safe findings. `ruff format` is not enforced: it would rewrite most files.
lint: setup
	$(PY) -m ruff check .

# Display for the GUI tests: the pytest-xvfb plugin (in the `test` extra)
# starts its own Xvfb on a free display for the pytest session and sets
# DISPLAY, also when the caller already has a DISPLAY, so the tests never
# touch a real desktop and need no xvfb-run wrapper. QtInteractor needs a real
# X server: QT_QPA_PLATFORM=offscreen fails with "Render window is not
# current", so tests/gui/conftest.py forces the xcb platform.
# pytest's exit code is make's: a failing test fails `make test`.
# One BLAS thread, as in the benchmarks' workers: trajectories are deterministic per seed
# only for a fixed summation order, which the number of BLAS threads changes.
#
# Without PYTEST_ARGS the GUI tests run in a pytest process of their own: pymeshlab (mesh
# repairs, the Poisson baseline) loads its bundled Qt 5 into the process, and one full run
# in a single process segfaulted inside Qt 6 (a menu of the main window) after 1,000 other
# tests, while tests/gui alone passed. Either failing run fails `make test`.
# Both run in TEST_WORKERS processes (pytest-xdist; the rest 4m26s instead of 7m40s on 2
# cores, the GUI tests 1m36s instead of 2m51s, each worker on an Xvfb of its own); every
# test owns its files (tmp_path), so the workers share nothing. TEST_WORKERS=0: one.
TEST_WORKERS ?= 2
PYTEST := OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 $(PY) -m pytest
test: setup lint
ifeq ($(strip $(PYTEST_ARGS)),)
	$(PYTEST) -n $(TEST_WORKERS) --ignore=tests/gui
	$(PYTEST) -n $(TEST_WORKERS) tests/gui
else
	$(PYTEST) $(PYTEST_ARGS)
endif

# Regenerate the README's images: object sheets off-screen, the window under Xvfb, one BLAS
# thread as in `make test`, so that tests/app/test_screenshots.py runs the novel picture's
# trajectory (mug_2 is judged novel in every seed of the bundled protocol). The learned
# picture explores mug_2 at seed 3 to termination, learns it and recognises it at seed 4.
XVFB_RUN := OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 \
  xvfb-run -a -s "-screen 0 1600x1000x24"
screenshots: setup
	$(PY) -m tactile_viz.gui.object_sheet --out screenshots
	$(XVFB_RUN) $(PY) app.py --object mug_1 --seed 0 --steps 60 --screenshot screenshots/app_known_mug1.png
	$(XVFB_RUN) $(PY) app.py --object mug_2 --seed 3 --steps 80 --screenshot screenshots/app_novel_mug2.png
	$(XVFB_RUN) $(PY) app.py --object mug_2 --seed 3 --learn-first --steps 30 --screenshot screenshots/app_learned_mug2.png
