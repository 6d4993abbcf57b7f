"""Compile the engine's numba kernels before a user's first session needs them.

numba compiles a kernel on its first call and caches the machine code beside its source
(``cache=True``), so only the first session after an install pays for it: 13-16 s of a
fresh clone's first two-step trial, against 2.6 s once cached. ``make setup`` runs
``python -m tactile_viz.engine.warmup`` after installing: a few steps of a known and of a
novel bundled object, at the default and the ``recognise`` presets (whose grids differ in
type), compile every kernel the way sessions call them.
"""

import sys
import time

from .belief import kernels
from .shape import gpis_compiled, sdf

KERNELS = (sdf._interpolate, kernels.contact_log_likelihoods, kernels.distances,
           kernels.align, kernels.pairs_below, gpis_compiled._corrections,
           gpis_compiled._value_rows, gpis_compiled._kernel_blocks)
"""The compiled kernels Python calls."""

HELPERS = (sdf.grid_lookup, gpis_compiled._profile, gpis_compiled._term,
           gpis_compiled._kernel_terms)
"""Compiled functions only kernels call: compiled into their callers."""

SESSIONS = (("mug_1", "recommended"), ("mug_1", "recognise"), ("vase_2", "recommended"))
"""The bundled objects and presets the warm-up explores: mug_1 is known, vase_2 novel."""


def compile_kernels(steps=3):
    """Run ``steps`` steps of each of :data:`SESSIONS` against the bundled known set.

    Returns
    -------
    list of str
        The names of :data:`KERNELS` still without a compiled signature (none expected).
    """
    from . import PriorLibrary, Session, load_bundled, make_truth
    from .session import session_preset

    library = PriorLibrary.bundled("known")
    for name, preset in SESSIONS:
        session = Session.simulated(make_truth(load_bundled(name), rng=0), library, "gpis-dhd",
                          session_preset(preset), seed=0)
        session.run(max_steps=steps)
    return [kernel.__name__ for kernel in KERNELS if not kernel.signatures]


def main():
    """Compile, saying so in one line; a failure here only delays compiling to the first
    trial, so it warns and leaves the set-up to go on."""
    clock = time.perf_counter()
    try:
        missing = compile_kernels()
    except Exception as error:  # any failure: the first trial compiles instead
        print(f"tactile_viz.engine.warmup: warning: kernels not compiled ahead "
              f"({type(error).__name__}: {error}); the first trial will compile them",
              file=sys.stderr)
        return 0
    if missing:
        print(f"tactile_viz.engine.warmup: not compiled: {', '.join(missing)}",
              file=sys.stderr)
        return 1
    print(f"compiled the engine's {len(KERNELS)} numba kernels "
          f"({time.perf_counter() - clock:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
