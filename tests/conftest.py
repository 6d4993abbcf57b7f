"""Shared test set-up: a repo-local cache so derived arrays are built once per machine."""

import os
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
os.environ.setdefault("TACTILE_VIZ_CACHE", str(REPO / ".cache" / "tests"))
