"""Shared test set-up: a repo-local cache so derived arrays are built once per machine."""

import os
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
os.environ.setdefault("TACTILE_VIZ_CACHE", str(REPO / ".cache" / "tests"))
# Seeded trials are reproducible only for one BLAS summation order; the thread count changes
# it. `make test` sets these before Python starts; this covers a bare `pytest` run, as long
# as numpy has not been imported yet.
for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")
