"""The warm-up that `make setup` runs compiles every numba kernel of the engine."""

import importlib
import os
import pkgutil
import subprocess
import sys

from numba.core.registry import CPUDispatcher

import tactile_viz.engine
from tactile_viz.engine.warmup import HELPERS, KERNELS, compile_kernels


def _dispatchers():
    """Every njit-compiled function defined in a module of the engine."""
    found = {}
    for info in pkgutil.walk_packages(tactile_viz.engine.__path__, "tactile_viz.engine."):
        module = importlib.import_module(info.name)
        for value in vars(module).values():
            if isinstance(value, CPUDispatcher) and value.py_func.__module__ == info.name:
                found[f"{info.name}.{value.__name__}"] = value
    return found


def test_every_kernel_of_the_engine_is_warmed():
    listed = {id(kernel) for kernel in KERNELS + HELPERS}
    assert sorted(name for name, kernel in _dispatchers().items()
                  if id(kernel) not in listed) == []


def test_the_warm_up_leaves_no_kernel_uncompiled():
    assert compile_kernels(steps=3) == []
    assert all(kernel.signatures for kernel in KERNELS)


_DIGEST = """
import hashlib
import numpy as np
from tactile_viz.engine.shape import gpis_compiled as compiled
rng = np.random.default_rng(7)
x, y = rng.normal(size=(2000, 3)), rng.normal(size=(1203, 3))
weights = rng.normal(size=(4 * len(y), 2))
out = [compiled.compiled_corrections(x, y, weights, 2.0, wendland) for wendland in (0, 1)]
out += [compiled.compiled_value_rows(x[:50], y, 2.0, 0),
        compiled.compiled_kernel_blocks(x[:50], y, 2.0, 1)]
print(hashlib.sha256(b"".join(a.tobytes() for a in out)).hexdigest())
"""


def test_a_kernel_gives_the_same_numbers_compiled_here_or_loaded_from_the_cache(tmp_path):
    # A trial must not depend on whether numba compiled its kernels in this process or
    # loaded them from its disk cache (fastmath's sums did).
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    runs = [subprocess.run([sys.executable, "-c", _DIGEST], env=env, capture_output=True,
                           text=True, check=True).stdout for _ in range(2)]
    assert any(tmp_path.rglob("*.nbc"))  # the second run loaded what the first cached
    assert runs[0] == runs[1]
