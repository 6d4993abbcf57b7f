"""One BLAS thread a process for the commands and the desktop app.

OpenBLAS starts a thread a core in every process that loads numpy. Two sessions at once
(or a session beside a benchmark) on a two-core machine then run four threads that wait on
each other: a 2,500-row Cholesky factor took 1.2-3.5 s there, against 0.16 s with one
thread a process (docs/journal/bench-speed.md). The engine's matrices are small (a GPIS
fit's at most a few thousand rows), where one thread alone is about as fast as two; and a
benchmark's worker processes already ran with one. Only takes effect before numpy is first
imported; a variable the user set is kept.
"""

import os

VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def one_blas_thread():
    """Ask the BLAS and OpenMP libraries numpy will load for one thread (unless set)."""
    for name in VARIABLES:
        os.environ.setdefault(name, "1")
