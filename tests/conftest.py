"""Shared test set-up: a repo-local cache so derived arrays are built once per machine."""

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
os.environ.setdefault("TACTILE_VIZ_CACHE", str(REPO / ".cache" / "tests"))
# The app's default log file goes under $XDG_STATE_HOME: keep it out of the user's home.
os.environ["XDG_STATE_HOME"] = str(REPO / ".cache" / "tests" / "state")
# Seeded trials are reproducible only for one BLAS summation order; the thread count changes
# it. `make test` sets these before Python starts; this covers a bare `pytest` run, as long
# as numpy has not been imported yet.
for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")


@pytest.fixture(scope="session")
def bundled():
    """Every bundled object model, loaded once (derived data cached in the test cache)."""
    from tactile_viz.engine import bundled_names, load_bundled

    return {name: load_bundled(name) for name in bundled_names("all")}
