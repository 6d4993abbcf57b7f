"""The command line and the app ask for one BLAS thread a process, unless told."""

import os
import subprocess
import sys

import pytest

from tactile_viz.threads import VARIABLES

SHOW = "import os; print(' '.join(os.environ.get(n, '-') for n in {names!r}))"


@pytest.mark.parametrize("entry", ["tactile_viz.__main__", "tactile_viz.launcher"])
def test_an_entry_point_asks_for_one_thread_before_numpy_loads(entry):
    env = {k: v for k, v in os.environ.items() if k not in VARIABLES}
    code = f"import {entry}; " + SHOW.format(names=VARIABLES)
    shown = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
    ).stdout.split()
    assert shown == ["1"] * len(VARIABLES)
    env["OPENBLAS_NUM_THREADS"] = "3"  # the user's own choice is kept
    shown = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
    ).stdout.split()
    assert shown == ["3"] + ["1"] * (len(VARIABLES) - 1)


def test_numpy_is_not_loaded_before_the_threads_are_asked_for():
    code = "import sys, tactile_viz.threads; print('numpy' in sys.modules)"
    shown = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout.strip()
    assert shown == "False"
