"""The warm-up that `make setup` runs compiles every numba kernel of the engine."""

import importlib
import pkgutil

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
